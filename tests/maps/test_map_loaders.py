"""Map loaders: ROS map_server maps written by the test, small wall maps, and bad inputs -> MapError."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from rescuemesh.maps import MapError, Rect, load_map
from rescuemesh.maps.raster import cells_to_rects, merge_cells

WHITE, BLACK = 255, 0


def _write_ros_map(tmp_path: Path, pixels: np.ndarray, *, suffix: str = ".pgm", **fields: object) -> Path:
    """Write `pixels` (row 0 = top of the image) and its map_server YAML; returns the YAML path."""
    image = tmp_path / f"map{suffix}"
    Image.fromarray(pixels.astype(np.uint8)).save(image)
    doc = {"image": image.name, "resolution": 0.1, "origin": [-1.0, -2.0, 0.0], "negate": 0,
           "occupied_thresh": 0.65, "free_thresh": 0.196}
    doc.update(fields)
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def _blank(rows: int = 10, cols: int = 20) -> np.ndarray:
    return np.full((rows, cols), WHITE, dtype=np.uint8)


def test_ros_map_orientation_origin_and_bounds(tmp_path: Path) -> None:
    pixels = _blank()
    pixels[1, 2] = BLACK  # near the top-left corner of the image
    m = load_map(_write_ros_map(tmp_path, pixels), grid_resolution=0.5)
    assert m.bounds == Rect(-1.0, -2.0, 1.0, -1.0)
    assert m.grid.resolution == pytest.approx(0.1)  # ROS maps keep their own resolution
    assert m.grid.shape == (10, 20)
    # image row 1 from the top = grid row 8 from the bottom: high y, low x
    x, y = -1.0 + 2.5 * 0.1, -2.0 + 8.5 * 0.1
    assert m.grid.is_occupied(x, y)
    assert int(m.grid.occupied.sum()) == 1
    assert len(m.walls) == 1
    wall = m.walls[0]
    assert (wall.x_min, wall.y_min, wall.x_max, wall.y_max) == pytest.approx((-0.8, -1.2, -0.7, -1.1))
    assert m.regions == {} and m.starts == {} and m.goals == {} and m.doorways == ()
    assert m.name == "map"


def test_ros_map_walls_are_merged_into_few_boxes(tmp_path: Path) -> None:
    pixels = _blank(40, 60)
    pixels[0, :] = pixels[-1, :] = BLACK  # frame
    pixels[:, 0] = pixels[:, -1] = BLACK
    pixels[10:20, 30:45] = BLACK  # a block
    m = load_map(_write_ros_map(tmp_path, pixels))
    assert len(m.walls) <= 6
    area = sum((w.x_max - w.x_min) * (w.y_max - w.y_min) for w in m.walls)
    assert area == pytest.approx(int((pixels == BLACK).sum()) * 0.01)


@pytest.mark.parametrize(
    ("value", "fields", "expect"),
    [
        (100, {}, "unknown"),  # p = 0.61: between the thresholds
        (100, {"occupied_thresh": 0.5}, "occupied"),
        (220, {}, "free"),  # p = 0.14
        (220, {"free_thresh": 0.1}, "unknown"),
        (BLACK, {"negate": 1}, "free"),  # negate: p = v / 255
        (WHITE, {"negate": 1}, "occupied"),
        (100, {"mode": "raw"}, "occupied"),  # raw: the pixel is the occupancy in percent
        (0, {"mode": "raw"}, "free"),
        (255, {"mode": "raw"}, "unknown"),
        (100, {"mode": "scale"}, "unknown"),
    ],
)
def test_ros_map_thresholds_negate_and_modes(tmp_path: Path, value: int, fields: dict, expect: str) -> None:
    pixels = _blank(4, 4) if not fields.get("negate") else np.full((4, 4), BLACK, dtype=np.uint8)
    if fields.get("mode") == "raw":
        pixels[:] = 0
    pixels[2, 2] = value
    m = load_map(_write_ros_map(tmp_path, pixels, **fields))
    obstacle = bool(m.grid.occupied[1, 2])  # image row 2 of 4 = grid row 1
    wall = len(m.walls) == 1
    assert (obstacle, wall) == {"free": (False, False), "unknown": (True, False), "occupied": (True, True)}[expect]
    assert int(m.grid.occupied.sum()) == (0 if expect == "free" else 1)


def test_png_with_transparent_pixels_reads_them_as_unknown(tmp_path: Path) -> None:
    rgba = np.zeros((3, 3, 4), dtype=np.uint8)
    rgba[..., :3] = WHITE
    rgba[..., 3] = 255
    rgba[0, 0, 3] = 0
    image = tmp_path / "map.png"
    Image.fromarray(rgba, mode="RGBA").save(image)
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump({"image": "map.png", "resolution": 0.05, "origin": [0, 0, 0]}))
    m = load_map(path)
    assert m.grid.occupied.tolist() == [[False] * 3, [False] * 3, [True, False, False]]
    assert m.walls == ()


def test_ros_map_accepts_rescuemesh_extras(tmp_path: Path) -> None:
    path = _write_ros_map(
        tmp_path, _blank(), name="lab", starts={"robot_1": [0.0, -1.5, 1.0]}, goals={"g": [0.5, -1.5]},
        regions={"all": [-1.0, -2.0, 1.0, -1.0]},
    )
    m = load_map(path)
    assert m.name == "lab"
    assert m.starts["robot_1"].yaw == pytest.approx(1.0)
    assert m.goals["g"].yaw == 0.0
    assert m.region_of(0.0, -1.5) == "all"


def test_small_wall_map_is_rasterised(tmp_path: Path) -> None:
    path = tmp_path / "box.yaml"
    path.write_text(
        "walls:\n  - [0, 0, 2, 0.1]\n  - [0, 1.9, 2, 2]\n  - [0, 0, 0.1, 2]\n  - [1.9, 0, 2, 2]\n"
        "starts:\n  r: [1, 1, 0]\n"
    )
    m = load_map(path, grid_resolution=0.05)
    assert m.name == "box" and m.bounds == Rect(0, 0, 2, 2)
    assert m.grid.shape == (40, 40)
    assert m.grid.occupied[0:2, :].all() and not m.grid.occupied[2, 2:38].any()  # 0.1 m wall = 2 cells
    assert int(m.grid.occupied.sum()) == 40 * 40 - 36 * 36


def test_merge_cells_covers_exactly_without_overlap() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        mask = rng.random((15, 17)) < 0.4
        cover = np.zeros(mask.shape, dtype=int)
        for r0, c0, r1, c1 in merge_cells(mask):
            cover[r0:r1, c0:c1] += 1
        assert np.array_equal(cover, mask.astype(int))
    assert cells_to_rects(np.ones((3, 4), dtype=bool), 0.5, 1.0, 2.0) == (Rect(1.0, 2.0, 3.0, 3.5),)


# ---------------------------------------------------------------- bad inputs

GOOD_WALL = "walls:\n  - [0, 0, 1, 0.1]\n"


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("walls: [[0, 0, 1", "not valid YAML"),
        ("- a\n- b\n", "must be a YAML mapping"),
        ("", "is empty"),
        ("name: x\n", "neither"),
        (GOOD_WALL + "image: m.pgm\n", "both"),
        ("walls: []\n", "empty"),
        ("walls: 3\n", "must be a list"),
        ("walls:\n  - [0, 0, 1]\n", "walls[0]"),
        ("walls:\n  - [0, 0, a, 1]\n", "walls[0]"),
        ("walls:\n  - [0, 0, 1, .nan]\n", "finite"),
        ("walls:\n  - [0, 0, 1, 0.1]\n  - [2, 0, 1, 1]\n", "x_max > x_min"),
        (GOOD_WALL + "wals: []\n", "unknown key"),
        (GOOD_WALL + "wall_height: 0\n", "wall_height"),
        (GOOD_WALL + "regions: [1, 2]\n", "'regions' must be a mapping"),
        (GOOD_WALL + "regions:\n  hall: [0, 0, 1]\n", "regions.hall"),
        (GOOD_WALL + "starts:\n  r1: [0.5, 0.05, 0]\n", "starts.r1"),
        (GOOD_WALL + "starts:\n  r1: [5, 5, 0]\n", "outside the map"),
        (GOOD_WALL + "goals:\n  g: true\n", "goals.g"),
        (GOOD_WALL + "name: 3\n", "'name'"),
        ("image: nothere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "not found"),
        ("image: map.pgm\nresolution: 0\norigin: [0, 0, 0]\n", "resolution"),
        ("image: map.pgm\nresolution: -1\norigin: [0, 0, 0]\n", "resolution"),
        ("image: map.pgm\norigin: [0, 0, 0]\n", "resolution"),
        ("image: map.pgm\nresolution: 0.05\n", "origin"),
        ("image: map.pgm\nresolution: 0.05\norigin: [0, 0]\n", "origin"),
        ("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0.5]\n", "not supported"),
        ("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 2\n", "negate"),
        ("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nfree_thresh: 0.7\n", "thresholds"),
        ("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\noccupied_thresh: 1.5\n", "thresholds"),
        ("image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: fancy\n", "mode"),
        ("image: garbage.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "cannot read image"),
        ("image: [1]\nresolution: 0.05\norigin: [0, 0, 0]\n", "'image'"),
    ],
)
def test_bad_map_files_raise_one_line_map_errors(tmp_path: Path, text: str, fragment: str) -> None:
    Image.fromarray(_blank()).save(tmp_path / "map.pgm")
    (tmp_path / "garbage.pgm").write_bytes(b"P5\n20 10\n255\n\x00\x01")  # truncated
    path = tmp_path / "bad_map.yaml"
    path.write_text(text)
    with pytest.raises(MapError) as info:
        load_map(path)
    message = str(info.value)
    assert "bad_map.yaml" in message and fragment in message
    assert "\n" not in message


def test_missing_binary_and_directory_paths_raise_map_errors(tmp_path: Path) -> None:
    for path, fragment in [
        (tmp_path / "absent.yaml", "no such map file"),
        (tmp_path, "directory"),
    ]:
        with pytest.raises(MapError, match=fragment) as info:
            load_map(path)
        assert path.name in str(info.value)
    image = tmp_path / "image.pgm"
    Image.fromarray(_blank()).save(image)
    with pytest.raises(MapError) as info:  # a binary file is not YAML
        load_map(image)
    assert "image.pgm" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.parametrize("resolution", [0.0, -0.05, float("nan")])
def test_bad_grid_resolution_is_a_map_error(resolution: float) -> None:
    from rescuemesh.maps import office_map_path

    with pytest.raises(MapError, match="grid resolution"):
        load_map(office_map_path(), grid_resolution=resolution)


def test_wall_materials_are_read_and_rasterised(tmp_path: Path) -> None:
    from rescuemesh.maps import WallMaterial

    path = tmp_path / "walls.yaml"
    path.write_text("walls:\n  - [0, 0, 4, 0.2, concrete]\n  - [0, 1.8, 4, 2, light]\n  - [1.9, 0.2, 2.1, 1.8]\n")
    m = load_map(path, grid_resolution=0.1)
    assert m.wall_materials == (WallMaterial.CONCRETE, WallMaterial.LIGHT, None)
    assert m.grid.materials is not None
    assert m.grid.materials[0, 5] == WallMaterial.CONCRETE.code
    assert m.grid.materials[19, 5] == WallMaterial.LIGHT.code
    assert m.grid.materials[10, 20] == 0 and m.grid.occupied[10, 20]  # untagged wall
    assert m.grid.materials[10, 5] == 0 and not m.grid.occupied[10, 5]  # free space
    # a map with no tags keeps no material raster
    plain = tmp_path / "plain.yaml"
    plain.write_text("walls:\n  - [0, 0, 4, 0.2]\n  - [0, 1.8, 4, 2]\n")
    assert load_map(plain, grid_resolution=0.1).grid.materials is None


def test_an_unknown_wall_material_is_one_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "walls.yaml"
    path.write_text("walls:\n  - [0, 0, 4, 0.2, marble]\n  - [0, 1.8, 4, 2]\n")
    with pytest.raises(MapError, match=r"walls\[0\] has an unknown wall material 'marble'; known: light, brick"):
        load_map(path)
