"""Fuzzing the control plane's input path: random and mutated control messages, as a peer on the
network could send them, through what a robot process or a world does with a message it receives.

Owns: the corpus of genuine messages, the mutations, and the count. Must not know: Zenoh (the bytes
go straight to ControlKey.open and the decoder, the same calls CallServer and CallClient make).

Two paths, each message through both:
- sealed: the whole wire message (tag, header, body) mutated, then opened with the run's key and
  decoded: a message is accepted only if both pass. Every mutation must be refused.
- body: the decoder alone (as if an attacker held the key): each message is refused with a
  CodecError or decodes to registered types only; any other exception is a finding.

`python -m rescuemesh.checks.control_fuzz --messages 100000` (make fuzz-control).
"""

from __future__ import annotations

import argparse
import pickle
import random
import sys
import time
from dataclasses import dataclass

import msgpack
import numpy as np

from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.processes.control import ControlError, ControlKey
from rescuemesh.runtime.processes.control_codec import CodecError, decode, encode


@dataclass
class FuzzCounts:
    messages: int = 0
    accepted: int = 0  # sealed path: a mutated message that opened and decoded (must stay 0)
    refused_sealed: int = 0
    refused_body: int = 0  # body path: CodecError
    decoded_body: int = 0  # body path: decoded to registered types (a mutation inside a number, say)
    untyped: int = 0  # any other exception (must stay 0)
    findings: list | None = None


def pickle_call(module: str, name: str, argument: str) -> bytes:
    """A pickle whose STACK_GLOBAL is (module, name), called with one string by REDUCE: what an
    intruder sent the old control plane (issue 17)."""
    def text(s: str) -> bytes:
        raw = s.encode()
        return pickle.SHORT_BINUNICODE + bytes([len(raw)]) + raw

    return (pickle.PROTO + b"\x04" + text(module) + text(name) + pickle.STACK_GLOBAL + text(argument)
            + pickle.TUPLE1 + pickle.REDUCE + pickle.STOP)


def corpus() -> list[bytes]:
    """Genuine encoded bodies of every request and reply kind, and some hostile ones."""
    from rescuemesh.body import LaserScan, RobotKind
    from rescuemesh.geometry import Pose2D
    from rescuemesh.maps.grid import OccupancyGrid
    from rescuemesh.mesh.node import Transmission
    from rescuemesh.protocol import MessageType, Pose, ResultCode, ShowScan
    from rescuemesh.robot.events import CommandSent
    from rescuemesh.robot.records import OutgoingCommand
    from rescuemesh.runtime.config import SimConfig

    pose = Pose2D(1.5, -2.0, 0.3)
    scan = LaserScan(0.1, pose, -1.0, 0.01, 0.1, 5.0, np.linspace(0.2, 4.0, 36))
    grid = OccupancyGrid(np.zeros((6, 8), dtype=bool), 0.05, -1.0, -2.0)
    transmission = Transmission(b"\x01\x02\x03", 1, 2, 3, 17, 4, False, None, None)
    status = msg.StatusDelta(True, msg.RunningView("follow", 1.0), [], [OutgoingCommand(3, 2, "Follow", 0.5,
                             result=ResultCode.ACCEPTED)], [CommandSent(0.5, "robot_1", MessageType.FOLLOW, 2, 3)],
                             None, 0)
    values = [
        msg.Hello(), msg.HelloReply(b"n" * 16),
        msg.RobotSetup("robot_1", pose, SimConfig(), grid, 0, RobotKind.GROUND, None, True, b"n" * 16, pose),
        msg.Tick(1.25, msg.BodyState(pose, (pose, 0.2, 0.1), scan)), msg.Tick(1.3, msg.BodyState(pose, (pose, 0, 0), None)),
        msg.Flush(2.0), msg.Receive(b"\x00" * 20, 2.5, -60.0, 0.01), msg.Timer(3.0),
        msg.NavigateTo(pose, 1.0), msg.Command(msg.CommandKind.GOTO, 2, 1.0, goal=pose),
        msg.Command(msg.CommandKind.MOVE_AROUND, 3, 1.0, radius_m=1.5), msg.Send(2, ShowScan(Pose(1.0, 2.0, 0.0, 0.5), 0.5, 2), 1.0),
        msg.Report(), msg.Stats(), msg.Bye(),
        msg.SetupReply(0.5), msg.StackReply([transmission], None), msg.TickReply([transmission], 1.0, (0.2, 0.0), status),
        msg.CommandReply(4, status), msg.StatsReply(123, 0.5), msg.Done(), msg.ErrorReply("ValueError: x", "tb"),
    ]
    bodies = [encode(v) for v in values]
    hostile = [
        pickle_call("rescuemesh.cli", "os.system", "touch /tmp/rescuemesh-pwned"),
        pickle_call("rescuemesh.runtime.processes.spawn", "subprocess.Popen", "true"),
        msgpack.packb([msgpack.ExtType(5, b"Popen"), ["true"]]),
        msgpack.packb({"stray": msgpack.ExtType(5, b"Stats")}),
        msgpack.packb([0, msgpack.ExtType(5, b"Bye")]),
        msgpack.packb(msgpack.ExtType(1, msgpack.packb(["|O", [1], b"\x00" * 8]))),
        msgpack.packb(msgpack.ExtType(1, msgpack.packb(["<f8", [1 << 40, 1 << 40], b""]))),
        msgpack.packb(msgpack.ExtType(3, msgpack.packb(["ResultCode", 99]))),
        msgpack.packb(msgpack.ExtType(9, b"")),
    ]
    return bodies + hostile


def _mutate(rng: random.Random, data: bytes, others: list[bytes]) -> bytes:
    data = bytearray(data)
    kind = rng.randrange(7)
    if kind == 0 or not data:  # random bytes
        return bytes(rng.getrandbits(8) for _ in range(rng.randrange(0, 200)))
    if kind == 1:  # flip bits
        for _ in range(rng.randrange(1, 8)):
            data[rng.randrange(len(data))] ^= 1 << rng.randrange(8)
    elif kind == 2:  # truncate
        del data[rng.randrange(len(data)):]
    elif kind == 3:  # insert random bytes
        at = rng.randrange(len(data) + 1)
        data[at:at] = bytes(rng.getrandbits(8) for _ in range(rng.randrange(1, 16)))
    elif kind == 4:  # splice with another message
        other = rng.choice(others)
        data = data[:rng.randrange(len(data) + 1)] + other[rng.randrange(len(other) + 1):]
    elif kind == 5:  # overwrite a byte with an interesting one (msgpack type markers, limits)
        data[rng.randrange(len(data))] = rng.choice([0xc0, 0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xd4, 0xd8, 0xdc,
                                                     0xdd, 0xde, 0xdf, 0x7f, 0xff, 0x00, 0x92, 0x93])
    else:  # duplicate a slice
        a = rng.randrange(len(data))
        b = rng.randrange(a, len(data) + 1)
        data[b:b] = data[a:b] * rng.randrange(1, 4)
    return bytes(data)


def fuzz(messages: int, seed: int = 0) -> FuzzCounts:
    rng = random.Random(seed)
    key = ControlKey(bytes(range(32)))
    bodies = corpus()
    sealed = [key.seal(rng.choice((1, 2)), bytes(16), rng.randrange(1, 1000), "robot_1", b) for b in bodies]
    counts = FuzzCounts(findings=[])
    for _ in range(messages):
        counts.messages += 1
        wire = _mutate(rng, rng.choice(sealed), sealed)
        if wire in sealed:
            wire += b"\x00"  # a mutation that changed nothing is not a forgery
        try:
            *_, body = key.open(wire)
            decode(body)
            counts.accepted += 1
            counts.findings.append(("accepted", wire))
        except (ControlError, CodecError):
            counts.refused_sealed += 1
        except Exception as error:  # noqa: BLE001 - what the count is for
            counts.untyped += 1
            counts.findings.append((f"{type(error).__name__}: {error}", wire))
        body = _mutate(rng, rng.choice(bodies), bodies)
        try:
            decode(body)
            counts.decoded_body += 1
        except CodecError:
            counts.refused_body += 1
        except Exception as error:  # noqa: BLE001
            counts.untyped += 1
            counts.findings.append((f"{type(error).__name__}: {error}", body))
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rescuemesh.checks.control_fuzz", description=__doc__.split("\n")[0])
    parser.add_argument("--messages", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    started = time.monotonic()
    counts = fuzz(args.messages, args.seed)
    print(f"control-plane fuzz, seed {args.seed}: {counts.messages} sealed messages mutated: {counts.accepted} accepted, "
          f"{counts.refused_sealed} refused; {counts.messages} bodies mutated (decoder alone): "
          f"{counts.refused_body} refused, {counts.decoded_body} decoded to registered types; "
          f"{counts.untyped} untyped exceptions ({time.monotonic() - started:.1f} s)")
    for finding, data in (counts.findings or [])[:10]:
        print(f"  {finding}: {data[:80].hex()}")
    return 0 if counts.accepted == 0 and counts.untyped == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
