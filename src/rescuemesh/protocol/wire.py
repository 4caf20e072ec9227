"""Wire-format constants and field types: one symmetric push/pull pair per field (u8, u16, pose,
period, radius, CRC-32), big-endian. Must not know headers, message layouts, retries or endpoints;
the byte-by-byte layout is in docs/protocol.md.
"""

from __future__ import annotations

import math
import struct
import zlib

from .errors import EncodeError, MalformedPayload
from .messages import Pose

PROTOCOL_VERSION = 1  # byte 0, bits 7-6
BROADCAST = 0xFF  # destination address heard by every robot
MAX_UNICAST_ADDRESS = 0xFE  # robot addresses are 0..254
HEADER_BYTES = 6
INTEGRITY_BYTES = 4  # CRC-32 now; AES-CCM MIC-32 with the AUTH flag (later issue)
FRAME_OVERHEAD_BYTES = HEADER_BYTES + INTEGRITY_BYTES
#: One BLE ATT notification at the default ATT_MTU of 23 (23 - 3 bytes of opcode and handle), and
#: the 20 bytes after the 9-byte header of a 29-byte Bluetooth Mesh network PDU.
MAX_CONTROL_FRAME_BYTES = 20
MAX_TTL = 15  # 4 bits, hops (Bluetooth Mesh uses 7 bits, 0..127)
DEFAULT_TTL = 7  # Zephyr's CONFIG_BT_MESH_DEFAULT_TTL: 7 hops, enough for a 6-hop chain
#: Largest logical frame (header + payload + integrity) in bytes. Longer than a control frame means
#: segmented by the mesh layer (docs/mesh.md): 512 segments of 16 bytes.
MAX_MESSAGE_BYTES = 8192
MAX_ATTEMPT = 3  # 2 bits: 0 = first send, 1 and 2 = resends; saturates at 3
MAX_SEQ = 0xFFFF  # per-sender sequence number, wraps to 0
MAX_EPOCH = 0xFFFFFFFF  # per-sender epoch: boot counter plus seq wraps (docs/protocol.md section 12)
TYPE_MASK = 0x3F  # byte 1, bits 5-0
POSE_BYTES = 8
MAX_FORWARD_MESSAGE_BYTES = 9  # 20 - 10 overhead - 1 target byte: the largest unsegmented inner message
MAX_FORWARD_INNER_BYTES = MAX_MESSAGE_BYTES - 11  # segmented: the whole logical frame is at most 8192
DATA_HEADER_BYTES = 3  # Data: kind u8 + ref_seq u16
MAX_DATA_BYTES = MAX_MESSAGE_BYTES - 10 - DATA_HEADER_BYTES
SEGMENT_ACK_BITMAP_BITS = 48

# Field units. The exact rules (docs/protocol.md, section 3) scale by the integers below, not by
# these floats: 0.01 and 0.1 are not doubles, and rounding x / 0.01 differs from rounding x * 100.
POSITION_UNIT_M = 0.01  # x, y, z: int16 cm, -327.68..327.67 m after rounding
YAW_UNIT_RAD = math.tau / 65536.0  # yaw: uint16, 0.0055 deg; exactly TAU / 2**16 (TAU = math.tau)
PERIOD_UNIT_S = 0.1  # ShowCam/ShowScan period: uint8, 0..25.5 s
RADIUS_UNIT_M = 0.01  # MoveAround radius: uint16 cm, 0.01..655.35 m
POSITION_PER_M = 100  # units per m: the exact scale of x, y, z and the radius
PERIOD_PER_S = 10  # units per s: the exact scale of a period
YAW_UNITS_PER_TURN = 65536  # yaw units per TAU

_U8 = struct.Struct(">B")
_U16 = struct.Struct(">H")
_U32 = struct.Struct(">I")
_U48_BYTES = 6
_POSE = struct.Struct(">hhhH")
#: The double nearest 2*pi, 0x1.921fb54442d18p+2 (C: 2 * M_PI). The yaw rule is defined on it.
TAU = math.tau
_TAU_NUM, _TAU_DEN = TAU.as_integer_ratio()  # TAU exactly: 884279719003555 / 2**47

# Decoding builds a Pose per pose field. A frozen dataclass __init__ stores each field through
# object.__setattr__; storing straight into the slots builds the same immutable object about 3x
# faster (docs/protocol.md, "Speed"). codec.py does the same for Header.
_new = object.__new__
_SET_POSE = tuple(Pose.__dict__[name].__set__ for name in ("x", "y", "z", "yaw"))


def _make_pose(x: float, y: float, z: float, yaw: float) -> Pose:
    """Same as Pose(x, y, z, yaw) (Pose has no __post_init__ to skip), for the decode fast path."""
    pose = _new(Pose)
    set_x, set_y, set_z, set_yaw = _SET_POSE
    set_x(pose, x)
    set_y(pose, y)
    set_z(pose, z)
    set_yaw(pose, yaw)
    return pose


# push_x(buf, value) appends to a bytearray; pull_x(data, offset) returns (value, next offset).
# A pull never reads past the end: the caller has checked the payload length.


def push_u8(buf: bytearray, value: int) -> None:
    """Append an unsigned byte (0..255)."""
    buf += _U8.pack(value)


def pull_u8(data: bytes, offset: int) -> tuple[int, int]:
    return data[offset], offset + 1


def push_u16(buf: bytearray, value: int) -> None:
    """Append a big-endian uint16 (0..65535)."""
    buf += _U16.pack(value)


def pull_u16(data: bytes, offset: int) -> tuple[int, int]:
    return _U16.unpack_from(data, offset)[0], offset + 2


def push_u48(buf: bytearray, value: int) -> None:
    """Append a big-endian 48-bit unsigned integer (0..2**48 - 1)."""
    buf += value.to_bytes(_U48_BYTES, "big")


def pull_u48(data: bytes, offset: int) -> tuple[int, int]:
    return int.from_bytes(data[offset : offset + _U48_BYTES], "big"), offset + _U48_BYTES


# --- quantisation (docs/protocol.md, section 3, "Rounding, exactly") -----------------------------
#
# The rule: units = round_half_even(X), X the *exact* real value of (the double) x times the scale,
# then check the integer's range. For yaw X = yaw * 65536 / TAU, wrapped as an integer afterwards.
# float.as_integer_ratio() is a double's exact value as n / d, so `_round_ratio` on integers is the
# rule itself. It costs about 1 us, so the encoders first round f, the double nearest X:
#
#   f = fl(X) (one IEEE multiplication or division), r = round(f) (Python's round is half to
#   even), d = f - r (exact). Every half-integer h below 2**52 is a double and correct rounding is
#   monotone, so X < h implies f <= h and X > h implies f >= h: unless f *is* a half-integer
#   (d = +-1/2), f and X lie in the same open interval between two half-integers and round to the
#   same r. When f is one, X may lie on either side (0.005 * 100.0 is 0.5, but the double 0.005
#   is 0.005000000000000000104..., so X is above 1/2), and `_round_ratio` decides. From 2**52 up
#   every field except yaw is out of range either way, and yaw's |X| stays below 65536 (fmod).
#
# tests/protocol/test_wire.py checks fast == exact on random and adversarial near-tie inputs.


def _round_ratio(num: int, den: int) -> int:
    """num / den (den > 0) rounded to the nearest integer, ties to even, in integer arithmetic."""
    quotient, remainder = divmod(num, den)  # floor: 0 <= remainder < den
    twice = 2 * remainder
    if twice > den or (twice == den and quotient & 1):
        quotient += 1
    return quotient


def _exact(value: float, scale: int) -> int:
    """round_half_even(exact(value) * scale): the rule itself, on integers."""
    num, den = value.as_integer_ratio()
    return _round_ratio(num * scale, den)


def _exact_yaw(wrapped: float) -> int:
    """round_half_even(exact(wrapped) * 65536 / exact(TAU)): the yaw rule itself, on integers."""
    num, den = wrapped.as_integer_ratio()
    return _round_ratio(num * YAW_UNITS_PER_TURN * _TAU_DEN, den * _TAU_NUM)


def _to_units(value: float, scale: int, lo: int, hi: int, what: str, span: str) -> int:
    """`value` times the integer `scale`, rounded half to even exactly, then checked to be in lo..hi
    ("round, then check"). EncodeError unless finite and in range."""
    try:
        f = value * scale
        units = round(f)
    except (ValueError, OverflowError) as exc:
        if not math.isfinite(value):
            raise EncodeError(f"{what} {value!r} is not finite") from exc
        units = _exact(value, scale)  # finite, but value * scale overflowed: far out of range
    else:
        d = f - units
        if d == 0.5 or d == -0.5:  # f is a half-integer: X may be on either side of it
            units = _exact(value, scale)
    if not lo <= units <= hi:
        raise EncodeError(f"{what} {value!r} is out of range {span}")
    return units


def yaw_to_units(yaw: float) -> int:
    """Yaw in rad -> 0..65535: round_half_even(exact(yaw) * 65536 / exact(TAU)) mod 65536.

    fmod by TAU first is exact (IEEE 754 fmod always is) and shifts the quotient by a multiple of
    65536, so it changes nothing but bounds |X| below 65536. EncodeError if not finite.
    """
    try:
        w = math.fmod(yaw, TAU)  # exact; ValueError for +-inf
        f = w * 65536.0 / TAU  # w * 2**16 is exact: one rounding, in the division
        units = round(f)  # ValueError for NaN
    except (ValueError, OverflowError) as exc:
        raise EncodeError(f"yaw {yaw!r} is not finite") from exc
    d = f - units
    if d == 0.5 or d == -0.5:  # f is a half-integer: X may be on either side of it
        units = _exact_yaw(w)
    return units & 0xFFFF  # mod 65536: -1 -> 65535, 65536 -> 0


_CM_WHAT, _CM_SPAN = "coordinate (m)", "-327.68..327.67 m"


def position_to_units(value_m: float) -> int:
    """A coordinate in m -> int16 cm: round_half_even(exact(value) * 100), then -32768..32767
    (-327.68..327.67 m). EncodeError if not finite or out of range after rounding."""
    return _to_units(value_m, POSITION_PER_M, -32768, 32767, _CM_WHAT, _CM_SPAN)


def push_pose(buf: bytearray, pose: Pose) -> None:
    """Append 8 bytes: x, y, z as int16 cm, yaw as uint16 in TAU/65536 rad, each rounded half to even
    on the exact value (docs/protocol.md, section 3). EncodeError if not finite or x, y, z outside
    -327.68..327.67 m after rounding."""
    try:
        x = _to_units(pose.x, 100, -32768, 32767, _CM_WHAT, _CM_SPAN)  # position_to_units, inlined
        y = _to_units(pose.y, 100, -32768, 32767, _CM_WHAT, _CM_SPAN)
        z = _to_units(pose.z, 100, -32768, 32767, _CM_WHAT, _CM_SPAN)
        yaw = yaw_to_units(pose.yaw)
    except EncodeError as exc:
        raise EncodeError(f"pose {pose!r}: {exc}") from exc
    buf += _POSE.pack(x, y, z, yaw)


def pull_pose(data: bytes, offset: int) -> tuple[Pose, int]:
    """x, y, z = units / 100 and yaw = units * TAU / 65536, each the correctly rounded double of the
    exact quotient or product (IEEE division and multiplication are; TAU / 65536 is exact)."""
    x, y, z, yaw = _POSE.unpack_from(data, offset)
    return _make_pose(x / 100.0, y / 100.0, z / 100.0, yaw * YAW_UNIT_RAD), offset + POSE_BYTES


def period_to_units(period_s: float) -> int:
    """A period in s -> uint8 tenths: round_half_even(exact(period) * 10), then 0..255."""
    return _to_units(period_s, PERIOD_PER_S, 0, 255, "period (s)", "0..25.5 s")


def push_period(buf: bytearray, period_s: float) -> None:
    """Append a repeat period in 0.1 s units (uint8, 0..25.5 s), rounded half to even exactly."""
    buf += _U8.pack(period_to_units(period_s))


def pull_period(data: bytes, offset: int) -> tuple[float, int]:
    return data[offset] / 10.0, offset + 1


def radius_to_units(radius_m: float) -> int:
    """A radius in m -> uint16 cm: round_half_even(exact(radius) * 100), then 1..65535 (0 cm is not
    a radius)."""
    return _to_units(radius_m, POSITION_PER_M, 1, 0xFFFF, "radius (m)", "0.01..655.35 m")


def push_radius(buf: bytearray, radius_m: float) -> None:
    """Append a radius in cm (uint16, 0.01..655.35 m), rounded half to even exactly."""
    buf += _U16.pack(radius_to_units(radius_m))


def pull_radius(data: bytes, offset: int) -> tuple[float, int]:
    value = _U16.unpack_from(data, offset)[0]
    if value == 0:
        raise MalformedPayload("radius 0 m")
    return value / 100.0, offset + 2


def push_crc(buf: bytearray) -> None:
    """Append the CRC-32 of all of `buf`, big-endian: CRC-32/ISO-HDLC (zlib.crc32, as in PNG and
    Ethernet): width 32, poly 0x04C11DB7, reflected in and out, init and xorout 0xFFFFFFFF, check
    value 0xCBF43926 for b"123456789" (docs/protocol.md, section 2)."""
    buf += _U32.pack(zlib.crc32(buf))


def pull_crc(data: bytes, offset: int) -> tuple[int, int]:
    return _U32.unpack_from(data, offset)[0], offset + INTEGRITY_BYTES
