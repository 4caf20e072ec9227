"""Forgery fuzzer for frame security: random bytes and mutated sealed frames into FrameSealer.open
with the right key; none may be accepted. A command (`python -m rescuemesh.checks.fuzz --frames N`),
not part of the sans-IO stack: it draws its own random numbers and reads a clock for its rate.
"""

from __future__ import annotations

import argparse
import random
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from typing import Callable

from rescuemesh.protocol import (
    BROADCAST, DataKind, Follow, ForwardMsg, Goto, MessageType, MoveAround, Pose, ResultCode, Return, ShowCam,
    Stop, encode_frame)
from rescuemesh.protocol.codec import HEADER_BYTES, INTEGRITY_BYTES, PROTOCOL_VERSION, FrameFlags, Header
from rescuemesh.protocol.messages import Confirm, Data, PoseUpdate, SegmentAck

from rescuemesh.mesh.frames import AUTH_BIT, SEG_BIT, TTL_MASK
from rescuemesh.mesh.frames import seal as with_crc
from rescuemesh.mesh.keys import derive_frame_key, team_key_from_seed
from rescuemesh.mesh.security import AuthenticationError, FrameSealer, MicMismatch
from rescuemesh.mesh.segments import make_segment, segment_count

#: Mutation kinds, drawn uniformly. Each produces bytes that differ from the genuine sealed frame,
#: or the genuine bytes with another epoch.
KINDS = ("random", "bitflip", "truncate", "extend", "swap", "epoch", "auth", "ttl", "header", "splice")
POOL_SIZE = 512  # genuine sealed frames the mutations start from
DEFAULT_MAX_SECONDS = 900.0
_CHECK_EVERY = 4096  # frames between clock reads
_POSE = Pose(3.25, -1.5, 0.0, 0.75)


@dataclass
class FuzzReport:
    """What a run did: `frames` tried, `mic_checked` (well formed enough to reach the MIC check: each
    has a 2**-32 chance of passing), `accepted` (forged frames open() returned), `crashes` (an
    exception other than AuthenticationError), `identical` (mutations that came out genuine, redrawn),
    per-kind counts, wall time in s and whether the time bound stopped it."""

    frames: int = 0
    mic_checked: int = 0
    accepted: int = 0
    crashes: int = 0
    identical: int = 0
    by_kind: Counter = field(default_factory=Counter)
    accepted_by_kind: Counter = field(default_factory=Counter)
    first_failure: str = ""
    seconds: float = 0.0
    timed_out: bool = False

    @property
    def rate(self) -> float:
        """Frames per second."""
        return self.frames / self.seconds if self.seconds > 0 else float("inf")


def _genuine_frames(rng: random.Random) -> list[bytes]:
    """POOL_SIZE CRC frames as the stack makes them: control frames of every layout, Heartbeats with
    an epoch, and segment frames of Data messages."""
    frames: list[bytes] = []
    while len(frames) < POOL_SIZE:
        src, dst, seq = rng.randrange(255), rng.randrange(255), rng.randrange(65536)
        ttl, attempt = rng.randrange(16), rng.randrange(4)
        pick = rng.randrange(10)

        def header(msg_type: MessageType) -> Header:
            return Header(PROTOCOL_VERSION, FrameFlags.NONE, ttl, attempt, msg_type, src, dst, seq)

        if pick == 0:  # a Heartbeat with its epoch, built by hand: active_command, init_ttl, epoch
            payload = bytes((0, ttl)) + rng.randrange(1 << 32).to_bytes(4, "big") + bytes((rng.randrange(32),))
            frames.append(with_crc(bytes(((PROTOCOL_VERSION << 6) | ttl, MessageType.HEARTBEAT, src,
                                          BROADCAST, seq >> 8, seq & 0xFF)) + payload))
            continue
        if pick == 1:  # segments of a Data message
            size = rng.randrange(21, 120)
            logical = encode_frame(header(MessageType.DATA), Data(DataKind.RAW, seq, rng.randbytes(size - 13)))
            count = segment_count(len(logical))
            frames += [make_segment(logical, i, rng.randrange(4)) for i in range(count)]
            continue
        message = rng.choice((
            Stop(), Return(), Follow(_POSE), Goto(_POSE), PoseUpdate(_POSE), ShowCam(_POSE, 0.5, 3),
            MoveAround(_POSE, 2.0), Confirm(seq ^ 1, MessageType.FOLLOW, ResultCode.ACCEPTED),
            SegmentAck(seq, 0, rng.randrange(1 << 48)), ForwardMsg(3, b"\x06"),
            Data(DataKind.RAW, seq, rng.randbytes(rng.randrange(8))),
        ))
        frames.append(encode_frame(header(message.TYPE), message))
    return frames[:POOL_SIZE]


def _flip_bits(rng: random.Random, data: bytes) -> bytes:
    out = bytearray(data)
    for bit in rng.sample(range(8 * len(out)), rng.randint(1, 3)):
        out[bit >> 3] ^= 1 << (bit & 7)
    return bytes(out)


def _swap(rng: random.Random, data: bytes) -> bytes:
    out = bytearray(data)
    for _ in range(8):  # a pair of distinct bytes; a frame of one repeated byte stays as it is
        i, j = rng.sample(range(len(out)), 2)
        if out[i] != out[j]:
            out[i], out[j] = out[j], out[i]
            break
    return bytes(out)


def _change_header(rng: random.Random, data: bytes) -> bytes:
    """One header field (or a segment's SegO|SegN) changed to another value; byte 0 kept."""
    out = bytearray(data)
    last = HEADER_BYTES + 3 if data[0] & SEG_BIT else HEADER_BYTES
    i = rng.randrange(1, last)
    out[i] ^= rng.randrange(1, 256)
    return bytes(out)


def _mutate(rng: random.Random, kind: str, pool: list[tuple[bytes, bytes, int]]) -> tuple[bytes, int]:
    """(bytes, epoch) to try to open, drawn by `kind` from a genuine (CRC frame, sealed, epoch)."""
    plain, sealed, epoch = rng.choice(pool)
    if kind == "random":
        return rng.randbytes(rng.randrange(41)), epoch
    if kind == "bitflip":
        return _flip_bits(rng, sealed), epoch
    if kind == "truncate":  # cut at the end (most often) or at the start
        if rng.random() < 0.7:
            return sealed[: rng.randrange(len(sealed))], epoch
        return sealed[rng.randrange(1, len(sealed)):], epoch
    if kind == "extend":
        return sealed + rng.randbytes(rng.randint(1, 8)), epoch
    if kind == "swap":
        return _swap(rng, sealed), epoch
    if kind == "epoch":
        delta = rng.choice((1, -1, rng.randrange(1, 1 << 32)))
        return sealed, (epoch + delta) % (1 << 32)
    if kind == "auth":  # AUTH cleared on a sealed frame, or set on the CRC frame it came from
        if rng.random() < 0.5:
            return bytes((sealed[0] & ~AUTH_BIT & 0xFF,)) + sealed[1:], epoch
        return bytes((plain[0] | AUTH_BIT,)) + plain[1:], epoch
    if kind == "ttl":  # what a careless relay does: a new TTL nibble, the old MIC
        ttl = (sealed[0] & TTL_MASK) ^ rng.randrange(1, 16)
        return bytes(((sealed[0] & ~TTL_MASK & 0xFF) | ttl,)) + sealed[1:], epoch
    if kind == "header":
        return _change_header(rng, sealed), epoch
    # splice: the clear part of one frame with the encrypted part and MIC of another of equal length
    other = rng.choice([s for _, s, _ in pool if len(s) == len(sealed)])
    cut = rng.randrange(HEADER_BYTES, len(sealed) - INTEGRITY_BYTES + 1)
    return sealed[:cut] + other[cut:], epoch


def run_fuzz(
    frames: int,
    seed: int,
    clock: Callable[[], float],
    max_seconds: float = DEFAULT_MAX_SECONDS,
    make_sealer: Callable[[bytes], FrameSealer] = FrameSealer,
) -> FuzzReport:
    """Try `frames` random and mutated frames on open() under the key the genuine ones were sealed
    with; stop early (timed_out) after `max_seconds` of `clock`. `make_sealer` lets a test plant a
    broken sealer and watch the fuzzer catch it."""
    rng = random.Random(seed)
    sealer = make_sealer(derive_frame_key(team_key_from_seed(seed)))
    pool = []
    for plain in _genuine_frames(rng):
        epoch = rng.randrange(1 << 32)
        if plain[1] == MessageType.HEARTBEAT and not plain[0] & SEG_BIT:  # sealed under its own epoch
            epoch = int.from_bytes(plain[8:12], "big")
        sealed = sealer.seal(plain, epoch)
        if sealer.open(sealed, epoch) != plain:
            raise AssertionError(f"genuine frame {sealed.hex()} does not open to {plain.hex()}")
        pool.append((plain, sealed, epoch))
    genuine = {(sealed, epoch) for _, sealed, epoch in pool}
    report = FuzzReport()
    start = clock()
    open_ = sealer.open
    while report.frames < frames:
        if report.frames % _CHECK_EVERY == 0 and clock() - start > max_seconds:
            report.timed_out = True
            break
        kind = KINDS[rng.randrange(len(KINDS))]
        data, epoch = _mutate(rng, kind, pool)
        if (data, epoch) in genuine:  # not a forgery: the genuine frame itself
            report.identical += 1
            continue
        report.frames += 1
        report.by_kind[kind] += 1
        try:
            open_(data, epoch)
        except MicMismatch:
            report.mic_checked += 1
            continue
        except AuthenticationError:
            continue
        except Exception as exc:  # noqa: BLE001 - the fuzzer's job is to find these
            report.crashes += 1
            report.first_failure = report.first_failure or f"{kind}: {data.hex()} epoch {epoch}: {exc!r}"
            continue
        report.mic_checked += 1
        report.accepted += 1
        report.accepted_by_kind[kind] += 1
        report.first_failure = report.first_failure or f"{kind}: accepted {data.hex()} epoch {epoch}"
    report.seconds = clock() - start
    return report


def main(argv: list[str] | None = None) -> int:
    """Exit status 0: every frame rejected; 1: a frame accepted or an exception other than
    AuthenticationError; 2: the time bound stopped the run before `--frames`."""
    parser = argparse.ArgumentParser(prog="python -m rescuemesh.checks.fuzz", description=__doc__)
    parser.add_argument("--frames", type=int, default=100_000, help="frames to try (default 100000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--max-seconds", type=float, default=DEFAULT_MAX_SECONDS,
                        help=f"stop after this many seconds (default {DEFAULT_MAX_SECONDS:.0f})")
    args = parser.parse_args(argv)
    if args.frames < 0 or not 0 <= args.seed < 1 << 64 or not args.max_seconds > 0:
        parser.error("--frames >= 0, --seed in 0..2**64-1, --max-seconds > 0")
    report = run_fuzz(args.frames, args.seed, time.perf_counter, args.max_seconds)
    print(f"frames: {report.frames} (seed {args.seed}) in {report.seconds:.1f} s, "
          f"{report.rate:,.0f} frames/s")
    for kind in KINDS:
        print(f"  {kind:9s} {report.by_kind[kind]:9d} tried, {report.accepted_by_kind[kind]} accepted")
    print(f"reached the MIC check: {report.mic_checked} (expected forgeries at 2**-32 each: "
          f"{report.mic_checked / 2**32:.1e})")
    print(f"identical to a genuine frame (redrawn, not counted): {report.identical}")
    print(f"exceptions other than AuthenticationError: {report.crashes}")
    if report.first_failure:
        print(f"first failure: {report.first_failure}")
    print(f"accepted: {report.accepted}")
    if report.accepted or report.crashes:
        return 1
    if report.timed_out:
        print(f"stopped by --max-seconds {args.max_seconds:g} before {args.frames} frames", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
