"""Map file loaders: the rescuemesh wall YAML and the ROS map_server YAML + image, both to a MapModel.

Owns: file reading, validation (every user mistake becomes a one-line MapError naming the file)
and the pixel semantics of map_server images. Must not know physics, navigation or scenarios.

Wall maps (`walls:`) are rasterised at `grid_resolution` for the grid; a wall may carry its material
as a fifth item (`[x0, y0, x1, y1, concrete]`, maps.model.WallMaterial), which the grid keeps as a
per-cell code for the radio. ROS maps have no materials (the radio prices their walls by default). ROS maps (`image:`) keep
the image's own resolution for the grid (`grid_resolution` is ignored) and become walls by merging
occupied cells into boxes. Pixel semantics follow map_server:

- trinary (default) and scale: p = (255 - v) / 255, or v / 255 when `negate`; v is the mean of the
  colour channels. Occupied when p > occupied_thresh, free when p < free_thresh, else unknown.
- raw: p = v / 100 for v <= 100 (the pixel is the occupancy in percent); v > 100 is unknown.
- A fully transparent pixel (alpha 0) is unknown in every mode.

The navigation grid marks occupied AND unknown cells as obstacles (safe: never plan through the
unknown). The physics walls are built from occupied cells only: unknown space is usually outside
the building, and leaving it out keeps the number of boxes down.

Limits (docs/design.md, "Map limits"): a grid of at most MAX_MAP_CELLS cells (checked from the
image header before any pixel is decoded, and from the bounds before a wall map is rasterised);
bounds within POSE_RANGE_M (poses go on the air as int16 cm); at most MAX_OCCUPIED_FRACTION of a
ROS map occupied; at most MAX_WALL_BOXES wall boxes (listed, or merged from a ROS map's occupied
cells); no YAML aliases, no nesting deeper than Python's recursion allows; every value quoted in a
MapError cut to about 80 characters.
"""

from __future__ import annotations

import math
import re
import reprlib
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.model import MapError, MapModel, Rect, WallMaterial
from rescuemesh.maps.raster import TooManyBoxes, cells_to_rects, rasterise_walls

DEFAULT_WALL_HEIGHT = 0.5  # m
# Defaults of the Nav2 map_server when a map YAML leaves the thresholds out.
DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.25
# The largest grid: 4000 x 4000 cells (200 x 200 m at 0.05 m). A run needs about 100 B per cell
# (a 100 M-cell map took 9.7 GB and ran at 0.4x real time), so this stays near 1.6 GB.
MAX_MAP_SIDE = 4000
MAX_MAP_CELLS = MAX_MAP_SIDE * MAX_MAP_SIDE
# Robots' poses are sent as int16 centimetres: -32768..32767 cm (docs/protocol.md section 3,
# `rescuemesh.protocol.wire.position_to_units`). Repeated here because maps/ is a leaf and must
# not import protocol/; tests/maps/test_map_limits.py checks both agree.
POSE_RANGE_M = (-327.68, 327.67)
# A ROS map with more of its cells occupied leaves no room to drive: almost surely inverted.
MAX_OCCUPIED_FRACTION = 0.9
MAX_SHOWN_CHARS = 80  # a value quoted in a MapError is cut to about this many characters
# Wall boxes a map may become: each is a MuJoCo box and a rectangle every lidar ray is tested against.
# A checkerboard ROS map of 1000 x 1000 cells became 500,000 (5.8 s, 169 MB before the run began);
# a SLAM map with speckle gives about 1,000 (tests/maps/test_slam_like.py), the office 18.
MAX_WALL_BOXES = 20_000

_WALL_MAP_KEYS = {"name", "wall_height", "walls", "regions", "doorways", "starts", "goals", "bases"}


def load_map(path: str | Path, grid_resolution: float = 0.05) -> MapModel:
    """Load a map file: a rescuemesh wall map (YAML with `walls:`) or a ROS map_server map (YAML with `image:`).

    `grid_resolution` (m per cell) sets the navigation grid of wall maps. Raises MapError with a
    one-line message naming the file for every problem with the file or its content.
    """
    path = Path(path)
    fail = _Failer(path)
    if not (isinstance(grid_resolution, (int, float)) and math.isfinite(grid_resolution) and grid_resolution > 0):
        fail(f"grid resolution must be a positive number of m, got {_show(grid_resolution)}")
    doc = _read_yaml(path, fail)
    has_walls, has_image = "walls" in doc, "image" in doc
    if has_walls and has_image:
        fail("has both 'walls' (rescuemesh wall map) and 'image' (ROS map_server map); keep one")
    if has_walls:
        return _load_wall_map(path, doc, float(grid_resolution), fail)
    if has_image:
        return _load_ros_map(path, doc, fail)
    return fail("is neither a rescuemesh wall map (no 'walls:') nor a ROS map_server map (no 'image:')")


_SHOW = reprlib.Repr()
_SHOW.maxstring = _SHOW.maxother = MAX_SHOWN_CHARS
_SHOW.maxlist = _SHOW.maxtuple = _SHOW.maxdict = _SHOW.maxset = 6
_SHOW.maxlevel = 3


def _show(value: Any) -> str:
    """repr(value) for a MapError: one line, at most MAX_SHOWN_CHARS characters."""
    return _cut(_SHOW.repr(value))


def _cut(text: object) -> str:
    """str(text) on one line, cut to MAX_SHOWN_CHARS characters."""
    text = " ".join(str(text).split())
    return text if len(text) <= MAX_SHOWN_CHARS else text[: MAX_SHOWN_CHARS - 3] + "..."


def _cells(n: float) -> str:
    """A cell count for a message: '16 M' from 1e6 on, else the number."""
    return f"{n / 1e6:.3g} M" if n >= 1e6 else f"{n:.0f}"


def _limit() -> str:
    square = f"{MAX_MAP_SIDE} x {MAX_MAP_SIDE} = " if MAX_MAP_SIDE * MAX_MAP_SIDE == MAX_MAP_CELLS else ""
    return f"the limit is {square}{_cells(MAX_MAP_CELLS)} cells"


class _Failer:
    """Raises MapError('<file>: <problem>') on call; the problem is kept to one line of bounded length."""

    MAX_PROBLEM_CHARS = 400  # a safety net: every value in a problem is already cut by _show

    def __init__(self, path: Path) -> None:
        self.path = path

    def __call__(self, problem: str) -> Any:
        problem = " ".join(problem.split())
        if len(problem) > self.MAX_PROBLEM_CHARS:
            problem = problem[: self.MAX_PROBLEM_CHARS - 3] + "..."
        raise MapError(f"{self.path}: {problem}")


class _AliasFound(Exception):
    def __init__(self, line: int) -> None:
        super().__init__(line)
        self.line = line


class _NoAliasLoader(yaml.SafeLoader):
    """The safe loader, refusing YAML aliases (`*name`) before they are resolved: a few hundred bytes
    of nested aliases expand to gigabytes ("billion laughs"), and a map file never needs them."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            raise _AliasFound(self.peek_event().start_mark.line + 1)
        return super().compose_node(parent, index)


def _read_yaml(path: Path, fail: _Failer) -> dict[str, Any]:
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        fail("no such map file")
    except IsADirectoryError:
        fail("is a directory, not a map file")
    except OSError as exc:
        fail(f"cannot read the map file ({_cut(exc.strerror or exc)})")
    try:
        doc = yaml.load(text, Loader=_NoAliasLoader)  # a SafeLoader that refuses aliases
    except RecursionError:  # this used to escape as a traceback: [[[[... nested thousands deep
        fail("nests its values too deeply to be a map file (YAML lists or mappings thousands of levels deep)")
    except _AliasFound as exc:
        fail(f"YAML aliases are not allowed in a map file (line {exc.line}); write the values out")
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or (str(exc).splitlines() or [type(exc).__name__])[0]
        problem = _cut(problem)
        fail(f"is not valid YAML{where}: {problem}")
    if doc is None:
        fail("is empty; expected a YAML mapping with 'walls:' or 'image:'")
    if not isinstance(doc, dict):
        fail(f"must be a YAML mapping with 'walls:' or 'image:', got a {type(doc).__name__}")
    return doc


# ---------------------------------------------------------------- field validation


def _number(value: Any, what: str, fail: _Failer) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        fail(f"{what} must be a finite number, got {_show(value)}")
    return float(value)


def _numbers(value: Any, counts: tuple[int, ...], what: str, fail: _Failer) -> list[float]:
    shape = " or ".join(str(n) for n in counts)
    if not isinstance(value, (list, tuple)) or len(value) not in counts:
        fail(f"{what} must be a list of {shape} numbers, got {_show(value)}")
    return [_number(v, what, fail) for v in value]


def _rect(value: Any, what: str, fail: _Failer) -> Rect:
    x0, y0, x1, y1 = _numbers(value, (4,), f"{what} [x_min, y_min, x_max, y_max]", fail)
    if x1 <= x0 or y1 <= y0:
        fail(f"{what} {_show(value)} needs x_max > x_min and y_max > y_min")
    return Rect(x0, y0, x1, y1)


def _pose(value: Any, what: str, fail: _Failer) -> Pose2D:
    nums = _numbers(value, (2, 3), f"{what} [x, y, yaw_rad]", fail)
    return Pose2D(nums[0], nums[1], nums[2] if len(nums) == 3 else 0.0)


def _mapping(doc: dict[str, Any], key: str, fail: _Failer) -> dict[str, Any]:
    value = doc.get(key)
    if value is None:
        return {}
    if not isinstance(value, dict):
        fail(f"'{key}' must be a mapping of name: value, got {type(value).__name__}")
    for name in value:
        if not isinstance(name, str) or not name:
            fail(f"'{key}' has a name that is not a non-empty string: {_show(name)}")
    return value


def _sequence(doc: dict[str, Any], key: str, fail: _Failer) -> list[Any]:
    value = doc.get(key)
    if value is None:
        return []
    if not isinstance(value, list):
        fail(f"'{key}' must be a list, got {type(value).__name__}")
    return value


def _name(doc: dict[str, Any], path: Path, fail: _Failer) -> str:
    name = doc.get("name", path.stem)
    if not isinstance(name, str) or not name:
        fail(f"'name' must be a non-empty string, got {_show(name)}")
    return name


def _wall_height(doc: dict[str, Any], fail: _Failer) -> float:
    height = _number(doc.get("wall_height", DEFAULT_WALL_HEIGHT), "'wall_height'", fail)
    if height <= 0:
        fail(f"'wall_height' must be > 0 m, got {height}")
    return height


def _extras(doc: dict[str, Any], fail: _Failer) -> dict[str, Any]:
    """The optional named areas and poses shared by both map kinds, validated."""
    return {
        "regions": {n: _rect(v, f"regions.{_cut(n)}", fail) for n, v in _mapping(doc, "regions", fail).items()},
        "doorways": tuple(_rect(v, f"doorways[{i}]", fail) for i, v in enumerate(_sequence(doc, "doorways", fail))),
        "starts": {n: _pose(v, f"starts.{_cut(n)}", fail) for n, v in _mapping(doc, "starts", fail).items()},
        "goals": {n: _pose(v, f"goals.{_cut(n)}", fail) for n, v in _mapping(doc, "goals", fail).items()},
        "bases": {n: _pose(v, f"bases.{_cut(n)}", fail) for n, v in _mapping(doc, "bases", fail).items()},
    }


def _check_poses_free(grid: OccupancyGrid, extras: dict[str, Any], fail: _Failer) -> None:
    for kind in ("starts", "goals", "bases"):
        for name, pose in extras[kind].items():
            if not grid.in_bounds(*grid.world_to_cell(pose.x, pose.y)):
                fail(f"{kind}.{_cut(name)} ({pose.x:g}, {pose.y:g}) lies outside the map")
            if grid.is_occupied(pose.x, pose.y):
                fail(f"{kind}.{_cut(name)} ({pose.x:g}, {pose.y:g}) lies in an obstacle")


def _check_size(width: float, height: float, resolution: float, fail: _Failer) -> None:
    cells = (width / resolution) * (height / resolution)
    if cells > MAX_MAP_CELLS:
        fail(
            f"a {width:g} x {height:g} m map at {resolution:g} m per cell needs {_cells(cells)} cells;"
            f" {_limit()}"
        )


def _check_span(bounds: Rect, fail: _Failer) -> None:
    """Refuse a map that reaches beyond the coordinates a pose can carry on the air (POSE_RANGE_M)."""
    lo, hi = POSE_RANGE_M
    spans = [
        f"{axis} {a_min:.1f}..{a_max:.1f} m"
        for axis, a_min, a_max in (("x", bounds.x_min, bounds.x_max), ("y", bounds.y_min, bounds.y_max))
        if round(a_min, 6) < lo or round(a_max, 6) > hi  # round: 327.57 + 10 * 0.01 is 327.67000000000002
    ]
    if spans:
        fail(
            f"map spans {', '.join(spans)}; robots' poses are sent in int16 centimetres"
            f" ({lo:.2f}..{hi:.2f} m): move the origin closer"
        )


# ---------------------------------------------------------------- rescuemesh wall map


def _load_wall_map(path: Path, doc: dict[str, Any], resolution: float, fail: _Failer) -> MapModel:
    unknown = sorted(str(k) for k in doc if k not in _WALL_MAP_KEYS)
    if unknown:
        fail(f"unknown key(s) {_cut(', '.join(unknown))}; expected some of {', '.join(sorted(_WALL_MAP_KEYS))}")
    raw_walls = _sequence(doc, "walls", fail)
    if not raw_walls:
        fail("'walls' is empty; a wall map needs at least one wall")
    if len(raw_walls) > MAX_WALL_BOXES:
        fail(f"lists {len(raw_walls):,} walls; the limit is {MAX_WALL_BOXES:,} wall boxes")
    tagged = [_tagged_rect(v, f"walls[{i}]", fail) for i, v in enumerate(raw_walls)]
    walls = tuple(rect for rect, _ in tagged)
    materials = tuple(material for _, material in tagged)
    bounds = Rect(
        min(w.x_min for w in walls),
        min(w.y_min for w in walls),
        max(w.x_max for w in walls),
        max(w.y_max for w in walls),
    )
    _check_span(bounds, fail)
    _check_size(bounds.x_max - bounds.x_min, bounds.y_max - bounds.y_min, resolution, fail)
    grid = rasterise_walls(walls, bounds, resolution, materials)
    extras = _extras(doc, fail)
    _check_poses_free(grid, extras, fail)
    return MapModel(
        name=_name(doc, path, fail),
        source=path,
        bounds=bounds,
        walls=walls,
        grid=grid,
        wall_height=_wall_height(doc, fail),
        wall_materials=materials,
        **extras,
    )


def _tagged_rect(value: Any, what: str, fail: _Failer) -> tuple[Rect, WallMaterial | None]:
    """A wall: [x_min, y_min, x_max, y_max] or the same with a material name as a fifth item."""
    if isinstance(value, (list, tuple)) and len(value) == 5:
        tag = value[4]
        known = ", ".join(m.value for m in WallMaterial)
        if not isinstance(tag, str) or tag not in {m.value for m in WallMaterial}:
            fail(f"{what} has an unknown wall material {_show(tag)}; known: {known}")
        return _rect(list(value[:4]), what, fail), WallMaterial(tag)
    return _rect(value, what, fail), None


# ---------------------------------------------------------------- ROS map_server map


def _load_ros_map(path: Path, doc: dict[str, Any], fail: _Failer) -> MapModel:
    image_name = doc.get("image")
    if not isinstance(image_name, str) or not image_name:
        fail(f"'image' must be the image file name, got {_show(image_name)}")
    resolution = _number(doc.get("resolution"), "'resolution' (m per pixel)", fail)
    if resolution <= 0:
        fail(f"'resolution' must be > 0 m per pixel, got {resolution}")
    if "origin" not in doc:
        fail("'origin' [x, y, yaw] is missing")
    ox, oy, oyaw = _numbers(doc["origin"], (3,), "'origin' [x, y, yaw]", fail)
    if abs(oyaw) > 1e-9:
        fail(f"origin yaw {oyaw:g} rad is not supported (only axis-aligned maps); rotate the image and set yaw 0")
    negate = doc.get("negate", 0)
    if negate not in (0, 1):  # also accepts False/True
        fail(f"'negate' must be 0 or 1, got {_show(negate)}")
    occ_t = _number(doc.get("occupied_thresh", DEFAULT_OCCUPIED_THRESH), "'occupied_thresh'", fail)
    free_t = _number(doc.get("free_thresh", DEFAULT_FREE_THRESH), "'free_thresh'", fail)
    if not 0.0 <= free_t < occ_t <= 1.0:
        fail(f"thresholds need 0 <= free_thresh < occupied_thresh <= 1, got free {free_t:g}, occupied {occ_t:g}")
    mode = doc.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        fail(f"'mode' must be trinary, scale or raw, got {_show(mode)}")

    image_path = Path(image_name) if Path(image_name).is_absolute() else path.parent / image_name

    def check_header(cols: int, rows: int) -> None:
        _check_span(Rect(ox, oy, ox + cols * resolution, oy + rows * resolution), fail)

    value, opaque = _read_image(image_path, fail, check_header)
    p, known = _occupancy_probability(value, opaque, mode, bool(negate))
    occupied_top_down = known & (p > occ_t)
    _check_occupied_fraction(float(occupied_top_down.mean()), mode, bool(negate), fail)
    free_top_down = known & (p < free_t)
    # Image row 0 is the top (highest y); grid row 0 is the lowest y.
    occupied = np.ascontiguousarray(occupied_top_down[::-1])
    obstacle = np.ascontiguousarray(~free_top_down[::-1])
    rows, cols = obstacle.shape
    grid = OccupancyGrid(occupied=obstacle, resolution=resolution, origin_x=ox, origin_y=oy)
    extras = _extras(doc, fail)
    _check_poses_free(grid, extras, fail)
    return MapModel(
        name=_name(doc, path, fail),
        source=path,
        bounds=Rect(ox, oy, ox + cols * resolution, oy + rows * resolution),
        walls=_boxes(occupied, resolution, ox, oy, fail),
        grid=grid,
        wall_height=_wall_height(doc, fail),
        **extras,
    )


def _boxes(occupied: np.ndarray, resolution: float, ox: float, oy: float, fail: _Failer) -> tuple[Rect, ...]:
    """The occupied cells merged into wall boxes; a map that needs more than MAX_WALL_BOXES is refused."""
    try:
        return cells_to_rects(occupied, resolution, ox, oy, limit=MAX_WALL_BOXES)
    except TooManyBoxes as exc:
        fail(f"its occupied cells make at least {exc.count:,} wall boxes; the limit is {exc.limit:,} "
             "(a noisy or checkered image: clean it, or threshold it harder)")


def _check_occupied_fraction(fraction: float, mode: str, negate: bool, fail: _Failer) -> None:
    """Refuse a map with no room to drive: with more than MAX_OCCUPIED_FRACTION occupied, the image
    is almost surely read inverted (or as percentages when it is not)."""
    if fraction <= MAX_OCCUPIED_FRACTION:
        return
    pct = f"{math.floor(fraction * 100)} % of the map is occupied"
    if mode == "raw":
        fail(f"{pct}: is `mode: raw` right? (raw reads each pixel as the occupancy in percent, 0..100)")
    fail(f"{pct}: is `negate` right? (negate: {int(negate)} means {'white' if negate else 'black'} is occupied)")


def _open_image(image_path: Path, fail: _Failer) -> Any:
    """Image.open (lazy: reads the header only), with the size checked against MAX_MAP_CELLS before
    anything else and Pillow's decompression-bomb warning turned into that check's MapError."""
    from PIL import Image  # Pillow is only needed for ROS maps

    try:
        with warnings.catch_warnings():
            # Pillow warns above 89 M pixels; MAX_MAP_CELLS is lower, so the check below reports it.
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            img = Image.open(image_path)
    except Image.DecompressionBombError as exc:  # over 179 M pixels: Pillow refuses before we see the size
        found = re.search(r"\((\d+) pixels\)", str(exc))
        size = f"{_cells(int(found.group(1)))} cells" if found else "too large"
        return fail(f"map image is {size}; {_limit()}: crop or downsample {_cut(image_path.name)}")
    cols, rows = img.size
    if cols * rows > MAX_MAP_CELLS:
        img.close()
        fail(
            f"map image is {cols} x {rows} = {_cells(cols * rows)} cells; {_limit()}:"
            f" crop or downsample {_cut(image_path.name)}"
        )
    return img


def _read_image(
    image_path: Path, fail: _Failer, check_header: Any = None
) -> tuple[np.ndarray, np.ndarray]:
    """(grey value 0..255 as float, opaque mask), top row first, from a PGM/PNG/... image.

    The size is checked (MAX_MAP_CELLS, then `check_header(cols, rows)`) before pixels are decoded.
    """
    from PIL import Image  # Pillow is only needed for ROS maps

    if not image_path.is_file():
        fail(f"image file {_cut(image_path)} not found")
    try:
        with _open_image(image_path, fail) as img:
            if check_header is not None:
                check_header(*img.size)
            img.load()
            mode = img.mode
            if mode == "P":
                img = img.convert("RGBA")
                mode = "RGBA"
            elif mode == "1":
                img = img.convert("L")
                mode = "L"
            if mode not in ("L", "LA", "RGB", "RGBA"):
                fail(f"image {_cut(image_path.name)} has unsupported pixel mode {mode} (use 8-bit grey or colour)")
            pixels = np.asarray(img, dtype=np.uint8)  # 1 B per channel: 16 M cells stay small
    except MapError:
        raise
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as exc:
        fail(f"cannot read image {_cut(image_path.name)} ({_cut(exc)})")
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    has_alpha = mode in ("LA", "RGBA")
    colour = pixels[:, :, :-1] if has_alpha else pixels
    opaque = pixels[:, :, -1] > 0 if has_alpha else np.ones(pixels.shape[:2], dtype=bool)
    if pixels.shape[0] == 0 or pixels.shape[1] == 0:
        fail(f"image {image_path.name} is empty")
    # The channel mean as float64, from an exact integer sum (as colour.mean, without a float copy).
    return colour.sum(axis=2, dtype=np.uint16) / colour.shape[2], opaque


def _occupancy_probability(
    value: np.ndarray, opaque: np.ndarray, mode: str, negate: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(occupancy probability 0..1, known mask) per pixel, as map_server reads them."""
    if mode == "raw":
        return value / 100.0, opaque & (value <= 100.0)
    p = value / 255.0 if negate else (255.0 - value) / 255.0
    return p, opaque
