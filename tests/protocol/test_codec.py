"""Wire format: golden bytes, round trips, frame sizes and every way a frame can be bad."""

from __future__ import annotations

import math
import re
import zlib
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rescuemesh.protocol import (
    BROADCAST, EncodeError, Follow, ForwardMsg, FrameError, Goto, DataKind, Reason, LandOnTop, MessageType,
    MoveAround, Pose, ResultCode, Return, ShowCam, ShowScan, Stop, decode_frame, encode_frame)
from rescuemesh.protocol.codec import (
    MAX_CONTROL_FRAME_BYTES, MAX_FORWARD_MESSAGE_BYTES, PAYLOAD_BYTES, FrameFlags, Header,
    MAX_FORWARD_INNER_BYTES, MAX_MESSAGE_BYTES, PROTOCOL_VERSION, decode_inner, encode_inner, max_frame_bytes,
    parse_frame)
from rescuemesh.protocol.errors import (
    IntegrityError, MalformedPayload, TruncatedFrame, UnknownMessageType, UnsupportedFeature,
    UnsupportedVersion)
from rescuemesh.protocol.messages import Confirm, Heartbeat, Data, SegmentAck, PoseUpdate
from rescuemesh.protocol.codec import (
    pull_crc,
    pull_header,
    pull_period,
    pull_pose,
    pull_radius,
    pull_u8,
    pull_u16,
    push_crc,
    push_header,
    push_period,
    push_pose,
    push_radius,
    push_u8,
    push_u16,
)

from .strategies import frames, poses

DOCS = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"


def with_crc(hex_prefix: str) -> bytes:
    """Hand-written header + payload, plus its CRC-32 (big-endian) as the spec says."""
    data = bytes.fromhex(hex_prefix)
    return data + zlib.crc32(data).to_bytes(4, "big")


def hdr(msg_type, src=1, dst=2, seq=7, attempt=0, ttl=3) -> Header:
    return Header(1, FrameFlags.NONE, ttl, attempt, MessageType(msg_type), src, dst, seq)


# Pose(1.5, -2.25, 0.1, pi/2): 150 cm, -225 cm (0xFF1F), 10 cm, 16384 yaw units.
P = Pose(1.5, -2.25, 0.1, math.pi / 2)
P_HEX = "0096 FF1F 000A 4000"
# Pose(-10.0, 20.48, 0.0, pi): -1000 cm (0xFC18), 2048 cm, 0 cm, 32768 yaw units.
Q = Pose(-10.0, 20.48, 0.0, math.pi)
Q_HEX = "FC18 0800 0000 8000"
T = MessageType

# byte 0 = 0x43: version 1 (01......), AUTH 0, SEG 0, TTL 3. byte 1: attempt (bits 7-6) | type.
GOLDEN = [
    pytest.param("43 01 01 02 0007" + P_HEX, hdr(T.FOLLOW), Follow(P), id="Follow"),
    pytest.param("43 02 01 02 0007" + P_HEX + "05 0A", hdr(T.SHOW_CAM), ShowCam(P, 0.5, 10), id="ShowCam"),
    pytest.param("43 03 01 02 0007" + P_HEX + "14 00", hdr(T.SHOW_SCAN), ShowScan(P, 2.0, 0), id="ShowScan"),
    pytest.param("43 04 01 02 0007" + P_HEX, hdr(T.LAND_ON_TOP), LandOnTop(P), id="LandOnTop"),
    pytest.param("43 05 01 02 0007" + Q_HEX, hdr(T.GOTO), Goto(Q), id="Goto"),
    pytest.param("43 06 01 02 0007", hdr(T.STOP), Stop(), id="Stop"),
    pytest.param("43 07 01 02 0007 03 06", hdr(T.FORWARD_MSG), ForwardMsg(3, b"\x06"), id="ForwardMsg"),
    pytest.param("43 08 01 02 0007", hdr(T.RETURN), Return(), id="Return"),
    pytest.param("43 09 01 02 0007" + P_HEX + "00C8", hdr(T.MOVE_AROUND), MoveAround(P, 2.0), id="MoveAround"),
    pytest.param(
        "43 20 02 01 0003 0007 01 00 FF 00",
        hdr(T.CONFIRM, src=2, dst=1, seq=3),
        Confirm(7, T.FOLLOW, ResultCode.ACCEPTED, 255),
        id="Confirm",
    ),
    pytest.param("43 21 01 02 0008" + Q_HEX, hdr(T.POSE_UPDATE, seq=8), PoseUpdate(Q), id="PoseUpdate"),
    pytest.param("43 22 01 FF 0009 01 03 00000002 16", hdr(T.HEARTBEAT, dst=255, seq=9), Heartbeat(1, 3, 2, 0x16),
                 id="Heartbeat"),
    pytest.param(
        "43 20 02 01 0005 0007 01 05 FF 03",
        hdr(T.CONFIRM, src=2, dst=1, seq=5),
        Confirm(7, T.FOLLOW, ResultCode.FAILED, 255, Reason.LINK_LOST),
        id="Confirm-failed-link-lost",
    ),
    # SegmentAck for message seq 0x0102: segments 0..2 in, then 3, 5 and 47 of the next 48
    pytest.param("43 23 02 01 000A 0102 0003 8000 0000 0005", hdr(T.SEGMENT_ACK, src=2, dst=1, seq=10),
                 SegmentAck(0x0102, 3, (1 << 47) | 0b101), id="SegmentAck"),
    pytest.param("43 24 02 01 000B 02 0007 FFD8FF", hdr(T.DATA, src=2, dst=1, seq=11),
                 Data(DataKind.IMAGE_JPEG, 7, b"\xff\xd8\xff"), id="Data"),
    # header variants: attempt 2 (0x80 | 0x01), TTL 0 (0x40), seq 0xFFFF, address 254
    pytest.param("43 81 01 02 0007" + P_HEX, hdr(T.FOLLOW, attempt=2), Follow(P), id="Follow-resend-2"),
    pytest.param("40 06 FE 00 FFFF", hdr(T.STOP, src=254, dst=0, seq=0xFFFF, ttl=0), Stop(), id="Stop-edges"),
    pytest.param(
        "43 20 02 01 0004 0007 01 01 28 00",
        hdr(T.CONFIRM, src=2, dst=1, seq=4),
        Confirm(7, T.FOLLOW, ResultCode.IN_PROGRESS, 40),
        id="Confirm-in-progress",
    ),
]


@pytest.mark.parametrize("prefix, header, message", GOLDEN)
def test_golden_bytes_decode_and_reencode_exactly(prefix, header, message):
    data = with_crc(prefix)
    assert decode_frame(data) == (header, message)
    assert encode_frame(header, message) == data


def test_golden_covers_every_message_type():
    assert {p.values[1].msg_type for p in GOLDEN} == set(MessageType)


def test_docs_hex_examples_are_valid_frames():
    """Every hex frame line in docs/protocol.md decodes and re-encodes to itself."""
    lines = re.findall(r"^((?:[0-9A-F]{2} ?)+)$", DOCS.read_text(encoding="utf-8"), flags=re.MULTILINE)
    frames = [bytes.fromhex(line) for line in lines if len(line.split()) >= 10]
    types = set()
    for data in frames:
        header, message = decode_frame(data)
        assert encode_frame(header, message) == data
        types.add(header.msg_type)
    assert types == set(MessageType)


# --- hypothesis round trips ---------------------------------------------------------------------

def angle_error(a: float, b: float) -> float:
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


def assert_pose_close(got: Pose, want: Pose) -> None:
    tol = 0.005 + 1e-9  # half a cm, plus float noise in x * 100
    assert abs(got.x - want.x) <= tol and abs(got.y - want.y) <= tol and abs(got.z - want.z) <= tol
    assert angle_error(got.yaw, want.yaw) <= 1e-4
    assert 0.0 <= got.yaw < 2 * math.pi


def assert_close(got, want) -> None:
    assert type(got) is type(want)
    for name in want.__dataclass_fields__:
        g, w = getattr(got, name), getattr(want, name)
        if isinstance(w, Pose):
            assert_pose_close(g, w)
        elif name == "period_s":
            assert abs(g - w) <= 0.05 + 1e-9
        elif name == "radius_m":
            assert abs(g - w) <= 0.005 + 1e-9
        else:
            assert g == w, name


@given(frames())
def test_every_message_round_trips(frame):
    header, message = frame
    data = encode_frame(header, message)
    got_header, got_message = decode_frame(data)
    assert got_header == header
    assert_close(got_message, message)
    assert len(data) <= MAX_CONTROL_FRAME_BYTES
    # quantisation is stable: the decoded message encodes to the same bytes
    assert encode_frame(got_header, got_message) == data


@given(st.binary(min_size=1, max_size=MAX_CONTROL_FRAME_BYTES - 4))
def test_any_frame_with_a_good_crc_decodes_canonically_or_raises_frame_error(body):
    body = bytes([0x40 | (body[0] & 0x0F)]) + body[1:]  # version 1, no flags
    raw = with_crc(body.hex())
    try:
        header, message = decode_frame(raw)
    except FrameError:
        return
    assert encode_frame(header, message) == raw


@given(st.binary(max_size=40))
def test_arbitrary_bytes_raise_only_frame_errors(raw):
    try:
        decode_frame(raw)
    except FrameError:
        pass


# --- frame sizes --------------------------------------------------------------------------------

FAR = Pose(-327.68, 327.67, -327.68, 6.28)
LARGEST = [
    Follow(FAR), ShowCam(FAR, 25.5, 255), ShowScan(FAR, 25.5, 255), LandOnTop(FAR), Goto(FAR), Stop(),
    ForwardMsg(255, bytes(range(MAX_FORWARD_MESSAGE_BYTES))), Return(), MoveAround(FAR, 655.35),
    Confirm(0xFFFF, T.MOVE_AROUND, ResultCode.CANCELLED, 100), PoseUpdate(FAR), Heartbeat(9, 15),
]


@pytest.mark.parametrize("message", LARGEST, ids=lambda m: type(m).__name__)
def test_largest_frame_of_each_type_fits_the_budget(message):
    dst = BROADCAST if message.TYPE == T.HEARTBEAT else 254
    data = encode_frame(Header(1, FrameFlags.NONE, 15, 3, message.TYPE, 254, dst, 0xFFFF), message)
    assert len(data) == max_frame_bytes(message.TYPE) <= MAX_CONTROL_FRAME_BYTES == 20


def test_largest_control_frames_are_exactly_20_bytes():
    assert max(max_frame_bytes(t) for t in MessageType) == MAX_CONTROL_FRAME_BYTES
    assert {t for t in MessageType if max_frame_bytes(t) == 20} == {
        T.SHOW_CAM, T.SHOW_SCAN, T.MOVE_AROUND, T.FORWARD_MSG, T.SEGMENT_ACK, T.DATA,
    }
    assert set(PAYLOAD_BYTES) == set(MessageType)


# --- field pairs --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "push, pull, value, size",
    [
        (push_u8, pull_u8, 200, 1),
        (push_u16, pull_u16, 0xBEEF, 2),
        (push_pose, pull_pose, P, 8),
        (push_period, pull_period, 2.5, 1),
        (push_radius, pull_radius, 3.25, 2),
    ],
)
def test_field_pairs_are_symmetric(push, pull, value, size):
    buf = bytearray(b"\xAA")  # pulls start at an offset
    push(buf, value)
    assert len(buf) == 1 + size
    assert pull(bytes(buf), 1) == (value, 1 + size)


def test_header_and_crc_pairs_are_symmetric():
    buf = bytearray()
    push_header(buf, hdr(T.GOTO, seq=513))
    push_crc(buf)
    assert pull_header(bytes(buf), 0) == (hdr(T.GOTO, seq=513), 6)
    assert pull_crc(bytes(buf), 6) == (zlib.crc32(buf[:6]), 10)


@pytest.mark.parametrize("yaw, units", [(0.0, 0), (-math.pi / 2, 49152), (2 * math.pi, 0), (-1e-12, 0), (7 * math.pi, 32768)])
def test_yaw_is_wrapped_to_one_turn(yaw, units):
    buf = bytearray()
    push_pose(buf, Pose(0.0, 0.0, 0.0, yaw))
    assert int.from_bytes(buf[6:8], "big") == units


def test_inner_messages_round_trip_and_ride_in_forward_msg():
    inner = encode_inner(Follow(P))
    assert inner == bytes.fromhex("01" + P_HEX) and len(inner) == MAX_FORWARD_MESSAGE_BYTES
    assert decode_inner(inner) == Follow(P)
    header, message = decode_frame(encode_frame(hdr(T.FORWARD_MSG), ForwardMsg(3, inner)))
    assert decode_inner(message.message) == Follow(P)
    # 11 bytes: no longer a 20-byte control frame but a 21-byte logical frame the mesh segments
    long_frame = encode_frame(hdr(T.FORWARD_MSG), ForwardMsg(3, encode_inner(MoveAround(P, 1.0))))
    assert len(long_frame) == MAX_CONTROL_FRAME_BYTES + 2
    assert decode_inner(decode_frame(long_frame)[1].message) == MoveAround(P, 1.0)


def test_logical_frames_up_to_the_maximum_decode_and_longer_ones_are_refused():
    data = Data(DataKind.RAW, 9, bytes(range(256)) * 31 + bytes(MAX_MESSAGE_BYTES - 13 - 256 * 31))
    frame = encode_frame(hdr(T.DATA), data)
    assert len(frame) == MAX_MESSAGE_BYTES and decode_frame(frame) == (hdr(T.DATA), data)
    with pytest.raises(MalformedPayload):
        decode_frame(with_crc(frame[:-4].hex() + "00"))


@pytest.mark.parametrize("raw, error", [(b"", TruncatedFrame), (b"\x48", UnknownMessageType), (b"\x06\x00", MalformedPayload)])
def test_bad_inner_messages(raw, error):
    with pytest.raises(error):
        decode_inner(raw)


# --- malformed frames ---------------------------------------------------------------------------

MOVE_AROUND = with_crc("43 09 01 02 0007" + P_HEX + "00C8")  # a 20-byte frame


@pytest.mark.parametrize("length", range(len(MOVE_AROUND)))
def test_truncated_frames(length):
    expected = TruncatedFrame if length < 10 else IntegrityError
    with pytest.raises(expected):
        decode_frame(MOVE_AROUND[:length])


@pytest.mark.parametrize("prefix", [p.values[0] for p in GOLDEN], ids=[p.id for p in GOLDEN])
def test_flipping_any_bit_is_detected(prefix):
    data = with_crc(prefix)
    for position in range(len(data)):
        for bit in range(8):
            corrupt = bytearray(data)
            corrupt[position] ^= 1 << bit
            with pytest.raises(FrameError):
                decode_frame(bytes(corrupt))
            if not (position == 0 and bit >= 5):  # version and AUTH bits are checked before the CRC
                with pytest.raises(IntegrityError):
                    decode_frame(bytes(corrupt))


@pytest.mark.parametrize(
    "prefix, error",
    [
        pytest.param("03 06 01 02 0007", UnsupportedVersion, id="version-0"),
        pytest.param("83 06 01 02 0007", UnsupportedVersion, id="version-2"),
        pytest.param("C3 06 01 02 0007", UnsupportedVersion, id="version-3"),
        pytest.param("63 06 01 02 0007", UnsupportedFeature, id="auth-flag"),
        pytest.param("53 06 01 02 0007", UnsupportedFeature, id="seg-flag"),
        pytest.param("73 06 01 02 0007", UnsupportedFeature, id="both-flags"),
        pytest.param("43 00 01 02 0007", UnknownMessageType, id="type-0"),
        pytest.param("43 0A 01 02 0007", UnknownMessageType, id="type-10"),
        pytest.param("43 3F 01 02 0007", UnknownMessageType, id="type-63"),
        pytest.param("43 C0 01 02 0007", UnknownMessageType, id="type-0-attempt-3"),
        pytest.param("43 06 FF 02 0007", MalformedPayload, id="src-broadcast"),
        pytest.param("43 06 01 FF 0007", MalformedPayload, id="command-to-broadcast"),
        pytest.param("43 20 02 FF 0003 0007 01 00 FF", MalformedPayload, id="confirm-to-broadcast"),
        pytest.param("43 06 01 02 0007 00", MalformedPayload, id="stop-with-payload"),
        pytest.param("43 01 01 02 0007 0096FF1F000A40", MalformedPayload, id="follow-7-bytes"),
        pytest.param("43 01 01 02 0007 0096FF1F000A400000", MalformedPayload, id="follow-9-bytes"),
        pytest.param("43 09 01 02 0007" + P_HEX + "0000", MalformedPayload, id="radius-0"),
        pytest.param("43 09 01 02 0007" + P_HEX + "00", MalformedPayload, id="move-around-short"),
        pytest.param("43 02 01 02 0007" + P_HEX + "00 00", MalformedPayload, id="showcam-period-0-repeated"),
        pytest.param("43 03 01 02 0007" + P_HEX + "05", MalformedPayload, id="showscan-short"),
        pytest.param("43 20 02 01 0003 0007 01 07 FF", MalformedPayload, id="result-7"),
        pytest.param("43 20 02 01 0003 0007 01 FF FF", MalformedPayload, id="result-255"),
        pytest.param("43 20 02 01 0003 0007 01 01 65", MalformedPayload, id="progress-101"),
        pytest.param("43 20 02 01 0003 0007 22 00 FF", MalformedPayload, id="confirm-of-heartbeat"),
        pytest.param("43 20 02 01 0003 0007 00 00 FF", MalformedPayload, id="confirm-of-type-0"),
        pytest.param("43 20 02 01 0003 0007 41 00 FF", MalformedPayload, id="confirm-ref-type-high-bits"),
        pytest.param("43 20 02 01 0003 0007 01 00", MalformedPayload, id="confirm-short"),
        pytest.param("43 07 01 02 0007 03", MalformedPayload, id="forward-empty"),
        pytest.param("43 24 01 02 0007 09 0001", MalformedPayload, id="data-kind-9"),
        pytest.param("43 24 01 02 0007 00 00", MalformedPayload, id="data-short"),
        # this used to pass up to base 4096, though no message has more than 512 segments
        pytest.param("43 23 01 02 0007 0001 0201 000000000000", MalformedPayload, id="segment-ack-base-513"),
        pytest.param("43 23 01 FF 0007 0001 0001 000000000000", MalformedPayload, id="segment-ack-broadcast"),
        pytest.param("43 20 02 01 0003 0007 01 05 FF 40", MalformedPayload, id="confirm-reason-64"),
        pytest.param("43 22 01 FF 0009 20 03", MalformedPayload, id="heartbeat-active-confirm"),
        pytest.param("43 22 01 FF 0009 01 10", MalformedPayload, id="heartbeat-init-ttl-16"),
        pytest.param("43 22 01 FF 0009 01", MalformedPayload, id="heartbeat-short"),
    ],
)
def test_malformed_frames_raise_typed_errors(prefix, error):
    with pytest.raises(error):
        decode_frame(with_crc(prefix))


def test_auth_flag_is_reported_before_the_integrity_check():
    data = bytearray(with_crc("63 06 01 02 0007"))
    data[-1] ^= 0xFF  # a MIC is not a CRC: the flag, not the mismatch, is the reason
    with pytest.raises(UnsupportedFeature):
        decode_frame(bytes(data))


def test_showcam_once_may_have_period_zero():
    assert decode_frame(with_crc("43 02 01 02 0007" + P_HEX + "00 01"))[1] == ShowCam(P, 0.0, 1)


def test_frame_errors_are_value_errors_and_encode_errors_are_not_frame_errors():
    for error in (TruncatedFrame, IntegrityError, UnsupportedVersion, UnknownMessageType, MalformedPayload, UnsupportedFeature):
        assert issubclass(error, FrameError) and issubclass(error, ValueError)
    assert issubclass(EncodeError, ValueError) and not issubclass(EncodeError, FrameError)


# --- values that cannot be encoded --------------------------------------------------------------

INF, NAN = float("inf"), float("nan")


@pytest.mark.parametrize(
    "header, message",
    [
        pytest.param(hdr(T.GOTO), Goto(Pose(327.68, 0, 0, 0)), id="x-too-far"),
        pytest.param(hdr(T.GOTO), Goto(Pose(0, -327.69, 0, 0)), id="y-too-far"),
        pytest.param(hdr(T.GOTO), Goto(Pose(0, 0, 1000, 0)), id="z-too-far"),
        pytest.param(hdr(T.GOTO), Goto(Pose(NAN, 0, 0, 0)), id="x-nan"),
        pytest.param(hdr(T.GOTO), Goto(Pose(0, INF, 0, 0)), id="y-inf"),
        pytest.param(hdr(T.GOTO), Goto(Pose(0, 0, 0, INF)), id="yaw-inf"),
        pytest.param(hdr(T.GOTO), Goto(Pose(0, 0, 0, NAN)), id="yaw-nan"),
        pytest.param(hdr(T.GOTO), Goto(None), id="not-a-pose"),
        pytest.param(hdr(T.MOVE_AROUND), MoveAround(P, 0.0), id="radius-0"),
        pytest.param(hdr(T.MOVE_AROUND), MoveAround(P, 0.004), id="radius-rounds-to-0"),
        pytest.param(hdr(T.MOVE_AROUND), MoveAround(P, -1.0), id="radius-negative"),
        pytest.param(hdr(T.MOVE_AROUND), MoveAround(P, 655.36), id="radius-too-big"),
        pytest.param(hdr(T.MOVE_AROUND), MoveAround(P, NAN), id="radius-nan"),
        pytest.param(hdr(T.SHOW_CAM), ShowCam(P, -0.1, 1), id="period-negative"),
        pytest.param(hdr(T.SHOW_CAM), ShowCam(P, 25.6, 1), id="period-too-long"),
        pytest.param(hdr(T.SHOW_CAM), ShowCam(P, 0.0, 0), id="period-0-repeated"),
        pytest.param(hdr(T.SHOW_SCAN), ShowScan(P, 1.0, 256), id="count-256"),
        pytest.param(hdr(T.SHOW_SCAN), ShowScan(P, 1.0, -1), id="count-negative"),
        pytest.param(hdr(T.SHOW_SCAN), ShowScan(P, 1.0, 1.5), id="count-not-int"),
        pytest.param(hdr(T.SHOW_SCAN), ShowScan(P, 1.0, "2"), id="count-str"),
        pytest.param(hdr(T.FORWARD_MSG), ForwardMsg(3, bytes(MAX_FORWARD_INNER_BYTES + 1)), id="forward-too-long"),
        pytest.param(hdr(T.DATA), Data(DataKind.RAW, 1, bytes(MAX_MESSAGE_BYTES)), id="data-too-long"),
        pytest.param(hdr(T.DATA), Data(9, 1, b""), id="data-kind-9"),
        pytest.param(hdr(T.SEGMENT_ACK), SegmentAck(1, 513, 0), id="segment-ack-base-513"),
        pytest.param(hdr(T.SEGMENT_ACK), SegmentAck(1, 0, 1 << 48), id="segment-ack-bitmap-49-bits"),
        pytest.param(hdr(T.SEGMENT_ACK, dst=255), SegmentAck(1, 0, 0), id="segment-ack-broadcast"),
        pytest.param(hdr(T.CONFIRM), Confirm(7, T.FOLLOW, ResultCode.FAILED, 255, 200), id="reason-200"),
        pytest.param(hdr(T.FORWARD_MSG), ForwardMsg(3, b""), id="forward-empty"),
        pytest.param(hdr(T.FORWARD_MSG), ForwardMsg(256, b"\x06"), id="forward-target-256"),
        pytest.param(hdr(T.FORWARD_MSG), ForwardMsg(3, "text"), id="forward-str"),
        pytest.param(hdr(T.CONFIRM), Confirm(7, T.FOLLOW, ResultCode.DONE, 101), id="progress-101"),
        pytest.param(hdr(T.CONFIRM), Confirm(7, T.HEARTBEAT, ResultCode.DONE), id="confirm-heartbeat"),
        pytest.param(hdr(T.CONFIRM), Confirm(7, T.FOLLOW, 9), id="result-9"),
        pytest.param(hdr(T.CONFIRM), Confirm(65536, T.FOLLOW, ResultCode.DONE), id="ref-seq-65536"),
        pytest.param(hdr(T.HEARTBEAT, dst=255), Heartbeat(32, 3), id="heartbeat-active-confirm"),
        pytest.param(hdr(T.HEARTBEAT, dst=255), Heartbeat(1, 16), id="heartbeat-init-ttl-16"),
        pytest.param(hdr(T.STOP, src=255), Stop(), id="src-255"),
        pytest.param(hdr(T.STOP, dst=255), Stop(), id="stop-broadcast"),
        pytest.param(hdr(T.STOP, dst=256), Stop(), id="dst-256"),
        pytest.param(hdr(T.STOP, seq=65536), Stop(), id="seq-65536"),
        pytest.param(hdr(T.STOP, seq=-1), Stop(), id="seq-negative"),
        pytest.param(hdr(T.STOP, ttl=16), Stop(), id="ttl-16"),
        pytest.param(hdr(T.STOP, attempt=4), Stop(), id="attempt-4"),
        pytest.param(hdr(T.STOP, src="1"), Stop(), id="src-str"),
        pytest.param(Header(2, FrameFlags.NONE, 3, 0, T.STOP, 1, 2, 7), Stop(), id="version-2"),
        pytest.param(Header(1, FrameFlags.AUTH, 3, 0, T.STOP, 1, 2, 7), Stop(), id="auth-flag"),
        pytest.param(Header(1, FrameFlags.SEG, 3, 0, T.STOP, 1, 2, 7), Stop(), id="seg-flag"),
        pytest.param(hdr(T.RETURN), Stop(), id="type-mismatch"),
        pytest.param(hdr(T.STOP), "Stop", id="not-a-message"),
    ],
)
def test_unencodable_values_raise_encode_error(header, message):
    with pytest.raises(EncodeError):
        encode_frame(header, message)


def test_coordinates_at_the_edges_of_int16_encode():
    data = encode_frame(hdr(T.GOTO), Goto(Pose(-327.68, 327.67, -327.68, 0.0)))
    assert data[6:12] == bytes.fromhex("8000 7FFF 8000")


@given(poses)
def test_pose_decode_is_exact_for_decoded_values(pose):
    buf = bytearray()
    push_pose(buf, pose)
    decoded, _ = pull_pose(bytes(buf), 0)
    again = bytearray()
    push_pose(again, decoded)
    assert again == buf


@pytest.mark.parametrize("bits", range(0x20))
def test_a_decoded_heartbeat_carries_the_capability_flags_it_announced(bits):
    # read through a table of the 32 valid sets since issue 21: a wrong entry would hand a robot
    # another robot's abilities (LandOnTop on a robot without a pad)
    from rescuemesh.protocol.messages import Capability

    header = hdr(MessageType.HEARTBEAT, dst=255)
    _, message = decode_frame(encode_frame(header, Heartbeat(0, 3, 7, bits)))
    assert isinstance(message.capabilities, Capability)
    assert message.capabilities == Capability(bits)
    assert [flag for flag in Capability if flag and flag in message.capabilities] == \
        [flag for flag in Capability if flag & bits]


def test_decode_frame_remembers_a_result_and_never_an_error():
    """The robots of a simulated team that hear one frame decode it once: the same bytes give the
    same frozen objects; bytes that do not decode raise every time."""
    header = Header(PROTOCOL_VERSION, FrameFlags.NONE, 3, 0, MessageType.HEARTBEAT, 1, BROADCAST, 77)
    frame = encode_frame(header, Heartbeat(0, 3, 9, 0))
    first = decode_frame(frame)
    assert decode_frame(bytearray(frame)) is first  # an equal copy, any bytes-like: the one result
    assert first == parse_frame(frame) and first is not parse_frame(frame)
    broken = frame[:-1] + bytes((frame[-1] ^ 1,))
    for _ in range(2):
        with pytest.raises(IntegrityError):
            decode_frame(broken)
