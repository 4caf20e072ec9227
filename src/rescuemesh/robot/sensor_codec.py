"""Sensor payloads for the radio: camera images as JPEG and laser scans in a compact binary layout,
each made to fit a byte budget the mesh carries in time (docs/sensors.md).

Owns: the encoders and decoders (pure functions of their inputs; Pillow, numpy, zlib), the scan
layout, the transfer budgets measured on the mesh, and `image_is_informative`. Must not know:
MuJoCo, the protocol or the mesh (the brain puts the bytes in a `Data` message).
"""

from __future__ import annotations

import io
import math
import struct
import zlib
from dataclasses import dataclass

import numpy as np
from PIL import Image

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D, wrap_angle

__all__ = [
    "BudgetTooSmallError", "DATA_BUDGET_BYTES", "JpegChoice", "SCAN_HEADER_BYTES", "SensorDecodeError",
    "choose_jpeg", "data_budget_bytes", "decode_image", "decode_scan", "encode_image", "encode_scan",
    "image_is_informative",
]


class SensorDecodeError(ValueError):
    """Bytes that are not a valid image or scan encoding (truncated, corrupt, unknown version ...)."""


class BudgetTooSmallError(ValueError):
    """Nothing this encoder can make fits `max_bytes`."""


# --------------------------------------------------------------------------- budgets

#: Data payload in bytes that reaches a requester `hops` away within 3 s per hop: real
#: NetworkStacks on the SimMedium, authenticated team, 8 m chain on the 10 m disc: 1,600 B took
#: 2.46-2.84 s over one hop and 3.35-4.54 s over two (12 seeds each), once relays stopped
#: repeating segments; in the office scenarios (three robots flooding, heartbeats, 20 % extra
#: loss) 1,600 B took up to 3.9 s on one hop, so the budget keeps a quarter in hand: 1,200 B.
#: Three hops not measured since.
DATA_BUDGET_BYTES: dict[int, int] = {1: 1200, 2: 1200, 3: 400}
#: What a stream of captures may send per second of its period (measured 529-630 B/s one way).
STREAM_BYTES_PER_S = 500


def data_budget_bytes(hops: int) -> int:
    """Byte budget of one image or scan for a requester `hops` radio hops away (1, 2, 3; more: the
    3-hop figure, not measured beyond)."""
    if not (isinstance(hops, int) and hops >= 1):
        raise ValueError(f"hops must be an int >= 1, got {hops!r}")
    return DATA_BUDGET_BYTES[min(hops, max(DATA_BUDGET_BYTES))]


# --------------------------------------------------------------------------- images

JPEG_MAX_QUALITY = 95  # Pillow: above 95 the file grows with no visible gain
MIN_IMAGE_SIDE = 8  # px: the smallest image side the encoder tries
#: Image sizes tried, as fractions of the input (160 x 120 -> 128 x 96, 96 x 72, 80 x 60 ...).
IMAGE_SCALES = (1.0, 0.8, 0.6, 0.5, 0.4, 0.3, 0.2, 0.1)
MAX_DECODED_PIXELS = 4096 * 4096  # a decoder refuses larger images (no decompression bombs)


@dataclass(frozen=True)
class JpegChoice:
    """The JPEG `choose_jpeg` picked: its bytes, size in pixels, quality (1..95) and the mean squared
    error of the decoded image against the input (after scaling back to the input size)."""

    data: bytes
    width: int
    height: int
    quality: int
    mse: float


def _check_rgb(rgb: np.ndarray) -> np.ndarray:
    if not (isinstance(rgb, np.ndarray) and rgb.dtype == np.uint8 and rgb.ndim == 3 and rgb.shape[2] == 3
            and rgb.shape[0] >= 1 and rgb.shape[1] >= 1):
        raise ValueError(f"an image must be an (H, W, 3) uint8 array, got {getattr(rgb, 'shape', type(rgb))!r}")
    return rgb


def _jpeg(image: Image.Image, quality: int) -> bytes:
    out = io.BytesIO()
    image.save(out, format="JPEG", quality=quality, optimize=True)  # optimised Huffman tables: ~10 % smaller
    return out.getvalue()


def _best_quality(image: Image.Image, max_bytes: int) -> tuple[int, bytes] | None:
    """Highest quality in 1..JPEG_MAX_QUALITY whose JPEG fits `max_bytes` (size grows with quality)."""
    lo, hi, best = 1, JPEG_MAX_QUALITY, None
    while lo <= hi:
        q = (lo + hi) // 2
        data = _jpeg(image, q)
        if len(data) <= max_bytes:
            best, lo = (q, data), q + 1
        else:
            hi = q - 1
    return best


def choose_jpeg(rgb: np.ndarray, *, max_bytes: int, downscale: bool = True) -> JpegChoice:
    """The JPEG of `rgb` that fits `max_bytes` and, decoded and scaled back to the input size, is
    closest to it (least mean squared error) over the sizes IMAGE_SCALES (only the input size when
    `downscale` is False) and, at each size, the highest quality that fits.

    Raises BudgetTooSmallError when not even the smallest size at quality 1 fits.
    """
    rgb = _check_rgb(rgb)
    if not (isinstance(max_bytes, int) and max_bytes > 0):
        raise ValueError(f"max_bytes must be a positive int, got {max_bytes!r}")
    height, width = rgb.shape[:2]
    source = Image.fromarray(rgb, "RGB")
    reference = rgb.astype(np.float32)
    best: JpegChoice | None = None
    tried: set[tuple[int, int]] = set()
    for scale in IMAGE_SCALES if downscale else (1.0,):
        size = (max(min(width, MIN_IMAGE_SIDE), round(width * scale)),
                max(min(height, MIN_IMAGE_SIDE), round(height * scale)))
        if size in tried:
            continue
        tried.add(size)
        image = source if size == (width, height) else source.resize(size, Image.Resampling.LANCZOS)
        found = _best_quality(image, max_bytes)
        if found is None:
            continue
        quality, data = found
        decoded = Image.open(io.BytesIO(data)).convert("RGB")
        if decoded.size != (width, height):
            decoded = decoded.resize((width, height), Image.Resampling.BILINEAR)
        mse = float(np.mean((np.asarray(decoded, dtype=np.float32) - reference) ** 2))
        if best is None or mse < best.mse:
            best = JpegChoice(data, size[0], size[1], quality, mse)
        if quality == JPEG_MAX_QUALITY:
            break  # a smaller size cannot do better than this one at full quality
    if best is None:
        raise BudgetTooSmallError(f"no JPEG of a {width} x {height} image fits {max_bytes} bytes")
    return best


def encode_image(rgb: np.ndarray, *, max_bytes: int) -> bytes:
    """JPEG bytes of `rgb` ((H, W, 3) uint8) of at most `max_bytes`, size and quality as `choose_jpeg`."""
    return choose_jpeg(rgb, max_bytes=max_bytes).data


def decode_image(data: bytes) -> np.ndarray:
    """The (H, W, 3) uint8 RGB array of JPEG (or PNG) bytes. SensorDecodeError for anything else."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise SensorDecodeError(f"image bytes expected, got {type(data).__name__}")
    try:
        with Image.open(io.BytesIO(bytes(data)), formats=("JPEG", "PNG")) as image:
            if image.width * image.height > MAX_DECODED_PIXELS:
                raise SensorDecodeError(f"image of {image.width} x {image.height} pixels is too large")
            return np.asarray(image.convert("RGB"), dtype=np.uint8).copy()
    except SensorDecodeError:
        raise
    except Exception as exc:  # noqa: BLE001 - Pillow raises OSError, SyntaxError, struct.error ... on bad bytes
        raise SensorDecodeError(f"not a decodable JPEG or PNG image: {type(exc).__name__}: {exc}") from exc


def image_is_informative(rgb: np.ndarray, *, min_std: float = 10.0, min_colours: int = 8) -> bool:
    """True when `rgb` shows a scene: pixel values spread (standard deviation over all channels of
    all pixels >= `min_std`, on 0..255) and at least `min_colours` distinct colours at 5 bits per
    channel (so JPEG noise on a flat image does not count). A blank, black or single-colour frame
    is False."""
    rgb = _check_rgb(rgb)
    if float(rgb.std()) < min_std:
        return False
    coarse = (rgb >> 3).astype(np.uint32)
    keys = (coarse[..., 0] << 10) | (coarse[..., 1] << 5) | coarse[..., 2]
    return int(np.unique(keys).size) >= min_colours


# --------------------------------------------------------------------------- scans

SCAN_VERSION = 1
FLAG_ZLIB = 0x01  # the range codes are zlib-compressed
FLAG_NARROW = 0x02  # the range codes are 8-bit (else 16-bit)
_KNOWN_FLAGS = FLAG_ZLIB | FLAG_NARROW
#: version, flags, stamp ms, x cm, y cm, yaw 1e-4 rad, angle_min, angle_increment, range_min mm,
#: range_max mm, count, step mm; big-endian (network order, as the protocol).
_HEADER = struct.Struct(">BBIhhhffHHHH")
SCAN_HEADER_BYTES = _HEADER.size  # 28
MAX_SCAN_BEAMS = 65535
#: Range resolutions tried, in mm, finest first; then every other beam, every third ... (decimation).
SCAN_STEPS_MM = (1, 2, 5, 10, 25, 50)
_NO_RETURN = {8: 0xFF, 16: 0xFFFF}
_YAW_UNIT = 1e-4  # rad
_MAX_ANGLE = 1000.0  # rad: any real angle_min / angle_increment; keeps them well inside float32


def _scan_header_fields(scan: LaserScan) -> tuple:
    o = scan.origin
    values = (scan.stamp, o.x, o.y, o.yaw, scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max)
    if not all(math.isfinite(v) for v in values):
        raise ValueError("a scan to encode needs finite stamp, origin, angles and range limits")
    if not (abs(scan.angle_min) <= _MAX_ANGLE and abs(scan.angle_increment) <= _MAX_ANGLE):
        raise ValueError(f"scan angles must be within +-{_MAX_ANGLE} rad")
    stamp_ms = round(scan.stamp * 1000.0)
    x_cm, y_cm = round(o.x * 100.0), round(o.y * 100.0)
    yaw = round(wrap_angle(o.yaw) / _YAW_UNIT)
    rmin, rmax = round(scan.range_min * 1000.0), round(scan.range_max * 1000.0)
    if not 0 <= stamp_ms <= 0xFFFFFFFF:
        raise ValueError(f"scan stamp {scan.stamp} s is outside 0 .. 4294967 s")
    if not (-32768 <= x_cm <= 32767 and -32768 <= y_cm <= 32767):
        raise ValueError(f"scan origin ({o.x}, {o.y}) m is outside +-327 m")
    if not 0 <= rmin <= rmax <= 0xFFFF:
        raise ValueError(f"scan range limits {scan.range_min} .. {scan.range_max} m must be 0 <= min <= max <= 65.5 m")
    return stamp_ms, x_cm, y_cm, max(-32768, min(32767, yaw)), rmin, rmax


def _pack_scan(fields: tuple, scan: LaserScan, ranges: np.ndarray, angle_increment: float, step_mm: int) -> bytes:
    stamp_ms, x_cm, y_cm, yaw, rmin, rmax = fields
    bits = 8 if math.ceil(rmax / step_mm) < _NO_RETURN[8] else 16
    no_return = _NO_RETURN[bits]
    with np.errstate(invalid="ignore"):
        codes = np.rint(ranges * (1000.0 / step_mm))
    codes = np.where(np.isfinite(codes) & (codes >= 0) & (codes < no_return), codes, no_return).astype(np.int64)
    deltas = np.diff(codes, prepend=0) % (no_return + 1)  # delta coding: neighbouring beams are alike
    body = deltas.astype(">u1" if bits == 8 else ">u2").tobytes()
    flags = FLAG_NARROW if bits == 8 else 0
    packed = zlib.compress(body, 9)
    if len(packed) < len(body):
        body, flags = packed, flags | FLAG_ZLIB
    header = _HEADER.pack(SCAN_VERSION, flags, stamp_ms, x_cm, y_cm, yaw, scan.angle_min, angle_increment,
                          rmin, rmax, len(ranges), step_mm)
    return header + body


def encode_scan(scan: LaserScan, *, max_bytes: int) -> bytes:
    """The scan in at most `max_bytes` bytes (layout in docs/sensors.md): the finest range step of
    SCAN_STEPS_MM that fits, keeping every beam; if none does, every 2nd, 3rd ... beam at the
    coarsest step. Ranges decode to within step / 2; no return (inf, NaN, negative) stays no return.

    ValueError for a scan the header cannot carry; BudgetTooSmallError when not even one beam fits.
    """
    if not (isinstance(max_bytes, int) and max_bytes > 0):
        raise ValueError(f"max_bytes must be a positive int, got {max_bytes!r}")
    ranges = np.asarray(scan.ranges, dtype=np.float64).reshape(-1)
    if ranges.size > MAX_SCAN_BEAMS:
        raise ValueError(f"a scan of {ranges.size} beams exceeds {MAX_SCAN_BEAMS}")
    fields = _scan_header_fields(scan)
    for step in SCAN_STEPS_MM:
        data = _pack_scan(fields, scan, ranges, scan.angle_increment, step)
        if len(data) <= max_bytes:
            return data
    step = SCAN_STEPS_MM[-1]
    for keep_every in range(2, max(2, ranges.size) + 1):
        data = _pack_scan(fields, scan, ranges[::keep_every], scan.angle_increment * keep_every, step)
        if len(data) <= max_bytes:
            return data
    raise BudgetTooSmallError(f"no encoding of this scan fits {max_bytes} bytes (header alone: {SCAN_HEADER_BYTES})")


def decode_scan(data: bytes) -> LaserScan:
    """The LaserScan of `encode_scan` bytes. SensorDecodeError for any other bytes."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise SensorDecodeError(f"scan bytes expected, got {type(data).__name__}")
    data = bytes(data)
    if len(data) < SCAN_HEADER_BYTES:
        raise SensorDecodeError(f"a scan is at least {SCAN_HEADER_BYTES} bytes, got {len(data)}")
    (version, flags, stamp_ms, x_cm, y_cm, yaw, angle_min, angle_increment,
     rmin, rmax, count, step) = _HEADER.unpack_from(data)
    if version != SCAN_VERSION:
        raise SensorDecodeError(f"unknown scan layout version {version}")
    if flags & ~_KNOWN_FLAGS:
        raise SensorDecodeError(f"unknown scan flags 0x{flags:02x}")
    if not (math.isfinite(angle_min) and math.isfinite(angle_increment)):
        raise SensorDecodeError("scan angles are not finite")
    if step == 0 or rmin > rmax:
        raise SensorDecodeError(f"bad range step {step} mm or limits {rmin} .. {rmax} mm")
    bits = 8 if flags & FLAG_NARROW else 16
    size = count * bits // 8
    body = data[SCAN_HEADER_BYTES:]
    if flags & FLAG_ZLIB:
        inflater = zlib.decompressobj()
        try:
            body = inflater.decompress(body, size + 1)
        except zlib.error as exc:
            raise SensorDecodeError(f"corrupt compressed ranges: {exc}") from exc
        if not inflater.eof or inflater.unused_data or inflater.unconsumed_tail:
            raise SensorDecodeError("compressed ranges do not end where the data ends")
    if len(body) != size:
        raise SensorDecodeError(f"{count} beams need {size} range bytes, got {len(body)}")
    no_return = _NO_RETURN[bits]
    deltas = np.frombuffer(body, dtype=">u1" if bits == 8 else ">u2").astype(np.int64)
    codes = np.cumsum(deltas) % (no_return + 1)
    ranges = np.where(codes == no_return, np.inf, codes * (step / 1000.0))
    return LaserScan(
        stamp=stamp_ms / 1000.0,
        origin=Pose2D(x_cm / 100.0, y_cm / 100.0, yaw * _YAW_UNIT),
        angle_min=float(angle_min),
        angle_increment=float(angle_increment),
        range_min=rmin / 1000.0,
        range_max=rmax / 1000.0,
        ranges=ranges,
    )
