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
TYPE_MASK = 0x3F  # byte 1, bits 5-0
POSE_BYTES = 8
MAX_FORWARD_MESSAGE_BYTES = 9  # 20 - 10 overhead - 1 target byte: the largest unsegmented inner message
MAX_FORWARD_INNER_BYTES = MAX_MESSAGE_BYTES - 11  # segmented: the whole logical frame is at most 8192
DATA_HEADER_BYTES = 3  # Data: kind u8 + ref_seq u16
MAX_DATA_BYTES = MAX_MESSAGE_BYTES - 10 - DATA_HEADER_BYTES
SEGMENT_ACK_BITMAP_BITS = 48

POSITION_UNIT_M = 0.01  # x, y, z: int16 cm, +-327.67 m
YAW_UNIT_RAD = 2.0 * math.pi / 65536.0  # yaw: uint16, 0.0055 deg
PERIOD_UNIT_S = 0.1  # ShowCam/ShowScan period: uint8, 0..25.5 s
RADIUS_UNIT_M = 0.01  # MoveAround radius: uint16 cm, 0.01..655.35 m

_U8 = struct.Struct(">B")
_U16 = struct.Struct(">H")
_U32 = struct.Struct(">I")
_U48_BYTES = 6
_POSE = struct.Struct(">hhhH")
_TAU = 2.0 * math.pi
_YAW_SCALE = 65536.0 / _TAU

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


def push_pose(buf: bytearray, pose: Pose) -> None:
    """Append 8 bytes: x, y, z as int16 cm, yaw as uint16 in 2*pi/65536 rad (wrapped to [0, 2*pi)),
    each rounded to nearest. EncodeError if not finite or x, y, z beyond +-327.67 m."""
    try:
        x = round(pose.x * 100.0)
        y = round(pose.y * 100.0)
        z = round(pose.z * 100.0)
        yaw = round((pose.yaw % _TAU) * _YAW_SCALE) & 0xFFFF
    except (ValueError, OverflowError) as exc:
        raise EncodeError(f"pose {pose!r} is not finite") from exc
    if not (-32768 <= x <= 32767 and -32768 <= y <= 32767 and -32768 <= z <= 32767):
        raise EncodeError(f"pose {pose!r} is out of range (x, y, z within +-327.67 m)")
    buf += _POSE.pack(x, y, z, yaw)


def pull_pose(data: bytes, offset: int) -> tuple[Pose, int]:
    x, y, z, yaw = _POSE.unpack_from(data, offset)
    return _make_pose(x / 100.0, y / 100.0, z / 100.0, yaw * YAW_UNIT_RAD), offset + POSE_BYTES


def _to_units(value: float, per_unit: float, lo: int, hi: int, what: str, span: str) -> int:
    """`value` scaled by `per_unit` and rounded to nearest; EncodeError unless finite and in lo..hi."""
    try:
        units = round(value * per_unit)
    except (ValueError, OverflowError) as exc:
        raise EncodeError(f"{what} {value!r} is not finite") from exc
    if not lo <= units <= hi:
        raise EncodeError(f"{what} {value!r} is out of range {span}")
    return units


def push_period(buf: bytearray, period_s: float) -> None:
    """Append a repeat period in 0.1 s units (uint8, 0..25.5 s), rounded to nearest."""
    buf += _U8.pack(_to_units(period_s, 10.0, 0, 255, "period (s)", "0..25.5 s"))


def pull_period(data: bytes, offset: int) -> tuple[float, int]:
    return data[offset] / 10.0, offset + 1


def push_radius(buf: bytearray, radius_m: float) -> None:
    """Append a radius in cm (uint16, 0.01..655.35 m), rounded to nearest; 0 cm is not a radius."""
    buf += _U16.pack(_to_units(radius_m, 100.0, 1, 0xFFFF, "radius (m)", "0.01..655.35 m"))


def pull_radius(data: bytes, offset: int) -> tuple[float, int]:
    value = _U16.unpack_from(data, offset)[0]
    if value == 0:
        raise MalformedPayload("radius 0 m")
    return value / 100.0, offset + 2


def push_crc(buf: bytearray) -> None:
    """Append the CRC-32 (zlib.crc32: IEEE 802.3 polynomial, as in PNG and Ethernet) of all of `buf`."""
    buf += _U32.pack(zlib.crc32(buf))


def pull_crc(data: bytes, offset: int) -> tuple[int, int]:
    return _U32.unpack_from(data, offset)[0], offset + INTEGRITY_BYTES
