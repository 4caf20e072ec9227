"""Sensor payloads: JPEG images within a byte budget, the scan layout byte by byte, malformed bytes
refused with SensorDecodeError, and the budgets the mesh really carries in time."""

from __future__ import annotations

import io
import math
import struct
import zlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D
from rescuemesh.mesh import TEAM_RELAY_RETRANSMIT_COUNT, MeshConfig, MeshNode, NetworkStack
from rescuemesh.mesh.keys import team_key_from_seed
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.protocol import DataKind, DataReceived, Endpoint, EndpointConfig
from rescuemesh.radio import DiscChannel
from rescuemesh.robot.sensor_codec import (
    IMAGE_SCALES,
    JPEG_MAX_QUALITY,
    SCAN_HEADER_BYTES,
    BudgetTooSmallError,
    SensorDecodeError,
    choose_jpeg,
    data_budget_bytes,
    decode_image,
    decode_scan,
    encode_image,
    encode_scan,
    image_is_informative,
)
from rescuemesh.transport.sim_medium import SimMedium


def _scene(width: int = 160, height: int = 120) -> np.ndarray:
    """A camera-like picture without a renderer: sky gradient, a wall band, a checker floor, a robot."""
    y, x = np.mgrid[0:height, 0:width]
    rgb = np.zeros((height, width, 3), dtype=np.float64)
    horizon, wall_top = height // 2, height // 3
    sky = y < wall_top
    rgb[sky] = np.stack([170 + 40 * y[sky] / height, 185 + 30 * y[sky] / height, 215 + 0 * y[sky]], axis=1)
    wall = (y >= wall_top) & (y < horizon)
    rgb[wall] = [200, 195, 185]
    rgb[wall & ((x // 23) % 3 == 0)] = [110, 105, 100]  # wall ends in shade
    floor = y >= horizon
    tiles = ((x // 12 + (y - horizon) // 6) % 2).astype(bool)
    rgb[floor & tiles] = [95, 100, 115]
    rgb[floor & ~tiles] = [80, 85, 98]
    robot = (abs(x - width // 2) < width // 8) & (y > height * 0.4) & (y < height * 0.75)
    rgb[robot] = [230, 115, 26]
    return rgb.astype(np.uint8)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(float) - b.astype(float)) ** 2))
    return 10 * math.log10(255.0**2 / mse)


# ---------------------------------------------------------------- images


@pytest.mark.parametrize("max_bytes", [300, 400, 700, 1000, 1600, 3000])
def test_a_jpeg_never_exceeds_its_budget_and_decodes_to_an_image(max_bytes: int) -> None:
    rgb = _scene()
    data = encode_image(rgb, max_bytes=max_bytes)
    assert len(data) <= max_bytes
    assert data[:2] == b"\xff\xd8"  # a JPEG a stock viewer opens
    decoded = decode_image(data)
    assert decoded.dtype == np.uint8 and decoded.ndim == 3 and decoded.shape[2] == 3
    assert image_is_informative(decoded)


def test_a_generous_budget_keeps_the_size_and_a_tight_one_trades_pixels_for_quality() -> None:
    rgb = _scene()
    roomy = choose_jpeg(rgb, max_bytes=3000)
    assert (roomy.width, roomy.height) == (160, 120) and _psnr(decode_image(roomy.data), rgb) > 30
    tight = choose_jpeg(rgb, max_bytes=400)
    assert tight.width < 160 and tight.height < 120  # at 160 x 120 the tables alone nearly fill 400 B
    assert tight.mse > roomy.mse


@pytest.mark.parametrize("max_bytes", [400, 700])
def test_the_choice_is_the_closest_to_the_input_of_every_size_tried(max_bytes: int) -> None:
    rgb = _scene()
    choice = choose_jpeg(rgb, max_bytes=max_bytes)
    errors = {}
    for scale in IMAGE_SCALES:
        size = (max(8, round(160 * scale)), max(8, round(120 * scale)))
        small = np.asarray(Image.fromarray(rgb).resize(size, Image.Resampling.LANCZOS))
        try:
            data = choose_jpeg(small, max_bytes=max_bytes, downscale=False).data
        except BudgetTooSmallError:
            continue
        back = np.asarray(Image.open(io.BytesIO(data)).convert("RGB").resize((160, 120), Image.Resampling.BILINEAR))
        errors[size] = float(np.mean((back.astype(np.float32) - rgb.astype(np.float32)) ** 2))
    assert choice.mse == pytest.approx(min(errors.values()), rel=1e-6)
    assert (choice.width, choice.height) == min(errors, key=errors.get)


def test_the_quality_is_the_highest_that_fits_at_that_size() -> None:
    rgb = _scene()
    choice = choose_jpeg(rgb, max_bytes=1600, downscale=False)
    assert (choice.width, choice.height) == (160, 120) and len(choice.data) <= 1600
    if choice.quality < JPEG_MAX_QUALITY:
        bigger = io.BytesIO()
        Image.fromarray(rgb).save(bigger, format="JPEG", quality=choice.quality + 1, optimize=True)
        assert len(bigger.getvalue()) > 1600


def test_a_budget_below_any_jpeg_is_refused() -> None:
    with pytest.raises(BudgetTooSmallError):
        encode_image(_scene(), max_bytes=100)  # the quantisation tables alone take 138 bytes


@pytest.mark.parametrize("bad", [np.zeros((120, 160), np.uint8), np.zeros((120, 160, 3), np.float32),
                                 np.zeros((0, 160, 3), np.uint8), [[0, 0, 0]]])
def test_only_rgb_uint8_arrays_are_encoded(bad) -> None:
    with pytest.raises(ValueError):
        encode_image(bad, max_bytes=1000)


def _jpeg_bytes() -> bytes:
    return encode_image(_scene(), max_bytes=1600)


@pytest.mark.parametrize("bad", [
    b"", b"\xff\xd8", b"not an image at all", b"GIF89a\x01\x00\x01\x00\x00\x00\x00;",
    "a str", None,
])
def test_malformed_image_bytes_raise_sensor_decode_error(bad) -> None:
    with pytest.raises(SensorDecodeError):
        decode_image(bad)


def test_a_truncated_or_corrupted_jpeg_raises_sensor_decode_error() -> None:
    data = _jpeg_bytes()
    with pytest.raises(SensorDecodeError):
        decode_image(data[: len(data) // 2])
    with pytest.raises(SensorDecodeError):
        decode_image(data[:20] + bytes(len(data) - 20))


@settings(max_examples=200, suppress_health_check=[HealthCheck.too_slow])
@given(st.binary(max_size=600))
def test_arbitrary_bytes_never_raise_anything_but_sensor_decode_error(data: bytes) -> None:
    try:
        decode_image(b"\xff\xd8" + data)
    except SensorDecodeError:
        pass


def test_informative_means_a_scene_not_a_blank_or_flat_frame() -> None:
    assert image_is_informative(_scene())
    assert image_is_informative(decode_image(encode_image(_scene(), max_bytes=400)))
    assert not image_is_informative(np.zeros((120, 160, 3), np.uint8))
    assert not image_is_informative(np.full((120, 160, 3), (180, 90, 20), np.uint8))
    flat_jpeg = decode_image(encode_image(np.full((120, 160, 3), 128, np.uint8), max_bytes=1600))
    assert not image_is_informative(flat_jpeg)  # JPEG noise on a flat frame is not a scene
    faint = np.random.default_rng(0).integers(120, 136, (120, 160, 3)).astype(np.uint8)
    assert not image_is_informative(faint)  # many colours, but a spread of a few levels: sensor noise
    two_tone = np.zeros((120, 160, 3), np.uint8)
    two_tone[60:] = 255
    assert not image_is_informative(two_tone)  # spread out, but two colours only


# ---------------------------------------------------------------- scans


def _scan(ranges, *, stamp=12.345, origin=Pose2D(6.6, 4.6, 0.5), angle_min=-2.0943951, beams=None) -> LaserScan:
    ranges = np.asarray(ranges, dtype=float)
    return LaserScan(stamp=stamp, origin=origin, angle_min=angle_min,
                     angle_increment=math.radians(240.0) / max(1, (beams or len(ranges)) - 1),
                     range_min=0.02, range_max=5.6, ranges=ranges)


def test_the_scan_layout_byte_by_byte() -> None:
    # The worked example of docs/sensors.md: three beams, one without a return.
    scan = LaserScan(stamp=12.345, origin=Pose2D(6.6, 4.6, 0.5), angle_min=-1.0, angle_increment=0.5,
                     range_min=0.02, range_max=5.6, ranges=np.array([1.234, math.inf, 1.236]))
    data = encode_scan(scan, max_bytes=1000)
    assert data.hex(" ") == (
        "01 00 00 00 30 39 02 94 01 cc 13 88 bf 80 00 00 3f 00 00 00 00 14 15 e0 00 03 00 01"
        " 04 d2 fb 2d 04 d5"
    )
    back = decode_scan(data)
    assert back.stamp == 12.345 and back.origin == Pose2D(6.6, 4.6, 0.5)
    assert (back.angle_min, back.angle_increment, back.range_min, back.range_max) == (-1.0, 0.5, 0.02, 5.6)
    assert back.ranges[0] == pytest.approx(1.234) and back.ranges[2] == pytest.approx(1.236)
    assert back.ranges[1] == math.inf


def _office_like_ranges(n: int = 683, seed: int = 0) -> np.ndarray:
    """Piecewise smooth walls with noise and a few gaps: what the office lidar returns."""
    rng = np.random.default_rng(seed)
    a = np.linspace(-2.0944, 2.0944, n)
    r = np.minimum(4.5 / np.maximum(np.abs(np.cos(a)), 0.05), 2.0 / np.maximum(np.abs(np.sin(a)), 0.05))
    r = r + rng.normal(0.0, 0.01, n)
    r[(r > 5.6) | (np.arange(n) % 97 == 5)] = np.inf
    return r


@pytest.mark.parametrize("max_bytes", [60, 120, 250, 400, 800, 1600])
def test_a_scan_fits_its_budget_and_decodes_within_its_step(max_bytes: int) -> None:
    scan = _scan(_office_like_ranges())
    data = encode_scan(scan, max_bytes=max_bytes)
    assert len(data) <= max_bytes
    back = decode_scan(data)
    keep = round(back.angle_increment / scan.angle_increment)
    step = struct.unpack_from(">H", data, 26)[0] / 1000.0
    original = scan.ranges[::keep]
    assert len(back.ranges) == len(original)
    assert np.array_equal(np.isinf(back.ranges), np.isinf(original))
    finite = np.isfinite(original)
    assert np.max(np.abs(back.ranges[finite] - original[finite])) <= step / 2 + 1e-9
    assert back.angles()[-1] == pytest.approx(scan.angles()[::keep][-1], abs=1e-5)


def test_a_roomy_budget_keeps_every_beam_at_1_mm() -> None:
    scan = _scan(_office_like_ranges())
    back = decode_scan(encode_scan(scan, max_bytes=1600))
    assert len(back.ranges) == 683
    finite = np.isfinite(scan.ranges)
    assert np.max(np.abs(back.ranges[finite] - scan.ranges[finite])) <= 0.0005 + 1e-9


def test_a_budget_below_the_header_is_refused() -> None:
    with pytest.raises(BudgetTooSmallError):
        encode_scan(_scan([1.0, 2.0]), max_bytes=SCAN_HEADER_BYTES - 1)


@pytest.mark.parametrize("bad", [
    dict(stamp=-1.0), dict(stamp=math.nan), dict(origin=Pose2D(400.0, 0.0, 0.0)),
    dict(origin=Pose2D(0.0, math.inf, 0.0)), dict(angle_min=1e40),
])
def test_scans_the_header_cannot_carry_are_refused(bad: dict) -> None:
    with pytest.raises(ValueError):
        encode_scan(_scan([1.0, 2.0], **bad), max_bytes=1000)


_finite_or_not = st.one_of(st.floats(0.0, 5.6), st.just(math.inf), st.just(math.nan), st.floats(-1.0, -0.001))


@settings(max_examples=200)
@given(
    ranges=st.lists(_finite_or_not, max_size=800),
    stamp=st.floats(0.0, 4_000_000.0),
    x=st.floats(-300.0, 300.0), y=st.floats(-300.0, 300.0), yaw=st.floats(-10.0, 10.0),
    angle_min=st.floats(-math.pi, math.pi), angle_increment=st.floats(0.0, 0.1),
    range_min=st.floats(0.0, 1.0), range_max=st.floats(1.0, 65.0),
)
def test_scan_round_trip_within_the_stated_quantisation(ranges, stamp, x, y, yaw, angle_min, angle_increment,
                                                        range_min, range_max) -> None:
    scan = LaserScan(stamp, Pose2D(x, y, yaw), angle_min, angle_increment, range_min, range_max,
                     np.array(ranges, float))
    back = decode_scan(encode_scan(scan, max_bytes=10**6))  # roomy: every beam at 1 mm
    assert abs(back.stamp - stamp) <= 0.0005 + 1e-9
    assert abs(back.origin.x - x) <= 0.005 + 1e-9 and abs(back.origin.y - y) <= 0.005 + 1e-9
    assert abs(math.remainder(back.origin.yaw - yaw, 2 * math.pi)) <= 0.5e-4 + 1e-9
    assert back.angle_min == pytest.approx(angle_min, rel=1e-6, abs=1e-12)
    assert back.angle_increment == pytest.approx(angle_increment, rel=1e-6, abs=1e-12)
    assert abs(back.range_min - range_min) <= 0.0005 + 1e-12 and abs(back.range_max - range_max) <= 0.0005 + 1e-12
    original = np.array(ranges, float)
    ok = np.isfinite(original) & (original >= 0)
    assert len(back.ranges) == len(original)
    assert np.all(np.isinf(back.ranges[~ok]))  # inf, NaN and negative ranges come back as no return
    assert np.all(np.abs(back.ranges[ok] - original[ok]) <= 0.0005 + 1e-9)


@settings(max_examples=100)
@given(ranges=st.lists(_finite_or_not, min_size=1, max_size=800), max_bytes=st.integers(SCAN_HEADER_BYTES + 2, 2000))
def test_any_budget_from_the_header_and_one_beam_up_is_met(ranges, max_bytes) -> None:
    data = encode_scan(_scan(ranges, beams=len(ranges)), max_bytes=max_bytes)
    assert len(data) <= max_bytes
    decode_scan(data)


def _valid_scan_bytes() -> bytes:
    return encode_scan(_scan(_office_like_ranges()), max_bytes=1600)


def _with(data: bytes, offset: int, fmt: str, value) -> bytes:
    out = bytearray(data)
    struct.pack_into(fmt, out, offset, value)
    return bytes(out)


@pytest.mark.parametrize(("name", "mangle"), [
    ("empty", lambda d: b""),
    ("header cut short", lambda d: d[:SCAN_HEADER_BYTES - 1]),
    ("ranges cut short", lambda d: d[:-3]),
    ("bytes after the end", lambda d: d + b"\x00"),
    ("bytes after uncompressed ranges", lambda d: _SMALL + b"\x00"),
    ("version 2", lambda d: _with(d, 0, ">B", 2)),
    ("unknown flag", lambda d: _with(d, 1, ">B", d[1] | 0x80)),
    ("NaN angle_min", lambda d: _with(d, 12, ">f", math.nan)),
    ("infinite angle_increment", lambda d: _with(d, 16, ">f", math.inf)),
    ("range_min above range_max", lambda d: _with(d, 20, ">H", 60000)),
    ("step 0", lambda d: _with(d, 26, ">H", 0)),
    ("more beams than bytes", lambda d: _with(d, 24, ">H", 65535)),
    ("corrupt zlib", lambda d: d[:SCAN_HEADER_BYTES] + b"\x78\x9c garbage"),
    ("uncompressed but flagged",
     lambda d: _with(d[:SCAN_HEADER_BYTES] + zlib.decompress(d[SCAN_HEADER_BYTES:]), 1, ">B", 1)),
])
def test_malformed_scans_raise_sensor_decode_error(name, mangle) -> None:
    data = _valid_scan_bytes()
    assert data[1] & 0x01  # this example is compressed
    with pytest.raises(SensorDecodeError):
        decode_scan(mangle(data))


@settings(max_examples=300)
@given(st.binary(max_size=200), st.integers(0, 2000), st.integers(0, 255))
def test_arbitrary_or_mangled_scan_bytes_raise_only_sensor_decode_error(junk: bytes, position: int, value: int) -> None:
    candidates = [junk, _VALID[:SCAN_HEADER_BYTES] + junk]
    mangled = bytearray(_VALID)
    mangled[position % len(mangled)] = value
    candidates.append(bytes(mangled))
    for data in candidates:
        try:
            scan = decode_scan(data)
        except SensorDecodeError:
            continue
        assert isinstance(scan, LaserScan)


_VALID = _valid_scan_bytes()
_SMALL = encode_scan(_scan([1.0, 2.0, math.inf]), max_bytes=100)  # uncompressed: 6 range bytes


def test_sensor_decode_error_is_a_value_error() -> None:
    assert issubclass(SensorDecodeError, ValueError) and issubclass(BudgetTooSmallError, ValueError)


# ---------------------------------------------------------------- budgets on the real mesh


def _chain(hops: int, seed: int):
    """A chain of robots 8 m apart on the 10 m disc: each hears only its neighbours. Authenticated
    frames and relay retransmissions as the simulated team has them (checks/mesh_bench.py)."""
    medium = SimMedium(DiscChannel(), seed)
    sealer = FrameSealer.from_team_key(team_key_from_seed(seed))
    stacks = []
    for address in range(1, hops + 2):
        stack = NetworkStack(Endpoint(address, EndpointConfig(initial_ttl=7)),
                             MeshNode(address, MeshConfig(relay_retransmit_count=TEAM_RELAY_RETRANSMIT_COUNT), sealer))
        medium.attach(address, stack, lambda x=8.0 * (address - 1): (x, 0.0))
        stacks.append(stack)
    t = 0.0
    for _ in range(6):  # heartbeats first: every node learns the others' hops and epochs
        for stack in stacks:
            stack.endpoint.send_heartbeat(t)
            medium.flush(t)
            t = round(t + 0.05, 9)
            medium.pump(t)
    t = 3.0
    medium.pump(t)
    for stack in stacks:
        while stack.endpoint.next_event() is not None:
            pass
    return medium, stacks, t


def _transfer_time(payload: bytes, hops: int, seed: int, limit_s: float) -> float | None:
    medium, stacks, t0 = _chain(hops, seed)
    requester, camera = stacks[0].endpoint, stacks[-1].endpoint
    camera.send_data(requester.address, DataKind.IMAGE_JPEG, 7, payload, t0)
    medium.flush(t0)
    t = t0
    while t < t0 + limit_s:
        t = round(t + 0.005, 9)
        medium.pump(t)
        for stack in stacks:
            while (event := stack.endpoint.next_event()) is not None:
                if stack is stacks[0] and isinstance(event, DataReceived):
                    assert event.data == payload
                    return event.now - t0
        medium.flush(t)
    return None


@pytest.mark.parametrize("hops", [1, 2])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_an_image_at_its_budget_reaches_the_requester_within_3_s_per_hop(hops: int, seed: int) -> None:
    payload = encode_image(_scene(), max_bytes=data_budget_bytes(hops))
    assert len(payload) > 0.8 * data_budget_bytes(hops)  # the budget is used, not wasted
    elapsed = _transfer_time(payload, hops, seed, limit_s=3.0 * hops)
    assert elapsed is not None, f"{len(payload)} bytes did not cross {hops} hop(s) within {3 * hops} s"


@pytest.mark.parametrize(("hops", "expected"), [(1, 1200), (2, 1200), (3, 400), (7, 400)])
def test_budgets_by_hops(hops: int, expected: int) -> None:
    assert data_budget_bytes(hops) == expected


@pytest.mark.parametrize("bad", [0, -1, 1.0, None])
def test_budget_needs_a_hop_count(bad) -> None:
    with pytest.raises(ValueError):
        data_budget_bytes(bad)


def test_draw_scan_png_writes_the_scan_on_the_map(tmp_path) -> None:
    from rescuemesh.maps import load_map, office_map_path
    from rescuemesh.report.sensors import draw_scan_png

    office = load_map(office_map_path())
    scan = decode_scan(encode_scan(_scan(_office_like_ranges()), max_bytes=400))
    path = draw_scan_png(scan, office, tmp_path / "scans" / "robot_1_0001.png", title="robot_1")
    with Image.open(path) as image:
        assert image.format == "PNG" and image.width > 400 and image.height > 200
        pixels = np.asarray(image.convert("RGB")).astype(int)
    red = (pixels[..., 0] > 180) & (pixels[..., 1] < 90) & (pixels[..., 2] < 90)
    assert red.sum() > 100  # the returns are drawn
