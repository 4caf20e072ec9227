"""Frame security (the AUTH flag): AES-CCM with a 4-byte MIC in place of the CRC-32, the header as
associated data, a nonce from the header and the source's epoch (docs/security.md). Must not know
key files, clocks, replay windows or relay decisions: the mesh node calls seal/open around those.
"""

# Theory of operation (after Bluetooth Mesh Profile 1.0, 3.8: network nonce and network-layer
# encryption; docs/security.md)
# =====================================================================================
#
# A sealed frame has the length of its CRC frame: the 6-byte header (and a segment frame's 3-byte
# SegO|SegN) stay in the clear as associated data, the payload is encrypted in place (CTR), and
# the 4 bytes that held the CRC-32 hold the CCM MIC-32 (CBC-MAC) instead. A Heartbeat encrypts
# nothing: its whole payload is associated data, so its epoch can be read before the frame is
# opened and is still bound by the MIC (Bluetooth Mesh's Secure Network Beacon carries the IV
# index the same way).
#
#   nonce (13 bytes, CCM L = 2) = byte 0 as sent (version, AUTH, SEG, TTL) | byte 1 (attempt or
#       round, type) | src | dst | seq (2) | SegO|SegN (3; zeros unsegmented) | epoch (4, big-endian)
#
# CTR mode fails badly if one nonce ever carries two different plaintexts under one key, so every
# input that can differ between two frames is in the nonce, and the nonce is unique per plaintext:
#   - a sender never reuses (epoch, seq) for another message: its epoch grows at every boot
#     (persisted) and every seq wrap (the node's replay layer owns it; the node's own SegmentAck
#     counter must advance the epoch when it wraps, too);
#   - a resend differs in its attempt bits (from the 4th send on they saturate at 3, and the frame
#     is byte-identical: the same sealed bytes, no leak); a segment differs in SegO; a segment
#     round differs in its round bits, and a round that repeats (mod 4) is byte-identical again;
#   - a relay re-seals with TTL - 1, which is in the nonce; two relays that re-seal the same frame
#     produce identical bytes (sealing is deterministic);
#   - the one known repeat: an endpoint resend of a *segmented* frame restarts its rounds at 0, and
#     the segments that carry the logical frame's CRC-32 then repeat a nonce with different bytes.
#     Only those CRC bytes differ, and their XOR is public (CRC-32 is affine, so the XOR depends
#     only on the attempt bits that changed and the length): the repeat reveals nothing new.
# open() raises AuthenticationError, and nothing else, for any bytes whatsoever: a robot counts and
# drops a frame it cannot open; it never crashes on one.

from __future__ import annotations

import struct
import zlib
from typing import Callable

from cryptography.exceptions import InvalidTag
from cryptography.hazmat.primitives.ciphers.aead import AESCCM

from rescuemesh.protocol import BROADCAST, MessageType, encode_frame
from rescuemesh.protocol.codec import (
    FRAME_OVERHEAD_BYTES, HEADER_BYTES, INTEGRITY_BYTES, MAX_CONTROL_FRAME_BYTES, MAX_TTL, PROTOCOL_VERSION,
    FrameFlags, Header)
from rescuemesh.protocol.errors import IntegrityError
from rescuemesh.protocol.bench import BENCH_MESSAGES
from rescuemesh.protocol.codec import TYPE_MASK

from .frames import AUTH_BIT, MAX_PDU_BYTES, SEG_BIT, with_ttl
from .keys import FRAME_KEY_BYTES, derive_frame_key
from .segments import MIN_SEGMENT_FRAME_BYTES, SEGMENT_HEADER_BYTES

MIC_BYTES = INTEGRITY_BYTES  # AES-CCM tag length: 4, as a Bluetooth Mesh access NetMIC
NONCE_BYTES = 13  # 15 - L with L = 2 (messages up to 65535 bytes)
EPOCH_BYTES = 4
MAX_EPOCH = 0xFFFFFFFF
#: A Heartbeat frame with its epoch: header 6, active_command, init_ttl, epoch (bytes 8-11), MIC 4.
HEARTBEAT_FRAME_BYTES = 17
HEARTBEAT_EPOCH_OFFSET = 8
_EPOCH_AT = slice(HEARTBEAT_EPOCH_OFFSET, HEARTBEAT_EPOCH_OFFSET + EPOCH_BYTES)

_VERSION_AUTH_MASK = 0xC0 | AUTH_BIT
_PLAIN_B0 = PROTOCOL_VERSION << 6  # version 1, AUTH clear (what seal takes)
_SEALED_B0 = _PLAIN_B0 | AUTH_BIT  # version 1, AUTH set (what open takes)
_CLEAR_AUTH = ~AUTH_BIT & 0xFF
_SEG_END = HEADER_BYTES + SEGMENT_HEADER_BYTES  # 9: associated data of a segment frame
_HEARTBEAT = int(MessageType.HEARTBEAT)
_NO_SEGMENT = bytes(SEGMENT_HEADER_BYTES)
_U32 = struct.Struct(">I")


class AuthenticationError(IntegrityError):
    """A frame that cannot be opened: no AUTH flag, wrong length or version, or a MIC that does not
    verify (wrong team key, wrong epoch, corrupted or forged). A FrameError: counted and dropped."""


class MicMismatch(AuthenticationError):
    """A well-formed sealed frame whose MIC does not verify: another key, another epoch, corruption
    or forgery (the other AuthenticationErrors are frames that never reached the MIC check)."""


def _epoch_bytes(epoch: int) -> bytes:
    """The epoch as 4 big-endian bytes. ValueError (a caller bug, not a bad frame) outside 0..2**32-1."""
    try:
        return _U32.pack(epoch)
    except struct.error:
        raise ValueError(f"epoch {epoch!r} is not an integer in 0..{MAX_EPOCH}") from None


def _aad_end(b0: int, b1: int, n: int) -> int | None:
    """Where the associated data of an n-byte frame ends (the rest up to the MIC is encrypted), or
    None if n does not fit its kind: a segment frame 14..29 bytes (header and SegO|SegN in the
    clear, whatever its type), a Heartbeat exactly 17 (all but the MIC in the clear), any other
    frame 10..20 (header). docs/protocol.md section 12."""
    if b0 & SEG_BIT:
        return _SEG_END if MIN_SEGMENT_FRAME_BYTES <= n <= MAX_PDU_BYTES else None
    if b1 & TYPE_MASK == _HEARTBEAT:  # this used to seal and open a Heartbeat of any length 10..20
        return n - MIC_BYTES if n == HEARTBEAT_FRAME_BYTES else None
    return HEADER_BYTES if FRAME_OVERHEAD_BYTES <= n <= MAX_CONTROL_FRAME_BYTES else None


def _length_rule(b0: int, b1: int) -> str:
    """The length rule _aad_end applied, for the error message."""
    if b0 & SEG_BIT:
        return "a segment frame is 14..29 bytes"
    if b1 & TYPE_MASK == _HEARTBEAT:
        return f"a Heartbeat is {HEARTBEAT_FRAME_BYTES}"
    return "a frame is 10..20 bytes"


class FrameSealer:
    """Seals CRC frames into AUTH frames and opens them again, under one 16-byte frame key
    (keys.derive_frame_key of the team key). Sans-IO and deterministic: the same frame and epoch
    always seal to the same bytes. One object per node; it holds the AES-CCM context.

    `remember`: how many recent seal and open results to keep, by (bytes, epoch) (0: none). Both
    are pure functions of their arguments, so a result remembered is the result computed; a
    simulated team shares one sealer, and the 20-odd robots that hear one frame open it once.

    `reads` (None when `remember` is 0): the mesh reader's results for frames opened under this
    sealer's key, by (bytes heard, epoch), shared like the rest and bounded by `remember` (the
    reader fills it: reader.FrameReader). Only frames that opened are in it, and an entry answers
    only for the epoch it opened under; another key is another sealer, with a memory of its own."""

    __slots__ = ("_encrypt", "_decrypt", "_remember", "_sealed", "_opened", "reads")

    def __init__(self, frame_key: bytes, *, remember: int = 0) -> None:
        if not isinstance(frame_key, (bytes, bytearray)) or len(frame_key) != FRAME_KEY_BYTES:
            raise ValueError(f"a frame key is {FRAME_KEY_BYTES} bytes (AES-128)")
        if not (isinstance(remember, int) and remember >= 0):
            raise ValueError(f"remember must be a whole number >= 0, got {remember!r}")
        aead = AESCCM(bytes(frame_key), tag_length=MIC_BYTES)
        self._encrypt = aead.encrypt
        self._decrypt = aead.decrypt
        self._remember = remember
        self._sealed: dict[tuple[bytes, int], bytes] = {}
        self._opened: dict[tuple[bytes, int], bytes] = {}
        self.reads: dict[tuple[bytes, int], tuple] | None = {} if remember else None

    @property
    def remember(self) -> int:
        """How many results of each kind this sealer keeps (0: none)."""
        return self._remember

    @classmethod
    def from_team_key(cls, team_key: bytes, *, remember: int = 0) -> FrameSealer:
        """A sealer under the frame key derived from `team_key` (the team key itself is never used)."""
        return cls(derive_frame_key(team_key), remember=remember)

    def seal(self, frame: bytes, epoch: int) -> bytes:
        """See _seal below; the result is remembered (`remember`)."""
        return self._remembered(self._sealed, self._seal, frame, epoch)

    def open(self, frame: bytes, epoch: int) -> bytes:
        """See _open below; a result is remembered (`remember`), an AuthenticationError is not."""
        return self._remembered(self._opened, self._open, frame, epoch)

    def _remembered(self, memory: dict[tuple[bytes, int], bytes], compute: Callable[[bytes, int], bytes],
                    frame: bytes, epoch: int) -> bytes:
        if not self._remember:
            return compute(frame, epoch)
        key = (bytes(frame), epoch)
        result = memory.get(key)
        if result is None:
            result = memory[key] = compute(frame, epoch)
            if len(memory) > self._remember:
                del memory[next(iter(memory))]  # the oldest
        return result

    def _seal(self, frame: bytes, epoch: int) -> bytes:
        """The AUTH frame for CRC frame `frame` (an unsegmented frame of at most 20 bytes, or a segment
        frame of at most 29, exactly as the codec and the mesh make them) from a source whose epoch
        is `epoch` (0..2**32-1): AUTH set, payload encrypted, the MIC in place of the CRC; same
        length. ValueError if `frame` is not such a frame (length, version, flags, CRC-32; a Heartbeat
        is 17 bytes), or is a Heartbeat announcing another epoch than `epoch`."""
        epoch_bytes = _epoch_bytes(epoch)
        n = len(frame)
        if n < FRAME_OVERHEAD_BYTES or frame[0] & _VERSION_AUTH_MASK != _PLAIN_B0:
            raise ValueError(f"not a CRC frame of version {PROTOCOL_VERSION} ({n} bytes)")
        b0 = frame[0]
        end = _aad_end(b0, frame[1], n)
        if end is None:
            raise ValueError(f"{n}-byte frame: {_length_rule(b0, frame[1])}")
        body = n - INTEGRITY_BYTES
        if zlib.crc32(frame[:body]) != _U32.unpack_from(frame, body)[0]:
            raise ValueError("CRC-32 mismatch: only intact CRC frames are sealed")
        aad = bytes((b0 | AUTH_BIT,)) + frame[1:end]
        if n == HEARTBEAT_FRAME_BYTES and end == body and frame[_EPOCH_AT] != epoch_bytes:  # a Heartbeat
            announced = _U32.unpack_from(frame, HEARTBEAT_EPOCH_OFFSET)[0]
            raise ValueError(f"Heartbeat announces epoch {announced}, sealed with {epoch}")
        segment = frame[HEADER_BYTES:_SEG_END] if b0 & SEG_BIT else _NO_SEGMENT
        return aad + self._encrypt(aad[:HEADER_BYTES] + segment + epoch_bytes, frame[end:body], aad)

    def _open(self, frame: bytes, epoch: int) -> bytes:
        """The CRC frame inside AUTH frame `frame` as heard, from a source whose epoch is `epoch`:
        AUTH cleared, payload decrypted, CRC-32 recomputed, so the rest of the stack is unchanged.
        Raises AuthenticationError, and nothing else, for any bytes that are not a frame sealed
        under this key and epoch (ValueError only for an `epoch` outside 0..2**32-1: a caller bug)."""
        epoch_bytes = _epoch_bytes(epoch)
        n = len(frame)
        if n < FRAME_OVERHEAD_BYTES:
            raise AuthenticationError(f"{n} bytes, a sealed frame has at least {FRAME_OVERHEAD_BYTES}")
        b0 = frame[0]
        if b0 & _VERSION_AUTH_MASK != _SEALED_B0:
            raise AuthenticationError(f"byte 0 is {b0:#04x}: not a sealed (AUTH) frame of version 1")
        end = _aad_end(b0, frame[1], n)
        if end is None:
            raise AuthenticationError(f"{n}-byte sealed frame: {_length_rule(b0, frame[1])}")
        if n == HEARTBEAT_FRAME_BYTES and end == n - MIC_BYTES and frame[_EPOCH_AT] != epoch_bytes:  # a Heartbeat
            announced = _U32.unpack_from(frame, HEARTBEAT_EPOCH_OFFSET)[0]
            raise AuthenticationError(f"Heartbeat announces epoch {announced}, opened with {epoch}")
        aad = frame[:end]
        segment = frame[HEADER_BYTES:_SEG_END] if b0 & SEG_BIT else _NO_SEGMENT
        try:
            plain = self._decrypt(frame[:HEADER_BYTES] + segment + epoch_bytes, frame[end:], aad)
        except InvalidTag:
            raise MicMismatch("MIC mismatch: wrong team key or epoch, or a corrupted frame") from None
        body = bytes((b0 & _CLEAR_AUTH,)) + frame[1:end] + plain
        return body + _U32.pack(zlib.crc32(body))

    @staticmethod
    def heartbeat_epoch(frame: bytes) -> int | None:
        """The epoch a sealed Heartbeat announces in the clear (frame bytes 8-11), to open it with;
        None if `frame` is not a 17-byte sealed, unsegmented Heartbeat. Unverified until open()."""
        if (
            len(frame) != HEARTBEAT_FRAME_BYTES
            or frame[0] & (_VERSION_AUTH_MASK | SEG_BIT) != _SEALED_B0
            or frame[1] & TYPE_MASK != _HEARTBEAT
        ):
            return None
        return _U32.unpack_from(frame, HEARTBEAT_EPOCH_OFFSET)[0]


def reseal_with_ttl(sealer: FrameSealer, frame: bytes, epoch: int, ttl: int) -> bytes:
    """What a relay sends: AUTH frame `frame` opened (AuthenticationError as open()), its TTL set to
    `ttl` (0..15; the TTL is in the nonce, so the payload and MIC change too) and sealed again."""
    if not (isinstance(ttl, int) and 0 <= ttl <= MAX_TTL):
        raise ValueError(f"ttl {ttl!r} out of range 0..{MAX_TTL}")
    return sealer.seal(with_ttl(sealer.open(frame, epoch), ttl), epoch)


# --- speed --------------------------------------------------------------------------------------

BENCH_EPOCH = 0x0001_0002  # any epoch; a Heartbeat is sealed under the one it announces
_BENCH_KEY = bytes(range(FRAME_KEY_BYTES))


def _bench_frames() -> list[tuple[bytes, int]]:
    """The codec benchmark's message mix (protocol/bench.py) as CRC frames, each with its epoch."""
    frames = []
    for seq, message in enumerate(BENCH_MESSAGES):
        dst = BROADCAST if message.TYPE == MessageType.HEARTBEAT else 2
        header = Header(PROTOCOL_VERSION, FrameFlags.NONE, 3, 0, message.TYPE, 1, dst, seq)
        frame = encode_frame(header, message)
        epoch = BENCH_EPOCH
        if message.TYPE == MessageType.HEARTBEAT and len(frame) == HEARTBEAT_FRAME_BYTES:
            epoch = _U32.unpack_from(frame, HEARTBEAT_EPOCH_OFFSET)[0]
        frames.append((frame, epoch))
    return frames


def seal_open_rate(seconds: float, clock: Callable[[], float]) -> float:
    """seal+open pairs per second over the codec benchmark's mix of control frames, measured for
    about `seconds` s of `clock` (e.g. time.perf_counter: the mesh package reads no clock itself)."""
    sealer = FrameSealer(_BENCH_KEY)
    seal, open_ = sealer.seal, sealer.open
    pairs = _bench_frames()
    count = 0
    start = clock()
    while True:
        for _ in range(100):
            for frame, epoch in pairs:
                open_(seal(frame, epoch), epoch)
        count += 100 * len(pairs)
        elapsed = clock() - start
        if elapsed >= seconds:
            break
    return count / elapsed if elapsed > 0 else float("inf")

