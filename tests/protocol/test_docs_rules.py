"""The rules issue 23 settled, read from docs/protocol.md and checked against the code: the integer
rounding rule as the page writes it, command types, reasons, unicast Heartbeats, SegmentAck's base,
the ForwardMsg whose inner type byte is out of range, the decoding order's length rule, and the
defaults and result transitions of sections 7 and 8."""

from __future__ import annotations

import ast
import dataclasses
import math
import re
import zlib
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rescuemesh.protocol import (
    BROADCAST, DataKind, EncodeError, Endpoint, EndpointConfig, ForwardMsg, HeartbeatReceived, MessageType,
    Reason, ResultCode, decode_frame, encode_frame)
from rescuemesh.protocol.codec import FrameFlags, Header, decode_inner
from rescuemesh.protocol.errors import MalformedPayload, UnknownMessageType
from rescuemesh.protocol.messages import COMMAND_TYPES, Confirm, Data, Heartbeat, SegmentAck
from rescuemesh.protocol.payloads import MAX_SEGMENTS
from rescuemesh.protocol.reliability import RESULT_TRANSITIONS, ReliabilityConfig
from rescuemesh.protocol.wire import TAU, period_to_units, position_to_units, radius_to_units, yaw_to_units

DOCS = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"
T = MessageType


def section(number: int) -> str:
    text = DOCS.read_text(encoding="utf-8")
    start = text.index(f"\n## {number}. ")
    end = text.find("\n## ", start + 1)
    return text[start : end if end >= 0 else None]


def frame(msg_type: MessageType, message, src: int = 1, dst: int = 2, seq: int = 7) -> bytes:
    return encode_frame(Header(1, FrameFlags.NONE, 3, 0, msg_type, src, dst, seq), message)


# --- section 3: the integer rule, as the page writes it --------------------------------------------


def doc_units():
    """The `units` function of section 3's Python block, run as written."""
    blocks = re.findall(r"```python\n(.*?)```", section(3), flags=re.DOTALL)
    [block] = [b for b in blocks if "def units(" in b]
    namespace: dict = {}
    exec(compile(block, f"{DOCS}:section 3", "exec"), namespace)  # noqa: S102  (our own document)
    return namespace["units"]


CODEC = {"x": position_to_units, "period": period_to_units, "radius": radius_to_units, "yaw": yaw_to_units}
RANGES = {"x": (-32768, 32767), "period": (0, 255), "radius": (1, 65535)}


def codec_or_none(field: str, value: float) -> int | None:
    try:
        return CODEC[field](value)
    except EncodeError:
        return None


def doc_or_none(units, field: str, value: float) -> int | None:
    n = units(value, field)
    if field in RANGES and not RANGES[field][0] <= n <= RANGES[field][1]:
        return None
    return n


def conformance_inputs() -> list[tuple[str, float]]:
    rows = [line for line in section(3).splitlines() if re.match(r"\| (x|period|radius|yaw) \| `", line)]
    return [(row.split("|")[1].strip(), float(row.split("|")[2].strip().strip("`"))) for row in rows]


def test_the_doc_rule_matches_the_codec_on_the_conformance_table():
    units = doc_units()
    inputs = conformance_inputs()
    assert len(inputs) >= 20 and {f for f, _ in inputs} == {"x", "period", "radius", "yaw"}
    for field, value in inputs:
        assert doc_or_none(units, field, value) == codec_or_none(field, value), (field, value)


@given(field=st.sampled_from(sorted(CODEC)),
       value=st.floats(allow_nan=False, allow_infinity=False, min_value=-1e6, max_value=1e6))
def test_the_doc_rule_matches_the_codec_and_exact_arithmetic(field, value):
    units = doc_units()
    n = units(value, field)
    scale = {"x": 100, "radius": 100, "period": 10}.get(field)
    exact = Fraction(value) * 65536 / Fraction(TAU) if field == "yaw" else Fraction(value) * scale
    assert n == (round(exact) % 65536 if field == "yaw" else round(exact))
    assert doc_or_none(units, field, value) == codec_or_none(field, value)


def test_the_doc_rule_wraps_yaw_ties_to_even():
    units = doc_units()
    half = TAU / 131072  # X = -1/2 exactly: the even neighbour 0
    assert units(-half, "yaw") == 0 and units(math.nextafter(-half, -1.0), "yaw") == 65535
    assert units(-3 * half, "yaw") == 65534  # X = -3/2: -2, wrapped


# --- section 4: command types, reasons, addresses, SegmentAck's base --------------------------------


def documented_command_types() -> set[int]:
    match = re.search(r"\*\*A command type\*\* is one of the nine assigned commands, (\d+)\.\.(\d+)", section(4))
    assert match, "section 4 defines 'a command type'"
    return set(range(int(match[1]), int(match[2]) + 1))


def decodes(data: bytes) -> bool:
    try:
        decode_frame(data)
    except MalformedPayload:
        return False
    return True


def test_a_command_type_is_an_assigned_one_in_heartbeats_and_confirms():
    commands = documented_command_types()
    assert commands == set(COMMAND_TYPES) == set(range(1, 10))
    heartbeat = bytearray(frame(T.HEARTBEAT, Heartbeat(0, 3), dst=BROADCAST))
    confirm = bytearray(frame(T.CONFIRM, Confirm(7, T.FOLLOW, ResultCode.ACCEPTED), src=2, dst=1))
    for value in range(64):
        heartbeat[6] = confirm[8] = value  # active_command; ref_type
        fixed = [bytes(b[:-4]) + zlib.crc32(b[:-4]).to_bytes(4, "big") for b in (heartbeat, confirm)]
        assert decodes(fixed[0]) == (value == 0 or value in commands), value
        assert decodes(fixed[1]) == (value in commands | {T.POSE_UPDATE, T.DATA}), value
    for unassigned in (10, 31):
        with pytest.raises(EncodeError):
            frame(T.HEARTBEAT, Heartbeat(unassigned, 3), dst=BROADCAST)
        with pytest.raises(EncodeError):
            frame(T.CONFIRM, Confirm(7, unassigned, ResultCode.ACCEPTED), src=2, dst=1)


def test_any_reason_goes_with_any_result_on_the_wire():
    assert "That is a sender's rule, not a value rule" in section(4)
    for result in ResultCode:
        for reason in Reason:
            data = frame(T.CONFIRM, Confirm(7, T.GOTO, result, 255, reason), src=2, dst=1)
            assert decode_frame(data)[1] == Confirm(7, T.GOTO, result, 255, reason)


def test_a_heartbeat_may_go_to_one_robot():
    assert "A Heartbeat may also go to one robot (0..254)" in section(4)
    data = frame(T.HEARTBEAT, Heartbeat(1, 3, 2, 0x16), src=1, dst=2, seq=9)
    assert decode_frame(data)[0].dst == 2
    endpoint = Endpoint(2)
    endpoint.receive(data, 0.0)
    event = endpoint.next_event()
    assert isinstance(event, HeartbeatReceived) and (event.src, event.active_command) == (1, 1)
    other = Endpoint(3)  # not for robot 3: dropped as any unicast frame for another robot
    other.receive(data, 0.0)
    assert other.next_event() is None and other.stats.frames_not_for_us == 1


def test_segment_ack_base_is_at_most_the_segment_count_of_the_largest_frame():
    match = re.search(r"`base` is 0\.\.(\d+): a logical frame has at most (\d+)", section(4))
    assert match and int(match[1]) == int(match[2]) == MAX_SEGMENTS == 512
    from rescuemesh.mesh import segments  # the mesh layer cuts frames into 16-byte segments

    assert segments.MAX_SEGMENTS == MAX_SEGMENTS
    assert decode_frame(frame(T.SEGMENT_ACK, SegmentAck(1, 512, 0), src=2, dst=1))[1].base == 512
    # this used to pass up to 4096
    with pytest.raises(EncodeError):
        frame(T.SEGMENT_ACK, SegmentAck(1, 513, 0), src=2, dst=1)


# --- section 5: the ForwardMsg whose inner type byte is out of range --------------------------------


def test_forward_msg_with_an_out_of_range_inner_type_byte():
    text = DOCS.read_text(encoding="utf-8")
    block = text.split("<!-- inner-type-out-of-range -->")[1].split("<!-- /inner-type-out-of-range -->")[0]
    forward, answer = [bytes.fromhex(line) for line in re.findall(r"^[0-9A-F ]+$", block, flags=re.MULTILINE)]
    header, message = decode_frame(forward)  # a valid frame: the codec never looks inside
    assert isinstance(message, ForwardMsg) and message.message[0] > 63
    with pytest.raises(UnknownMessageType):
        decode_inner(message.message)
    from rescuemesh.robot.forwarding import Forwarder  # the robot that forwards it parses it

    assert Forwarder(header.dst).accept(header.src, header.seq, message.target, message.message, 0.0) \
        == Reason.BAD_REQUEST
    reply_header, reply = decode_frame(answer)
    assert (reply_header.src, reply_header.dst) == (header.dst, header.src)
    assert reply == Confirm(header.seq, T.FORWARD_MSG, ResultCode.DENIED, 255, Reason.BAD_REQUEST)


# --- section 6: length first ------------------------------------------------------------------------


def test_decoding_order_step_1_names_both_length_errors():
    assert "length > 8192 (`MAX_MESSAGE_BYTES`): `MalformedPayload`" in section(6)
    body = frame(T.DATA, Data(DataKind.RAW, 7, b""))[:-4] + bytes(8192 - 13 + 1)  # 8193 bytes with its CRC
    data = body + zlib.crc32(body).to_bytes(4, "big")
    assert len(data) == 8193
    with pytest.raises(MalformedPayload):
        decode_frame(data)
    # the length comes before the version (step 2) and the CRC (step 4)
    with pytest.raises(MalformedPayload):
        decode_frame(bytes((0x83,)) + data[1:])
    with pytest.raises(MalformedPayload):
        decode_frame(data[:-1] + bytes((data[-1] ^ 1,)))


# --- sections 7 and 8: defaults and result transitions ----------------------------------------------


def api_defaults(name: str) -> dict[str, object]:
    """Keyword defaults of `name(...)` in section 8's API block."""
    block = re.search(r"```python\n(.*?)```", section(8), flags=re.DOTALL)[1]
    start = block.index(f"\n{name}(") + 1
    depth, end = 0, start
    for end in range(start, len(block)):
        depth += {"(": 1, ")": -1}.get(block[end], 0)
        if depth == 0 and block[end] == ")":
            break
    call = ast.parse(block[start : end + 1], mode="eval").body
    return {kw.arg: kw.value for kw in call.keywords}


def default_of(cls, name: str):
    spec = {f.name: f for f in dataclasses.fields(cls)}[name]
    return spec.default_factory() if spec.default is dataclasses.MISSING else spec.default


def test_section_8_gives_every_config_field_with_its_default():
    reliability = api_defaults("ReliabilityConfig")
    assert set(reliability) == {f.name for f in dataclasses.fields(ReliabilityConfig)}
    for name, node in reliability.items():
        assert ast.literal_eval(node) == default_of(ReliabilityConfig, name), name
    endpoint = api_defaults("EndpointConfig")
    assert set(endpoint) == {f.name for f in dataclasses.fields(EndpointConfig)}
    assert ast.unparse(endpoint["reliability"]) == "ReliabilityConfig()"
    assert ast.unparse(endpoint["initial_ttl"]) == "DEFAULT_TTL"
    assert re.search(r"DEFAULT_TTL = (\d+)", section(8))[1] == str(default_of(EndpointConfig, "initial_ttl")) == "7"
    for name in ("heartbeat_ttl", "initial_seq", "initial_epoch", "announce_epoch_on_resend"):
        assert ast.literal_eval(endpoint[name]) == default_of(EndpointConfig, name), name
    # this used to say initial_ttl=3: an endpoint sends with 7 unless told otherwise
    assert EndpointConfig().initial_ttl == 7


def test_section_7_transition_table_is_result_transitions():
    rows = re.findall(r"^\| ([A-Z_, ]+|nothing) \| ([^|]+) \|$", section(7), flags=re.MULTILINE)
    table = {}
    for last, nxt in rows:
        allowed = set(ResultCode) if nxt.strip() == "any result" else \
            set() if nxt.startswith("nothing") else {ResultCode[n.strip()] for n in nxt.split(",")}
        for name in last.split(","):
            table[None if name.strip() == "nothing" else ResultCode[name.strip()]] = allowed
    assert table == {k: set(v) for k, v in RESULT_TRANSITIONS.items()}
