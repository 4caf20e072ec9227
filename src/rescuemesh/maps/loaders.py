"""Map file loaders: the rescuemesh wall YAML and the ROS map_server YAML + image, both to a MapModel.

Owns: file reading, validation (every user mistake becomes a one-line MapError naming the file)
and the pixel semantics of map_server images. Must not know physics, navigation or scenarios.

Wall maps (`walls:`) are rasterised at `grid_resolution` for the grid. ROS maps (`image:`) keep
the image's own resolution for the grid (`grid_resolution` is ignored) and become walls by merging
occupied cells into boxes. Pixel semantics follow map_server:

- trinary (default) and scale: p = (255 - v) / 255, or v / 255 when `negate`; v is the mean of the
  colour channels. Occupied when p > occupied_thresh, free when p < free_thresh, else unknown.
- raw: p = v / 100 for v <= 100 (the pixel is the occupancy in percent); v > 100 is unknown.
- A fully transparent pixel (alpha 0) is unknown in every mode.

The navigation grid marks occupied AND unknown cells as obstacles (safe: never plan through the
unknown). The physics walls are built from occupied cells only: unknown space is usually outside
the building, and leaving it out keeps the number of boxes down.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.model import MapError, MapModel, Rect
from rescuemesh.maps.raster import cells_to_rects, rasterise_walls

DEFAULT_WALL_HEIGHT = 0.5  # m
# Defaults of the Nav2 map_server when a map YAML leaves the thresholds out.
DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.25
MAX_GRID_CELLS = 50_000_000  # refuse grids that would not fit comfortably in memory

_WALL_MAP_KEYS = {"name", "wall_height", "walls", "regions", "doorways", "starts", "goals"}


def load_map_file(path: Path, grid_resolution: float) -> MapModel:
    """Load a rescuemesh wall map or a ROS map_server map from the YAML file at `path`.

    `grid_resolution` (m per cell) sets the navigation grid of wall maps. Raises MapError with a
    one-line message naming the file for every problem with the file or its content.
    """
    path = Path(path)
    fail = _Failer(path)
    if not (isinstance(grid_resolution, (int, float)) and math.isfinite(grid_resolution) and grid_resolution > 0):
        fail(f"grid resolution must be a positive number of m, got {grid_resolution!r}")
    doc = _read_yaml(path, fail)
    has_walls, has_image = "walls" in doc, "image" in doc
    if has_walls and has_image:
        fail("has both 'walls' (rescuemesh wall map) and 'image' (ROS map_server map); keep one")
    if has_walls:
        return _load_wall_map(path, doc, float(grid_resolution), fail)
    if has_image:
        return _load_ros_map(path, doc, fail)
    return fail("is neither a rescuemesh wall map (no 'walls:') nor a ROS map_server map (no 'image:')")


class _Failer:
    """Raises MapError('<file>: <problem>') on call."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def __call__(self, problem: str) -> Any:
        raise MapError(f"{self.path}: {problem}")


def _read_yaml(path: Path, fail: _Failer) -> dict[str, Any]:
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        fail("no such map file")
    except IsADirectoryError:
        fail("is a directory, not a map file")
    except OSError as exc:
        fail(f"cannot read the map file ({exc.strerror or exc})")
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(exc, "problem", None) or (str(exc).splitlines() or [type(exc).__name__])[0]
        fail(f"is not valid YAML{where}: {problem}")
    if doc is None:
        fail("is empty; expected a YAML mapping with 'walls:' or 'image:'")
    if not isinstance(doc, dict):
        fail(f"must be a YAML mapping with 'walls:' or 'image:', got a {type(doc).__name__}")
    return doc


# ---------------------------------------------------------------- field validation


def _number(value: Any, what: str, fail: _Failer) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        fail(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _numbers(value: Any, counts: tuple[int, ...], what: str, fail: _Failer) -> list[float]:
    shape = " or ".join(str(n) for n in counts)
    if not isinstance(value, (list, tuple)) or len(value) not in counts:
        fail(f"{what} must be a list of {shape} numbers, got {value!r}")
    return [_number(v, what, fail) for v in value]


def _rect(value: Any, what: str, fail: _Failer) -> Rect:
    x0, y0, x1, y1 = _numbers(value, (4,), f"{what} [x_min, y_min, x_max, y_max]", fail)
    if x1 <= x0 or y1 <= y0:
        fail(f"{what} {value!r} needs x_max > x_min and y_max > y_min")
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
            fail(f"'{key}' has a name that is not a non-empty string: {name!r}")
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
        fail(f"'name' must be a non-empty string, got {name!r}")
    return name


def _wall_height(doc: dict[str, Any], fail: _Failer) -> float:
    height = _number(doc.get("wall_height", DEFAULT_WALL_HEIGHT), "'wall_height'", fail)
    if height <= 0:
        fail(f"'wall_height' must be > 0 m, got {height}")
    return height


def _extras(doc: dict[str, Any], fail: _Failer) -> dict[str, Any]:
    """The optional named areas and poses shared by both map kinds, validated."""
    return {
        "regions": {n: _rect(v, f"regions.{n}", fail) for n, v in _mapping(doc, "regions", fail).items()},
        "doorways": tuple(_rect(v, f"doorways[{i}]", fail) for i, v in enumerate(_sequence(doc, "doorways", fail))),
        "starts": {n: _pose(v, f"starts.{n}", fail) for n, v in _mapping(doc, "starts", fail).items()},
        "goals": {n: _pose(v, f"goals.{n}", fail) for n, v in _mapping(doc, "goals", fail).items()},
    }


def _check_poses_free(grid: OccupancyGrid, extras: dict[str, Any], fail: _Failer) -> None:
    for kind in ("starts", "goals"):
        for name, pose in extras[kind].items():
            if not grid.in_bounds(*grid.world_to_cell(pose.x, pose.y)):
                fail(f"{kind}.{name} ({pose.x:g}, {pose.y:g}) lies outside the map")
            if grid.is_occupied(pose.x, pose.y):
                fail(f"{kind}.{name} ({pose.x:g}, {pose.y:g}) lies in an obstacle")


def _check_size(width: float, height: float, resolution: float, fail: _Failer) -> None:
    cells = (width / resolution) * (height / resolution)
    if cells > MAX_GRID_CELLS:
        fail(
            f"a {width:g} x {height:g} m map at {resolution:g} m per cell needs {cells:.3g} cells"
            f" (limit {MAX_GRID_CELLS:.0e})"
        )


# ---------------------------------------------------------------- rescuemesh wall map


def _load_wall_map(path: Path, doc: dict[str, Any], resolution: float, fail: _Failer) -> MapModel:
    unknown = sorted(str(k) for k in doc if k not in _WALL_MAP_KEYS)
    if unknown:
        fail(f"unknown key(s) {', '.join(unknown)}; expected some of {', '.join(sorted(_WALL_MAP_KEYS))}")
    raw_walls = _sequence(doc, "walls", fail)
    if not raw_walls:
        fail("'walls' is empty; a wall map needs at least one wall")
    walls = tuple(_rect(v, f"walls[{i}]", fail) for i, v in enumerate(raw_walls))
    bounds = Rect(
        min(w.x_min for w in walls),
        min(w.y_min for w in walls),
        max(w.x_max for w in walls),
        max(w.y_max for w in walls),
    )
    _check_size(bounds.x_max - bounds.x_min, bounds.y_max - bounds.y_min, resolution, fail)
    grid = rasterise_walls(walls, bounds, resolution)
    extras = _extras(doc, fail)
    _check_poses_free(grid, extras, fail)
    return MapModel(
        name=_name(doc, path, fail),
        source=path,
        bounds=bounds,
        walls=walls,
        grid=grid,
        wall_height=_wall_height(doc, fail),
        **extras,
    )


# ---------------------------------------------------------------- ROS map_server map


def _load_ros_map(path: Path, doc: dict[str, Any], fail: _Failer) -> MapModel:
    image_name = doc.get("image")
    if not isinstance(image_name, str) or not image_name:
        fail(f"'image' must be the image file name, got {image_name!r}")
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
        fail(f"'negate' must be 0 or 1, got {negate!r}")
    occ_t = _number(doc.get("occupied_thresh", DEFAULT_OCCUPIED_THRESH), "'occupied_thresh'", fail)
    free_t = _number(doc.get("free_thresh", DEFAULT_FREE_THRESH), "'free_thresh'", fail)
    if not 0.0 <= free_t < occ_t <= 1.0:
        fail(f"thresholds need 0 <= free_thresh < occupied_thresh <= 1, got free {free_t:g}, occupied {occ_t:g}")
    mode = doc.get("mode", "trinary")
    if mode not in ("trinary", "scale", "raw"):
        fail(f"'mode' must be trinary, scale or raw, got {mode!r}")

    image_path = Path(image_name) if Path(image_name).is_absolute() else path.parent / image_name
    value, opaque = _read_image(image_path, fail)
    p, known = _occupancy_probability(value, opaque, mode, bool(negate))
    occupied_top_down = known & (p > occ_t)
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
        walls=cells_to_rects(occupied, resolution, ox, oy),
        grid=grid,
        wall_height=_wall_height(doc, fail),
        **extras,
    )


def _read_image(image_path: Path, fail: _Failer) -> tuple[np.ndarray, np.ndarray]:
    """(grey value 0..255 as float, opaque mask), top row first, from a PGM/PNG/... image."""
    from PIL import Image  # Pillow is only needed for ROS maps

    if not image_path.is_file():
        fail(f"image file {image_path} not found")
    try:
        with Image.open(image_path) as img:
            img.load()
            mode = img.mode
            if mode == "P":
                img = img.convert("RGBA")
                mode = "RGBA"
            elif mode == "1":
                img = img.convert("L")
                mode = "L"
            if mode not in ("L", "LA", "RGB", "RGBA"):
                fail(f"image {image_path.name} has unsupported pixel mode {mode} (use 8-bit grey or colour)")
            pixels = np.asarray(img, dtype=np.float64)
    except MapError:
        raise
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as exc:
        fail(f"cannot read image {image_path.name} ({exc})")
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    has_alpha = mode in ("LA", "RGBA")
    colour = pixels[:, :, :-1] if has_alpha else pixels
    opaque = pixels[:, :, -1] > 0 if has_alpha else np.ones(pixels.shape[:2], dtype=bool)
    if pixels.shape[0] == 0 or pixels.shape[1] == 0:
        fail(f"image {image_path.name} is empty")
    return colour.mean(axis=2), opaque


def _occupancy_probability(
    value: np.ndarray, opaque: np.ndarray, mode: str, negate: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(occupancy probability 0..1, known mask) per pixel, as map_server reads them."""
    if mode == "raw":
        return value / 100.0, opaque & (value <= 100.0)
    p = value / 255.0 if negate else (255.0 - value) / 255.0
    return p, opaque
