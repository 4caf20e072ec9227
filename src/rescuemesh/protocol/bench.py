"""Codec throughput: encode+decode round trips per second over a mix of message types.
Owns the benchmark loop only; must not read a clock itself: the caller passes one (the CLI bench
passes time.perf_counter), so the protocol package stays free of time and I/O.
"""

from __future__ import annotations

from typing import Callable

from .codec import PROTOCOL_VERSION, FrameFlags, Header, encode_frame, parse_frame
from .messages import (
    Confirm,
    Follow,
    Heartbeat,
    Message,
    MessageType,
    MoveAround,
    Pose,
    PoseUpdate,
    ResultCode,
    ShowCam,
    Stop,
)

_POSE = Pose(12.34, -5.67, 0.0, 1.2345)

#: The mix: mostly the stream of a Follow (PoseUpdate + Confirm), some commands and heartbeats.
BENCH_MESSAGES: tuple[Message, ...] = (
    PoseUpdate(_POSE),
    Confirm(7, MessageType.POSE_UPDATE, ResultCode.ACCEPTED),
    PoseUpdate(Pose(12.5, -5.5, 0.0, 1.3)),
    Confirm(8, MessageType.POSE_UPDATE, ResultCode.ACCEPTED),
    Follow(_POSE),
    MoveAround(_POSE, 1.5),
    ShowCam(_POSE, 0.5, 10),
    Stop(),
    Heartbeat(int(MessageType.FOLLOW), 3),
)


def _mix() -> list[tuple[Header, Message]]:
    pairs = []
    for seq, message in enumerate(BENCH_MESSAGES):
        dst = 0xFF if message.TYPE == MessageType.HEARTBEAT else 2
        header = Header(PROTOCOL_VERSION, FrameFlags.NONE, 3, 0, message.TYPE, 1, dst, seq)
        pairs.append((header, message))
    return pairs


def codec_roundtrip_rate(seconds: float, clock: Callable[[], float]) -> float:
    """Encode+decode pairs per second, measured for about `seconds` s of `clock` (a callable
    returning seconds, e.g. time.perf_counter). Runs at least one pass over the mix."""
    pairs = _mix()
    count = 0
    start = clock()
    elapsed = 0.0
    while True:
        for _ in range(100):
            for header, message in pairs:
                parse_frame(encode_frame(header, message))  # not decode_frame: it remembers
        count += 100 * len(pairs)
        elapsed = clock() - start
        if elapsed >= seconds:
            break
    return count / elapsed if elapsed > 0 else float("inf")
