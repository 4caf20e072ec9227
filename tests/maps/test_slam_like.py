"""The bench's SLAM-like map: about 1,000 occupied-cell runs, the office's free space kept, reproducible."""

from __future__ import annotations

import numpy as np
import pytest

from rescuemesh.maps import load_map, office_map_path
from rescuemesh.maps.slam_like import UNKNOWN, write_slam_like_map


@pytest.fixture(scope="module")
def office():
    return load_map(office_map_path())


def test_has_about_a_thousand_wall_boxes_where_the_office_has_a_few(tmp_path, office):
    slam = load_map(write_slam_like_map(tmp_path, seed=0))
    assert len(office.walls) < 30
    assert 800 <= len(slam.walls) <= 1300


def test_keeps_the_office_starts_and_goal_clear(tmp_path, office):
    slam = load_map(write_slam_like_map(tmp_path, seed=1))
    for pose in [*office.starts.values(), office.goals["follow_leader"]]:
        assert not slam.grid.is_occupied(pose.x, pose.y)
        # the TurtleBot footprint (0.18 m) around each is free too
        for dx, dy in ((0.2, 0), (-0.2, 0), (0, 0.2), (0, -0.2)):
            assert not slam.grid.is_occupied(pose.x + dx, pose.y + dy)


def test_has_an_unknown_border_and_a_ragged_wall(tmp_path, office):
    from PIL import Image

    write_slam_like_map(tmp_path, seed=0)
    pixels = np.asarray(Image.open(tmp_path / "slam_like.pgm"))
    assert (pixels[0] == UNKNOWN).all() and (pixels[:, 0] == UNKNOWN).all()
    slam = load_map(tmp_path / "slam_like.yaml")
    assert slam.grid.occupied.sum() > office.grid.occupied.sum() * 1.2


def test_same_seed_same_map_other_seed_other_map(tmp_path):
    a = (tmp_path / "a" / "slam_like.pgm", write_slam_like_map(tmp_path / "a", seed=3))
    b = (tmp_path / "b" / "slam_like.pgm", write_slam_like_map(tmp_path / "b", seed=3))
    c = (tmp_path / "c" / "slam_like.pgm", write_slam_like_map(tmp_path / "c", seed=4))
    assert a[0].read_bytes() == b[0].read_bytes()
    assert a[0].read_bytes() != c[0].read_bytes()


@pytest.mark.parametrize("kwargs", [{"speck_fraction": -0.1}, {"ragged_fraction": 1.5}])
def test_refuses_fractions_outside_zero_to_one(tmp_path, kwargs):
    with pytest.raises(ValueError, match="must be in"):
        write_slam_like_map(tmp_path, **kwargs)
