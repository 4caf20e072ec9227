"""Test helper: real protocol frames (through the codec) for mesh tests."""

from __future__ import annotations

from rescuemesh.protocol import BROADCAST, DataKind, MessageType, Pose, Stop, encode_frame
from rescuemesh.protocol.codec import FrameFlags, Header
from rescuemesh.protocol.messages import Data, Heartbeat, PoseUpdate


def heartbeat(src: int, seq: int, ttl: int = 7, init_ttl: int | None = None) -> bytes:
    """A broadcast Heartbeat sent with TTL `ttl`, announcing `init_ttl` (default: `ttl`)."""
    init = ttl if init_ttl is None else init_ttl
    header = Header(1, FrameFlags.NONE, ttl, 0, MessageType.HEARTBEAT, src, BROADCAST, seq)
    return encode_frame(header, Heartbeat(0, init))


def stop(src: int, dst: int, seq: int, ttl: int = 7, attempt: int = 0) -> bytes:
    """A 10-byte Stop command (a control frame)."""
    return encode_frame(Header(1, FrameFlags.NONE, ttl, attempt, MessageType.STOP, src, dst, seq), Stop())


def pose_update(src: int, dst: int, seq: int, ttl: int = 7, attempt: int = 0) -> bytes:
    """A PoseUpdate of the leader `src` to its follower `dst`."""
    header = Header(1, FrameFlags.NONE, ttl, attempt, MessageType.POSE_UPDATE, src, dst, seq)
    return encode_frame(header, PoseUpdate(Pose(1.0, 2.0, 0.0, 0.5)))


def data(src: int, dst: int, seq: int, size: int, ttl: int = 7, attempt: int = 0) -> bytes:
    """A Data frame of exactly `size` bytes (>= 13), its payload a recognisable byte pattern."""
    body = bytes((i * 7 + seq) % 251 for i in range(size - 13))
    header = Header(1, FrameFlags.NONE, ttl, attempt, MessageType.DATA, src, dst, seq)
    frame = encode_frame(header, Data(DataKind.LASER_SCAN, 7, body))
    assert len(frame) == size
    return frame
