"""Hypothesis strategies for protocol values, within the encodable ranges of docs/protocol.md."""

from __future__ import annotations

from hypothesis import strategies as st

from rescuemesh.protocol import (
    DataKind, Follow, ForwardMsg, Goto, LandOnTop, MessageType, MoveAround, Pose, Reason, ResultCode, Return,
    ShowCam, ShowScan, Stop)
from rescuemesh.protocol.codec import MAX_FORWARD_MESSAGE_BYTES, FrameFlags, Header
from rescuemesh.protocol.messages import (
    COMMAND_TYPES, CONFIRMABLE_TYPES, Confirm, Data, Heartbeat, PoseUpdate, SegmentAck)

coords = st.floats(-327.67, 327.67, allow_nan=False)
yaws = st.floats(-1000.0, 1000.0, allow_nan=False)
poses = st.builds(Pose, coords, coords, coords, yaws)
repeat = st.one_of(
    st.tuples(st.floats(0.1, 25.5), st.integers(0, 255)),
    st.tuples(st.floats(0.0, 25.5), st.just(1)),  # once: any period, 0 included
)
messages = st.one_of(
    st.builds(Follow, poses),
    repeat.flatmap(lambda r: st.builds(ShowCam, poses, st.just(r[0]), st.just(r[1]))),
    repeat.flatmap(lambda r: st.builds(ShowScan, poses, st.just(r[0]), st.just(r[1]))),
    st.builds(LandOnTop, poses),
    st.builds(Goto, poses),
    st.just(Stop()),
    st.builds(ForwardMsg, st.integers(0, 255), st.binary(min_size=1, max_size=MAX_FORWARD_MESSAGE_BYTES)),
    st.just(Return()),
    st.builds(MoveAround, poses, st.floats(0.01, 655.35)),
    st.builds(
        Confirm,
        st.integers(0, 0xFFFF),
        st.sampled_from(sorted(CONFIRMABLE_TYPES)),
        st.sampled_from(ResultCode),
        st.one_of(st.integers(0, 100), st.just(255)),
        st.sampled_from(Reason),
    ),
    st.builds(PoseUpdate, poses),
    st.builds(Heartbeat, st.sampled_from([0, *sorted(COMMAND_TYPES)]), st.integers(0, 15), st.integers(0, 2**32 - 1),
              st.integers(0, 0x1F)),
    st.builds(SegmentAck, st.integers(0, 0xFFFF), st.integers(0, 512), st.integers(0, 2**48 - 1)),
    # up to 7 data bytes: a control frame (13-byte overhead); longer ones are logical frames
    st.builds(Data, st.sampled_from(DataKind), st.integers(0, 0xFFFF), st.binary(max_size=7)),
)


@st.composite
def frames(draw, src=st.integers(0, 254), dst=None):
    message = draw(messages)
    is_heartbeat = message.TYPE == MessageType.HEARTBEAT
    header = Header(
        1,
        FrameFlags.NONE,
        draw(st.integers(0, 15)),
        draw(st.integers(0, 3)),
        message.TYPE,
        draw(src),
        draw(dst if dst is not None else st.integers(0, 255 if is_heartbeat else 254)),
        draw(st.integers(0, 0xFFFF)),
    )
    return header, message
