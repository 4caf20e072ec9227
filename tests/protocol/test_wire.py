"""The rules of docs/protocol.md a third party implements, checked against independent references:
exact quantisation (Fraction arithmetic), its C recipe, error bounds, the conformance table, CRC-32,
attempt bits of frames never retried and the inner message's type byte."""

from __future__ import annotations

import ctypes
import ctypes.util
import math
import re
import struct
from fractions import Fraction
from pathlib import Path

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from rescuemesh.protocol import (
    EncodeError, Endpoint, Follow, MessageType, Pose, ResultCode, Return, Stop, decode_frame, encode_frame)
from rescuemesh.protocol.codec import FrameFlags, Header, decode_inner, encode_inner
from rescuemesh.protocol.errors import UnknownMessageType
from rescuemesh.protocol.messages import Confirm, Heartbeat, SegmentAck
from rescuemesh.protocol.wire import (
    TAU,
    YAW_UNIT_RAD,
    position_to_units,
    period_to_units,
    pull_period,
    pull_pose,
    pull_radius,
    push_crc,
    push_period,
    push_pose,
    push_radius,
    radius_to_units,
    yaw_to_units,
)

DOCS = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"
TAU_Q = Fraction(TAU)

# --- the rule, written independently of the codec: Fraction is exact, round(Fraction) is half-even


def ref_units(value: float, scale: int) -> int:
    return round(Fraction(value) * scale)


def ref_yaw(yaw: float) -> int:
    """No fmod here: the codec's exact fmod must not change the result."""
    return round(Fraction(yaw) * 65536 / TAU_Q) % 65536


def expect(value: float, scale: int, lo: int, hi: int) -> int | None:
    units = ref_units(value, scale)
    return units if lo <= units <= hi else None


def encoded(fn, value):
    try:
        return fn(value)
    except EncodeError:
        return None


FIELDS = {  # name -> (codec function, scale, lo, hi)
    "x": (position_to_units, 100, -32768, 32767),
    "period": (period_to_units, 10, 0, 255),
    "radius": (radius_to_units, 100, 1, 65535),
}


def ulps_around(value: float, n: int = 3) -> list[float]:
    out, up, down = [value], value, value
    for _ in range(n):
        up, down = math.nextafter(up, math.inf), math.nextafter(down, -math.inf)
        out += [up, down]
    return out


# The inputs the issue names, and the ones where x * 100.0 or x / 0.01 round the other way.
NAMED = [327.665, -17.225, 327.675, -327.68, -327.685, 327.67, 0.35, 0.25, 0.45, 0.05, 0.15, 2.675, 2.55,
         0.005, -0.005, 0.015, 1.005, 25.55, 655.355, 0.004]


@pytest.mark.parametrize("field", sorted(FIELDS))
@pytest.mark.parametrize("value", [v for x in NAMED for v in ulps_around(x)] + [-0.0, 5e-324, -5e-324, 1e300])
def test_named_near_ties_follow_the_exact_rule(field, value):
    fn, scale, lo, hi = FIELDS[field]
    assert encoded(fn, value) == expect(value, scale, lo, hi)


@st.composite
def near_ties(draw, scale: int, lo: int, hi: int):
    """A double within a few ulps of (k + 1/2) / scale: where rounding the float product can go wrong."""
    k = draw(st.integers(lo - 2, hi + 1))
    tie = float(Fraction(2 * k + 1, 2 * scale))
    return draw(st.sampled_from(ulps_around(tie, 4)))


@pytest.mark.parametrize("field", sorted(FIELDS))
@given(data=st.data())
def test_fast_path_equals_the_exact_rule_near_ties_and_anywhere(field, data):
    fn, scale, lo, hi = FIELDS[field]
    value = data.draw(st.one_of(near_ties(scale, lo, hi), st.floats(allow_nan=False, allow_infinity=False)))
    assert encoded(fn, value) == expect(value, scale, lo, hi)


def test_the_fast_path_alone_would_be_wrong_near_ties():
    # the fallback is not decoration: rounding the float product disagrees with the rule here
    assert (round(0.005 * 100.0), position_to_units(0.005)) == (0, 1)
    assert (round(2.675 * 100.0), position_to_units(2.675)) == (268, 267)
    assert (round(0.35 * 10.0), period_to_units(0.35)) == (4, 3)
    # and so does rounding x / 0.01, the reading of POSITION_UNIT_M = 0.01
    assert (round(327.665 / 0.01), position_to_units(327.665)) == (32766, 32767)
    assert (round(-17.225 / 0.01), position_to_units(-17.225)) == (-1722, -1723)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("fn", [position_to_units, period_to_units, radius_to_units, yaw_to_units])
def test_non_finite_values_raise(fn, value):
    with pytest.raises(EncodeError):
        fn(value)


def test_finite_values_whose_product_overflows_are_out_of_range_not_non_finite():
    with pytest.raises(EncodeError, match="out of range"):
        position_to_units(1.7e308)


# --- yaw: round the exact quotient, then wrap the integer modulo 65536 ----------------------------

HALF_UNIT = TAU / 131072  # exact: TAU / 2**17, X = 1/2


@pytest.mark.parametrize(
    "yaw, units",
    [
        (0.0, 0), (-0.0, 0), (-1e-300, 0), (-5e-324, 0), (5e-324, 0),
        (TAU, 0), (math.nextafter(TAU, 0.0), 0), (-TAU, 0), (2 * TAU, 0),
        (HALF_UNIT, 0), (-HALF_UNIT, 0),  # X = +-1/2 exactly: ties to 0, the even one
        (math.nextafter(HALF_UNIT, 1.0), 1), (math.nextafter(-HALF_UNIT, -1.0), 65535),
        (3 * HALF_UNIT, 2), (-3 * HALF_UNIT, 65534),  # X = +-3/2 exactly: ties to +-2
        (5 * HALF_UNIT, 2), (math.pi, 32768), (-math.pi / 2, 49152), (7 * math.pi, 32768),
        # yaw * 65536.0 / TAU is exactly 8.5 (-9.5), the exact X is above (above) it
        (0.0008149272935642469, 9), (-0.0009108010928070994, 65527),
    ],
)
def test_yaw_wraps_as_an_integer_after_exact_rounding(yaw, units):
    assert yaw_to_units(yaw) == units == ref_yaw(yaw)


@st.composite
def yaw_near_ties(draw):
    """A yaw within a few ulps of (k + 1/2) * TAU / 65536 + j * TAU."""
    k = draw(st.integers(-65537, 65536))
    turns = draw(st.sampled_from([0, 0, 1, -1, 7, -300, 10**6]))
    tie = float(Fraction(2 * k + 1, 131072) * TAU_Q + turns * TAU_Q)
    return draw(st.sampled_from(ulps_around(tie, 4)))


@given(st.one_of(yaw_near_ties(), st.floats(allow_nan=False, allow_infinity=False),
                 st.floats(-10.0, 10.0), st.floats(-1e-300, 1e-300)))
@example(-1e-300)
@example(math.nextafter(TAU, 0.0))
@example(1e308)
def test_yaw_fast_path_equals_the_exact_rule(yaw):
    assert yaw_to_units(yaw) == ref_yaw(yaw)


# --- decoding: the correctly rounded double; decode -> encode is the identity --------------------


def test_every_coordinate_and_yaw_decodes_correctly_rounded_and_re_encodes_to_itself():
    assert Fraction(YAW_UNIT_RAD) == TAU_Q / 65536  # exact
    for units in range(-32768, 32768):
        yaw_units = units & 0xFFFF
        pose, _ = pull_pose(struct.pack(">hhhH", units, 0, 0, yaw_units), 0)
        assert pose.x == float(Fraction(units, 100)) and position_to_units(pose.x) == units
        assert pose.yaw == float(yaw_units * TAU_Q / 65536) and 0.0 <= pose.yaw < TAU
        assert yaw_to_units(pose.yaw) == yaw_units


def test_every_period_and_radius_decodes_correctly_rounded_and_re_encodes_to_itself():
    for units in range(256):
        value = pull_period(bytes([units]), 0)[0]
        assert value == float(Fraction(units, 10)) and period_to_units(value) == units
    for units in range(1, 65536):
        value = pull_radius(units.to_bytes(2, "big"), 0)[0]
        assert value == float(Fraction(units, 100)) and radius_to_units(value) == units


# --- the stated round-trip bounds hold exactly ---------------------------------------------------


def half_ulp(value: float) -> Fraction:
    return Fraction(math.ulp(value)) / 2


@given(st.one_of(st.floats(-327.685, 327.675), near_ties(100, -32768, 32767)),
       st.one_of(st.floats(-1e6, 1e6), yaw_near_ties()))
@example(327.665, -HALF_UNIT)
@example(-17.225, math.nextafter(TAU, 0.0))
def test_pose_round_trip_error_is_half_a_unit_plus_half_an_ulp(coordinate, yaw):
    buf = bytearray()
    try:
        push_pose(buf, Pose(coordinate, 0.0, 0.0, yaw))
    except EncodeError:
        assert not -32768 <= ref_units(coordinate, 100) <= 32767
        return
    decoded, _ = pull_pose(bytes(buf), 0)
    units = int.from_bytes(buf[0:2], "big", signed=True)
    assert abs(Fraction(coordinate) * 100 - units) <= Fraction(1, 2)  # encoding: half a unit, exactly
    error = abs(Fraction(decoded.x) - Fraction(coordinate))
    assert error <= Fraction(1, 200) + half_ulp(decoded.x) <= Fraction(1, 200) + Fraction(2**-45)
    # yaw: within half a unit of the input, modulo TAU
    turns = round((Fraction(yaw) - Fraction(decoded.yaw)) / TAU_Q)
    error = abs(Fraction(yaw) - turns * TAU_Q - Fraction(decoded.yaw))
    assert error <= TAU_Q / 131072 + half_ulp(decoded.yaw) <= TAU_Q / 131072 + Fraction(2**-51)


@given(st.one_of(st.floats(0.0, 25.549), near_ties(10, 0, 255)),
       st.one_of(st.floats(0.005, 655.354), near_ties(100, 1, 65535)))
@example(0.35, 655.355)
@example(0.25, 0.005)
@example(0.45, 2.675)
def test_period_and_radius_round_trip_error_is_half_a_unit_plus_half_an_ulp(period, radius):
    for value, push, pull, scale, bound in [
        (period, push_period, pull_period, 10, Fraction(2**-49)),
        (radius, push_radius, pull_radius, 100, Fraction(2**-44)),
    ]:
        buf = bytearray()
        try:
            push(buf, value)
        except EncodeError:
            continue
        decoded = pull(bytes(buf), 0)[0]
        error = abs(Fraction(decoded) - Fraction(value))
        assert error <= Fraction(1, 2 * scale) + half_ulp(decoded) <= Fraction(1, 2 * scale) + bound


# --- the C recipe of section 3, transcribed: fma, rint, fmod, ldexp ------------------------------


def _libm():
    name = ctypes.util.find_library("m")
    if name is None:
        return None
    lib = ctypes.CDLL(name)
    for fn in (lib.fma, lib.rint):
        fn.restype = ctypes.c_double
    lib.fma.argtypes = [ctypes.c_double] * 3
    lib.rint.argtypes = [ctypes.c_double]
    return lib


_LIBM = _libm()


def fma(a: float, b: float, c: float) -> float:
    """C99 fma: a * b + c rounded once (libm's, or the same thing in exact arithmetic)."""
    if _LIBM is not None:
        return _LIBM.fma(a, b, c)
    return float(Fraction(a) * Fraction(b) + Fraction(c))


def rint(x: float) -> float:
    return _LIBM.rint(x) if _LIBM is not None else float(round(x))


def settle(f: float, r: float, err: float) -> float:
    return math.floor(f) + 1 if err > 0 else math.floor(f) if err < 0 else r


def c_units_scaled(v: float, s: float) -> float:
    f = v * s
    r = rint(f)
    if abs(f - r) != 0.5:
        return r
    return settle(f, r, fma(v, s, -f))


def c_yaw_units(yaw: float) -> int:
    w = math.ldexp(math.fmod(yaw, TAU), 16)
    q = w / TAU
    r = rint(q)
    if abs(q - r) == 0.5:
        r = settle(q, r, fma(-q, TAU, w))
    return int(r) & 0xFFFF


@given(st.one_of(near_ties(100, -32768, 32767), near_ties(10, 0, 255), st.floats(-1e6, 1e6),
                 st.floats(-1e-300, 1e-300)))
@example(0.005)
@example(327.665)
@example(-17.225)
def test_the_c_recipe_for_positions_and_periods_matches_the_rule(value):
    assert c_units_scaled(value, 100.0) == ref_units(value, 100)
    assert c_units_scaled(value, 10.0) == ref_units(value, 10)


@given(st.one_of(yaw_near_ties(), st.floats(-1e9, 1e9), st.floats(-1e-300, 1e-300)))
@example(-HALF_UNIT)
@example(math.nextafter(-HALF_UNIT, -1.0))
@example(-3 * HALF_UNIT)
def test_the_c_recipe_for_yaw_matches_the_rule(yaw):
    assert c_yaw_units(yaw) == ref_yaw(yaw)


def test_the_naive_c_expressions_do_not_match_the_rule():
    # rint(x * 100.0) rounds an already rounded product; lround rounds ties away from zero
    assert rint(0.005 * 100.0) == 0.0 and ref_units(0.005, 100) == 1
    assert math.floor(0.25 * 10.0 + 0.5) == 3 and ref_units(0.25, 10) == 2


# --- the conformance table of section 3 ----------------------------------------------------------

TABLE_HEADER = "| Field | Input | Exact X | n | Wire | Note |"


def conformance_rows() -> list[list[str]]:
    text = DOCS.read_text(encoding="utf-8")
    start = text.index(TABLE_HEADER)
    rows = []
    for line in text[start:].splitlines()[2:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip().strip("`") for cell in line.strip("|").split("|")])
    return rows


def exact_x(field: str, value: float) -> Fraction:
    return Fraction(value) * 65536 / TAU_Q if field == "yaw" else Fraction(value) * (10 if field == "period" else 100)


def encode_field(field: str, value: float) -> bytes:
    buf = bytearray()
    if field in ("x", "y", "z"):
        push_pose(buf, Pose(*(value if f == field else 0.0 for f in "xyz"), 0.0))
        return bytes(buf["xyz".index(field) * 2 :][:2])
    if field == "yaw":
        push_pose(buf, Pose(0.0, 0.0, 0.0, value))
        return bytes(buf[6:8])
    (push_period if field == "period" else push_radius)(buf, value)
    return bytes(buf)


def test_conformance_table_is_there_and_covers_the_tricky_inputs():
    rows = conformance_rows()
    inputs = {(field, float(value)) for field, value, *_ in rows}
    for needed in [("x", 327.665), ("x", -17.225), ("x", 327.675), ("x", -327.68), ("period", 0.35),
                   ("period", 0.25), ("yaw", -1e-300), ("yaw", TAU), ("yaw", math.nextafter(TAU, 0.0))]:
        assert needed in inputs


@pytest.mark.parametrize("row", conformance_rows(), ids=lambda row: f"{row[0]}={row[1]}")
def test_conformance_table_matches_the_codec(row):
    field, text, shown, n, wire_bytes = row[:5]
    value = float(text)
    exact = exact_x(field, value)
    # "Exact X": all digits if it ends there, else a truncation ending in an ellipsis
    if shown.endswith("…"):
        digits = shown[:-1]
        mantissa = digits.split("e")[0]
        places = len(mantissa.split(".")[1]) if "." in mantissa else 0
        exponent = int(digits.split("e")[1]) if "e" in digits else 0
        truncated = Fraction(digits)
        assert (truncated < 0) == (exact < 0) and abs(truncated) <= abs(exact)
        assert abs(exact) - abs(truncated) < Fraction(10) ** (exponent - places)
    else:
        assert Fraction(shown) == exact
    assert int(n) == round(exact)
    if wire_bytes == "EncodeError":
        with pytest.raises(EncodeError):
            encode_field(field, value)
    else:
        assert encode_field(field, value) == bytes.fromhex(wire_bytes)


# --- CRC-32: the parameters of section 2, implemented bit by bit from their definition ------------

CRC_PARAMETERS = {"width": 32, "poly": 0x04C11DB7, "init": 0xFFFFFFFF, "refin": True, "refout": True,
                  "xorout": 0xFFFFFFFF, "check": 0xCBF43926}


def reflect(value: int, bits: int) -> int:
    return int(f"{value:0{bits}b}"[::-1], 2)


def crc_from_parameters(data: bytes, width: int, poly: int, init: int, refin: bool, refout: bool,
                        xorout: int, **_) -> int:
    """The Rocksoft/Williams model: MSB-first shift register, reflection as the parameters say."""
    top, mask, reg = 1 << (width - 1), (1 << width) - 1, init
    for byte in data:
        reg ^= (reflect(byte, 8) if refin else byte) << (width - 8)
        for _ in range(8):
            reg = ((reg << 1) ^ poly) & mask if reg & top else (reg << 1) & mask
    return (reflect(reg, width) if refout else reg) ^ xorout


def test_crc_parameters_give_the_check_value_and_the_codec_appends_it_big_endian():
    assert crc_from_parameters(b"123456789", **CRC_PARAMETERS) == CRC_PARAMETERS["check"]
    buf = bytearray(b"123456789")
    push_crc(buf)
    assert buf[9:] == bytes.fromhex("CB F4 39 26")


def test_crc_parameters_are_stated_in_the_docs():
    section = DOCS.read_text(encoding="utf-8").split("## 2. Frame layout")[1].split("## 3.")[0]
    for text in ("width 32", "0x04C11DB7", "init 0xFFFFFFFF", "xorout 0xFFFFFFFF", "reflected", "0xCBF43926",
                 "big-endian"):
        assert text in section, text


def test_every_docs_frame_ends_in_the_crc_of_the_stated_parameters():
    lines = re.findall(r"^((?:[0-9A-F]{2} ?)+)$", DOCS.read_text(encoding="utf-8"), flags=re.MULTILINE)
    frames = [bytes.fromhex(line) for line in lines if len(line.split()) >= 10]
    assert len(frames) >= 15
    for data in frames:
        if data[0] & 0x20:  # AUTH: the integrity field is a MIC, not a CRC
            continue
        decode_frame(data)  # a valid frame of this page (section 5)
        assert data[-4:] == crc_from_parameters(data[:-4], **CRC_PARAMETERS).to_bytes(4, "big")


# --- attempt bits of Confirm, Heartbeat, SegmentAck: sent as 0, any value accepted (section 2) ----

T = MessageType
NEVER_RETRIED = [
    pytest.param(Header(1, FrameFlags.NONE, 3, 0, T.CONFIRM, 2, 1, 3), Confirm(7, T.FOLLOW, ResultCode.ACCEPTED),
                 id="Confirm"),
    pytest.param(Header(1, FrameFlags.NONE, 3, 0, T.HEARTBEAT, 1, 255, 9), Heartbeat(1, 3), id="Heartbeat"),
    pytest.param(Header(1, FrameFlags.NONE, 3, 0, T.SEGMENT_ACK, 2, 1, 10), SegmentAck(0x0102, 3, 5),
                 id="SegmentAck"),
]


def with_attempt(frame: bytes, attempt: int) -> bytes:
    """The same frame with other attempt bits, under its recomputed CRC-32."""
    body = frame[:1] + bytes([attempt << 6 | frame[1] & 0x3F]) + frame[2:-4]
    return body + crc_from_parameters(body, **CRC_PARAMETERS).to_bytes(4, "big")


@pytest.mark.parametrize("attempt", [1, 2, 3])
@pytest.mark.parametrize("header, message", NEVER_RETRIED)
def test_attempt_bits_of_frames_never_retried_are_accepted_and_preserved(header, message, attempt):
    data = with_attempt(encode_frame(header, message), attempt)
    got_header, got_message = decode_frame(data)
    assert (got_header.attempt, got_message) == (attempt, message)
    assert encode_frame(got_header, got_message) == data  # decode -> encode stays the identity


def test_an_endpoint_sends_confirms_and_heartbeats_with_attempt_bits_0_even_answering_a_resend():
    a, b = Endpoint(1), Endpoint(2)
    seq = a.send_command(2, Stop(), 0.0)
    a.frames_to_send(0.0)  # the first send is lost
    a.handle_timer(0.15)
    (resend,) = a.frames_to_send(0.15)
    assert resend[1] >> 6 == 1
    b.receive(resend, 0.15)
    assert b.next_event().seq == seq
    b.confirm(1, seq, T.STOP, ResultCode.DONE, 0.15)
    b.receive(with_attempt(resend, 2), 0.3)  # heard again: the cached Confirm goes out again
    b.send_heartbeat(0.3)
    frames = b.frames_to_send(0.3)
    assert [decode_frame(f)[0].msg_type for f in frames] == [T.CONFIRM, T.CONFIRM, T.HEARTBEAT]
    assert [f[1] >> 6 for f in frames] == [0, 0, 0]


def test_a_confirm_with_attempt_bits_is_an_ordinary_confirm():
    a = Endpoint(1)
    seq = a.send_command(2, Stop(), 0.0)
    a.frames_to_send(0.0)
    confirm = encode_frame(Header(1, FrameFlags.NONE, 3, 0, T.CONFIRM, 2, 1, 0), Confirm(seq, T.STOP, ResultCode.DONE))
    a.receive(with_attempt(confirm, 3), 0.01)
    event = a.next_event()
    assert (event.ref_seq, event.result, event.solicited, event.sends) == (seq, ResultCode.DONE, True, 1)
    assert a.get_timer() is None and a.stats.frames_rejected == 0


# --- ForwardMsg: the inner message's type byte has bits 7-6 zero (section 4) ---------------------


@pytest.mark.parametrize("high", [0x40, 0x80, 0xC0])
@pytest.mark.parametrize("message", [Stop(), Return(), Follow(Pose(1.5, -2.25, 0.1, math.pi / 2))],
                         ids=lambda m: type(m).__name__)
def test_inner_type_byte_with_bits_7_6_set_is_an_unknown_type(message, high):
    inner = encode_inner(message)
    assert inner[0] == message.TYPE <= 63 and decode_inner(inner) == message
    with pytest.raises(UnknownMessageType):
        decode_inner(bytes([inner[0] | high]) + inner[1:])
