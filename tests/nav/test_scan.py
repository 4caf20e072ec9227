"""LaserScan.points_in_map (the navigation's only view of a sweep), against the plain formula."""

import math

import numpy as np
import pytest

from rescuemesh.body import LaserScan
from rescuemesh.geometry import Pose2D


def plain_points(scan: LaserScan) -> np.ndarray:
    r = scan.ranges
    ok = np.isfinite(r) & (r >= scan.range_min) & (r <= scan.range_max)
    a = scan.angles()[ok] + scan.origin.yaw
    return np.stack([scan.origin.x + r[ok] * np.cos(a), scan.origin.y + r[ok] * np.sin(a)], axis=1)


@pytest.mark.parametrize("range_max", [5.6, math.inf])
def test_points_in_map_are_the_valid_returns_placed_in_the_map(range_max):
    rng = np.random.default_rng(2)
    for trial in range(20):
        n = int(rng.choice([1, 90, 683]))
        ranges = rng.uniform(0.0, 7.0, n)
        ranges[rng.random(n) < 0.2] = np.inf
        ranges[rng.random(n) < 0.05] = np.nan
        # two lidars of different beam geometry in turn: the cached angles must not be mixed up
        fov = math.radians(240.0 if trial % 2 else 360.0)
        scan = LaserScan(float(trial), Pose2D(*rng.uniform(-5.0, 5.0, 2), rng.uniform(-math.pi, math.pi)),
                         -0.5 * fov, fov / max(n - 1, 1), 0.02, range_max, ranges)
        got = scan.points_in_map()
        np.testing.assert_array_equal(got, plain_points(scan))
        valid = np.isfinite(ranges) & (ranges >= 0.02) & (ranges <= range_max)
        assert got.shape == (int(valid.sum()), 2)
