"""The packaged office map: loads, and its walls, doorways, regions, starts and goal are consistent."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import ndimage
from skimage.graph import route_through_array

from rescuemesh.maps import MapModel, Rect, load_map, office_map_path
from rescuemesh.maps.raster import rasterise_walls

ROBOT_RADIUS = 0.177  # m, TurtleBot 2


@pytest.fixture(scope="module")
def office() -> MapModel:
    return load_map(office_map_path())


def _overlap_area(a: Rect, b: Rect) -> float:
    w = min(a.x_max, b.x_max) - max(a.x_min, b.x_min)
    h = min(a.y_max, b.y_max) - max(a.y_min, b.y_min)
    return max(0.0, w) * max(0.0, h)


def _clearance(office: MapModel) -> np.ndarray:
    """Distance in m from each cell centre to the nearest occupied cell."""
    g = office.grid
    return ndimage.distance_transform_edt(~g.occupied) * g.resolution


def test_office_size_and_content(office: MapModel) -> None:
    assert office.name == "small_office"
    assert office.bounds == Rect(0.0, 0.0, 19.5, 9.2)
    assert office.wall_height == pytest.approx(0.5)
    assert 10 <= len(office.walls) <= 40
    assert office.grid.shape == (184, 390)  # 9.2 m x 19.5 m at 0.05 m
    for name in ("hall", "passage", "room_east", "room_north", "room_south", "room_northeast"):
        assert name in office.regions
    assert set(office.starts) == {"robot_1", "robot_2", "robot_3"}
    assert "follow_leader" in office.goals


def test_starts_and_goal_are_free_and_placed_as_the_scenarios_need(office: MapModel) -> None:
    g = office.grid
    for pose in [*office.starts.values(), *office.goals.values()]:
        assert not g.is_occupied(pose.x, pose.y)
    r1, r2, r3 = (office.starts[n] for n in ("robot_1", "robot_2", "robot_3"))
    assert {office.region_of(p.x, p.y) for p in (r1, r2, r3)} == {"hall"}
    # robot_2 about 1.5 m straight behind robot_1
    assert r1.distance_to(r2) == pytest.approx(1.5, abs=0.1)
    assert math.cos(r1.bearing_to(r2) - r1.yaw) < -0.95
    assert r3.distance_to(r1) > 4.0 and r3.distance_to(r2) > 3.0
    goal = office.goals["follow_leader"]
    assert office.region_of(goal.x, goal.y) == "room_east"


def test_robot_1_sits_in_a_clear_disc_for_move_around(office: MapModel) -> None:
    r1 = office.starts["robot_1"]
    clearance = _clearance(office)[office.grid.world_to_cell(r1.x, r1.y)]
    assert clearance >= 2.2  # a 1.5 m move-around circle plus the robot radius and a margin


def test_regions_are_free_and_disjoint(office: MapModel) -> None:
    for name, region in office.regions.items():
        for wall in office.walls:
            area = _overlap_area(region, wall)
            # furniture may stand inside a room; structural walls may not cut into a region
            assert area == 0.0 or (wall.x_max - wall.x_min) * (wall.y_max - wall.y_min) < 2.0, (name, wall)
    for (na, a), (nb, b) in itertools.combinations(office.regions.items(), 2):
        assert _overlap_area(a, b) == 0.0, (na, nb)


def test_doorways_are_real_openings(office: MapModel) -> None:
    g = office.grid
    assert len(office.doorways) >= 4
    for door in office.doorways:
        width = max(door.x_max - door.x_min, door.y_max - door.y_min)
        assert width >= 0.9
        assert all(_overlap_area(door, wall) == 0.0 for wall in office.walls), door
        # every cell across the opening is free
        sub = rasterise_walls([door], office.bounds, g.resolution).occupied
        assert sub.sum() > 0 and not (g.occupied & sub).any(), door


def test_follow_path_runs_from_the_hall_through_one_doorway_into_room_east(office: MapModel) -> None:
    g = office.grid
    free = _clearance(office) > ROBOT_RADIUS + 0.05
    cost = np.where(free, 1.0, 1e9)
    start, goal = office.starts["robot_1"], office.goals["follow_leader"]
    path, total = route_through_array(
        cost, g.world_to_cell(start.x, start.y), g.world_to_cell(goal.x, goal.y), fully_connected=True, geometric=True
    )
    assert total < 1e9  # reachable with the robot's footprint
    length = total * g.resolution
    assert 6.0 <= length <= 10.0
    door = Rect(13.6, 4.1, 13.7, 5.1)
    assert door in office.doorways
    points = [g.cell_to_world(r, c) for r, c in path]
    assert any(door.contains(x, y) for x, y in points)
    regions = [office.region_of(x, y) for x, y in points]
    visited = [r for i, r in enumerate(regions) if r is not None and (i == 0 or r != regions[i - 1])]
    assert [r for i, r in enumerate(visited) if i == 0 or r != visited[i - 1]] == ["hall", "passage", "room_east"]
