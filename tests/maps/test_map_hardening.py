"""Maps an attacker (or an unlucky export) could hand a robot: a checkerboard that would become
hundreds of thousands of wall boxes, a wall list as long, YAML nested thousands deep (issue 17)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from rescuemesh.maps import MapError, load_map
from rescuemesh.maps.loaders import MAX_WALL_BOXES


def _error(path: Path) -> str:
    with pytest.raises(MapError) as info:
        load_map(path)
    return str(info.value)


def test_a_checkerboard_ros_map_is_refused_with_the_figure_and_the_limit(tmp_path):
    # this used to become 500,000 wall boxes (5.8 s, 169 MB) before anything ran
    board = np.indices((1000, 1000)).sum(axis=0) % 2  # occupied every other cell: 50 %
    Image.fromarray(np.where(board, 0, 255).astype(np.uint8)).save(tmp_path / "map.pgm")
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump({"image": "map.pgm", "resolution": 0.05, "origin": [0.0, 0.0, 0.0]}))
    start = time.perf_counter()
    error = _error(path)
    assert time.perf_counter() - start < 3.0
    assert "wall boxes" in error and f"{MAX_WALL_BOXES:,}" in error and "at least" in error
    assert len(error.splitlines()) == 1


def test_a_wall_map_listing_more_walls_than_the_limit_is_refused(tmp_path):
    path = tmp_path / "walls.yaml"
    walls = "".join(f"  - [{i * 0.01:.2f}, 0, {i * 0.01 + 0.005:.3f}, 1]\n" for i in range(MAX_WALL_BOXES + 1))
    path.write_text("walls:\n" + walls)
    error = _error(path)
    assert f"{MAX_WALL_BOXES + 1:,} walls" in error and f"{MAX_WALL_BOXES:,}" in error


@pytest.mark.parametrize("opener", ["[", "{a: "])
def test_yaml_nested_thousands_deep_is_a_map_error_not_a_recursion_error(tmp_path, opener):
    # this used to escape load_map as a RecursionError traceback
    path = tmp_path / "deep.yaml"
    depth = 20_000
    closer = "]" if opener == "[" else "}"
    path.write_text("walls: " + opener * depth + closer * depth + "\n")
    error = _error(path)
    assert "too deeply" in error and len(error.splitlines()) == 1
