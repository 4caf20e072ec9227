"""Map limits and the rough edges of real maps: YAML aliases, huge values in messages, huge images,
maps beyond the wire format's pose range, inverted images, and the maps package's import graph."""

from __future__ import annotations

import ast
import time
import tracemalloc
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from rescuemesh.maps import MapError, load_map
from rescuemesh.maps import loaders

WHITE, BLACK = 255, 0
MAPS_DIR = Path(loaders.__file__).parent


def _ros_yaml(tmp_path: Path, image: str = "map.pgm", **fields: object) -> Path:
    doc = {"image": image, "resolution": 0.1, "origin": [0.0, 0.0, 0.0]}
    doc.update(fields)
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def _error(path: Path) -> str:
    with pytest.raises(MapError) as info:
        load_map(path)
    return str(info.value)


# ---------------------------------------------------------------- 1. YAML aliases, huge values


def _laughs(depth: int) -> str:
    """A billion-laughs YAML: each level is a list of 9 aliases of the level below."""
    lines = ['l0: &l0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, depth + 1):
        lines.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * 9) + "]")
    lines.append(f"image: *l{depth}")  # the first field a ROS map checks
    return "\n".join(lines) + "\n"


def test_yaml_aliases_are_refused_in_one_short_line(tmp_path: Path) -> None:
    # this used to embed repr() of the expanded value: 226 MB on one line (here depth 6: 3.7 MB)
    path = tmp_path / "laughs.yaml"
    path.write_text(_laughs(6))
    assert path.stat().st_size < 1000
    tracemalloc.start()
    start = time.perf_counter()
    try:
        message = _error(path)
        elapsed = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert "YAML aliases are not allowed in a map file" in message
    assert "laughs.yaml" in message and "\n" not in message and len(message) < 300
    assert elapsed < 2.0 and peak < 20_000_000


def test_deep_billion_laughs_is_refused_fast(tmp_path: Path) -> None:
    # this used to build a 226 MB error message and take 1 GB of memory (depth 8, 357 bytes on disk)
    path = tmp_path / "laughs.yaml"
    path.write_text(_laughs(8))
    start = time.perf_counter()
    message = _error(path)
    assert time.perf_counter() - start < 2.0
    assert "aliases" in message and len(message) < 300


def test_huge_values_are_cut_in_map_errors(tmp_path: Path) -> None:
    # this used to print every one of the 20,000 numbers of a bad wall in the message
    path = tmp_path / "long.yaml"
    path.write_text("walls:\n  - [" + ", ".join(["1"] * 20_000) + "]\nname: x\n")
    message = _error(path)
    assert "walls[0]" in message and "\n" not in message and len(message) < 300
    path.write_text("walls:\n  - [0, 0, 1, 1]\nname: [" + ", ".join(['"' + "a" * 50 + '"'] * 1000) + "]\n")
    message = _error(path)
    assert "'name'" in message and len(message) < 300


# ---------------------------------------------------------------- 2. image size


def _pgm_header_only(path: Path, width: int, height: int) -> None:
    """A PGM whose header claims width x height but whose body is a few bytes: cheap to write,
    and only readable if the size is checked before the pixels are decoded."""
    path.write_bytes(f"P5\n{width} {height}\n255\n".encode() + b"\xff" * 16)


def test_image_over_the_cell_limit_is_refused_before_decoding(tmp_path: Path) -> None:
    # this used to decode the pixels first (here: "cannot read image ... truncated"); 100 M cells ran
    _pgm_header_only(tmp_path / "map.pgm", 5000, 5000)
    message = _error(_ros_yaml(tmp_path))
    assert "map image is 5000 x 5000 = 25 M cells; the limit is 4000 x 4000 = 16 M cells" in message
    assert "\n" not in message


def test_decompression_bomb_warning_is_not_printed_raw(tmp_path: Path) -> None:
    # this used to print PIL's DecompressionBombWarning for a 10000 x 10000 image
    _pgm_header_only(tmp_path / "map.pgm", 10000, 10000)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        message = _error(_ros_yaml(tmp_path))
    assert "map image is 10000 x 10000 = 100 M cells; the limit is 4000 x 4000 = 16 M cells" in message


def test_decompression_bomb_error_names_the_limit(tmp_path: Path) -> None:
    # this used to say only "cannot read image ... could be decompression bomb DOS attack."
    _pgm_header_only(tmp_path / "map.pgm", 20000, 20000)
    message = _error(_ros_yaml(tmp_path))
    assert "400 M cells" in message and "the limit is 4000 x 4000 = 16 M cells" in message


def test_cell_limit_boundary(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # this used to have no image size limit at all (no MAX_MAP_CELLS)
    monkeypatch.setattr(loaders, "MAX_MAP_CELLS", 200)
    Image.fromarray(np.full((10, 20), WHITE, dtype=np.uint8)).save(tmp_path / "map.pgm")
    assert load_map(_ros_yaml(tmp_path)).grid.shape == (10, 20)
    Image.fromarray(np.full((10, 21), WHITE, dtype=np.uint8)).save(tmp_path / "map.pgm")
    assert "map image is 21 x 10 = 210 cells" in _error(_ros_yaml(tmp_path))


def test_real_image_just_over_the_limit_is_refused(tmp_path: Path) -> None:
    # this used to be loaded (16,004,000 cells), on the way to 100 M-cell maps that need 9.7 GB
    Image.fromarray(np.full((4000, 4001), WHITE, dtype=np.uint8)).save(tmp_path / "map.pgm")
    assert "the limit is 4000 x 4000 = 16 M cells" in _error(_ros_yaml(tmp_path))


def test_the_limit_is_the_same_for_wall_maps(tmp_path: Path) -> None:
    # this used to allow 50 M cells for wall maps (about 5 GB at run time)
    path = tmp_path / "big.yaml"
    path.write_text("walls:\n  - [0, 0, 300, 0.1]\n  - [0, 299.9, 300, 300]\n")  # 6000 x 6000 cells
    message = _error(path)
    assert "36 M cells" in message and "16 M cells" in message


# ---------------------------------------------------------------- 3. pose range


def test_ros_map_beyond_the_pose_range_is_refused(tmp_path: Path) -> None:
    # this used to load, then fail seconds into the run when a pose could not be encoded
    Image.fromarray(np.full((10, 100), WHITE, dtype=np.uint8)).save(tmp_path / "map.pgm")
    message = _error(_ros_yaml(tmp_path, resolution=4.1, origin=[-400.0, 0.0, 0.0]))
    assert (
        "map spans x -400.0..10.0 m; robots' poses are sent in int16 centimetres (-327.68..327.67 m):"
        " move the origin closer" in message
    )


def test_wall_map_beyond_the_pose_range_is_refused(tmp_path: Path) -> None:
    # this used to load, then fail seconds into the run when a pose could not be encoded
    path = tmp_path / "far.yaml"
    path.write_text("walls:\n  - [0, 320, 1, 330]\n")
    assert "map spans y 320.0..330.0 m" in _error(path)


def test_map_at_the_edge_of_the_pose_range_loads(tmp_path: Path) -> None:
    Image.fromarray(np.full((10, 10), WHITE, dtype=np.uint8)).save(tmp_path / "map.pgm")
    m = load_map(_ros_yaml(tmp_path, resolution=0.01, origin=[327.57, -327.68, 0.0]))
    assert m.bounds.x_max == pytest.approx(327.67)


def test_pose_range_matches_the_wire_format() -> None:
    from rescuemesh.protocol.errors import EncodeError
    from rescuemesh.protocol.wire import position_to_units

    lo, hi = loaders.POSE_RANGE_M
    assert position_to_units(lo) == -32768 and position_to_units(hi) == 32767
    for outside in (lo - 0.01, hi + 0.01):
        with pytest.raises(EncodeError):
            position_to_units(outside)


# ---------------------------------------------------------------- 4. negate


def test_mostly_occupied_map_hints_at_negate(tmp_path: Path) -> None:
    # this used to load, and the run then failed with "goal is inside an obstacle"
    Image.fromarray(np.full((10, 10), WHITE, dtype=np.uint8)).save(tmp_path / "map.pgm")
    message = _error(_ros_yaml(tmp_path, negate=1))
    assert "100 % of the map is occupied: is `negate` right? (negate: 1 means white is occupied)" in message


def test_mostly_black_map_hints_at_negate_0(tmp_path: Path) -> None:
    # this used to load a map with no room for any robot
    pixels = np.full((10, 10), BLACK, dtype=np.uint8)
    pixels[0, :8] = WHITE  # 8 % free
    Image.fromarray(pixels).save(tmp_path / "map.pgm")
    message = _error(_ros_yaml(tmp_path))
    assert "92 % of the map is occupied: is `negate` right? (negate: 0 means black is occupied)" in message


def test_ninety_percent_occupied_still_loads(tmp_path: Path) -> None:
    pixels = np.full((10, 10), BLACK, dtype=np.uint8)
    pixels[0, :] = WHITE  # exactly 90 % occupied
    Image.fromarray(pixels).save(tmp_path / "map.pgm")
    assert int(load_map(_ros_yaml(tmp_path)).grid.occupied.sum()) == 90


# ---------------------------------------------------------------- 5. import graph


def _maps_imports() -> dict[str, set[str]]:
    """rescuemesh.maps module -> the rescuemesh.maps modules it imports, anywhere in its body."""
    graph: dict[str, set[str]] = {}
    for file in MAPS_DIR.glob("*.py"):
        name = "rescuemesh.maps" if file.stem == "__init__" else f"rescuemesh.maps.{file.stem}"
        deps: set[str] = set()
        for node in ast.walk(ast.parse(file.read_text())):
            if isinstance(node, ast.Import):
                deps.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                deps.add(node.module)
                deps.update(f"{node.module}.{a.name}" for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                raise AssertionError(f"{file.name}: use absolute imports")
        graph[name] = {d for d in deps if d.startswith("rescuemesh.maps.") and d != name}
    return graph


def test_maps_modules_do_not_import_each_other_in_a_cycle() -> None:
    # this used to fail: model.load_map imported loaders, which imports model
    graph = _maps_imports()
    graph = {name: {d for d in deps if d in graph} for name, deps in graph.items()}
    done: set[str] = set()

    def visit(name: str, stack: tuple[str, ...]) -> None:
        assert name not in stack, "import cycle: " + " -> ".join((*stack, name))
        if name in done:
            return
        for dep in sorted(graph[name]):
            visit(dep, (*stack, name))
        done.add(name)

    for name in sorted(graph):
        visit(name, ())
    assert "rescuemesh.maps.loaders" not in graph["rescuemesh.maps.model"]


def test_maps_is_a_leaf_and_old_import_paths_work() -> None:
    for file in MAPS_DIR.glob("*.py"):
        for node in ast.walk(ast.parse(file.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("rescuemesh."):
                assert node.module.split(".")[1] in ("maps", "geometry"), f"{file.name} imports {node.module}"
    import rescuemesh.maps as maps
    from rescuemesh.maps.loaders import load_map as loaders_load_map
    from rescuemesh.maps.model import MapError as ModelMapError
    from rescuemesh.maps.model import office_map_path

    assert maps.load_map is loaders_load_map and maps.MapError is ModelMapError
    assert maps.office_map_path is office_map_path
