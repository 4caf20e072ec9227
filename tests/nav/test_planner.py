import math
import numpy as np
import pytest
from navworld import room_with_door

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.nav import PLANNERS, Costmap, MCPPlanner, Planner, make_planner, register_planner
from rescuemesh.nav.path import cumulative_lengths
from rescuemesh.nav.planner import _area

ROBOT_RADIUS = 0.177


def true_clearance(grid: OccupancyGrid, pts: np.ndarray) -> np.ndarray:
    """Exact distance in m from each point to the nearest occupied cell square."""
    rows, cols = np.nonzero(grid.occupied)
    lo_x = grid.origin_x + cols * grid.resolution
    lo_y = grid.origin_y + rows * grid.resolution
    dx = np.maximum(np.maximum(lo_x[None, :] - pts[:, :1], 0.0), pts[:, :1] - (lo_x[None, :] + grid.resolution))
    dy = np.maximum(np.maximum(lo_y[None, :] - pts[:, 1:], 0.0), pts[:, 1:] - (lo_y[None, :] + grid.resolution))
    return np.hypot(dx, dy).min(axis=1)


def densify(points: np.ndarray, step: float = 0.01) -> np.ndarray:
    cum = cumulative_lengths(points)
    s = np.arange(0.0, cum[-1], step)
    return np.stack([np.interp(s, cum, points[:, 0]), np.interp(s, cum, points[:, 1])], axis=1)


def test_registry_makes_planners_by_name():
    assert isinstance(make_planner("mcp"), MCPPlanner)
    assert isinstance(make_planner(), MCPPlanner)
    assert {"mcp", "straight"} <= set(PLANNERS)
    with pytest.raises(ValueError, match="mcp"):
        make_planner("rrt-star")
    with pytest.raises(ValueError):
        register_planner("mcp")(type("Dup", (Planner,), {"plan": lambda self, *a, **k: None}))


@pytest.mark.parametrize("downsample", [1, 2])
def test_path_goes_through_the_middle_of_the_doorway_clear_of_walls(room_costmap, downsample):
    start, goal = Pose2D(1.0, 1.0), Pose2D(5.0, 3.0)
    path = make_planner("mcp", downsample=downsample).plan(room_costmap, start, goal)
    assert path is not None
    np.testing.assert_allclose(path.points[0], (1.0, 1.0))
    np.testing.assert_allclose(path.points[-1], (5.0, 3.0))
    assert path.length_m == pytest.approx(cumulative_lengths(path.points)[-1])
    dense = densify(path.points)
    assert true_clearance(room_costmap.grid, dense).min() >= ROBOT_RADIUS
    in_door = dense[np.abs(dense[:, 0] - 3.05) < 0.05]
    assert len(in_door) and np.all(np.abs(in_door[:, 1] - 2.0) < 0.15)
    assert len(path.points) < 15  # shortcut: a clean polyline, not a cell staircase


def test_goal_walled_off_gives_none():
    grid = room_with_door()
    occ = grid.occupied.copy()
    occ[:, 60:62] = True  # close the doorway
    cm = Costmap(OccupancyGrid(occ, grid.resolution, grid.origin_x, grid.origin_y))
    assert make_planner("mcp").plan(cm, Pose2D(1.0, 1.0), Pose2D(5.0, 3.0)) is None


@pytest.mark.parametrize("goal", [Pose2D(3.05, 0.5), Pose2D(0.05, 2.0), Pose2D(0.2, 2.0), Pose2D(9.0, 2.0)])
def test_goal_in_a_wall_or_its_inflation_gives_none(room_costmap, goal):
    assert make_planner("mcp").plan(room_costmap, Pose2D(1.0, 1.0), goal) is None


def test_goal_in_lethal_space_is_snapped_within_goal_tolerance(room_costmap):
    goal = Pose2D(0.2, 2.0)  # 0.1 m from the west wall
    path = make_planner("mcp").plan(room_costmap, Pose2D(1.5, 1.0), goal, goal_tolerance=0.3)
    assert path is not None
    end = path.points[-1]
    assert room_costmap.is_free(*end)
    assert np.hypot(*(end - (goal.x, goal.y))) <= 0.3


def test_start_inside_inflation_is_snapped_to_free_space(room_costmap):
    start = Pose2D(0.22, 1.0)  # brushed the west wall
    assert not room_costmap.is_free(start.x, start.y)
    path = make_planner("mcp").plan(room_costmap, start, Pose2D(2.0, 3.0))
    assert path is not None
    np.testing.assert_allclose(path.points[0], (start.x, start.y))
    assert all(room_costmap.is_free(*p) for p in path.points[1:])


def test_start_deep_in_a_wall_gives_none(room_costmap):
    assert make_planner("mcp", start_snap_radius=0.2).plan(room_costmap, Pose2D(3.05, 0.5), Pose2D(1.0, 1.0)) is None


def test_scan_obstacles_are_planned_around(corridor_costmap):
    blocker = np.array([[4.0, 1.1 + dy] for dy in np.linspace(-0.2, 0.2, 9)])
    cm = corridor_costmap.with_obstacles(blocker, 0.0)
    path = make_planner("mcp").plan(cm, Pose2D(1.0, 1.1), Pose2D(7.0, 1.1))
    assert path is not None
    dense = densify(path.points)
    gap = np.hypot(dense[:, None, 0] - blocker[None, :, 0], dense[:, None, 1] - blocker[None, :, 1]).min()
    assert gap >= ROBOT_RADIUS


def test_same_cell_start_and_goal(room_costmap):
    path = make_planner("mcp").plan(room_costmap, Pose2D(1.0, 1.0), Pose2D(1.01, 1.0))
    assert path is not None and path.length_m == pytest.approx(0.01)


def test_straight_planner_refuses_to_cross_a_wall(room_costmap):
    planner = make_planner("straight")
    assert planner.plan(room_costmap, Pose2D(1.0, 2.0), Pose2D(2.0, 2.5)) is not None
    assert planner.plan(room_costmap, Pose2D(1.0, 1.0), Pose2D(5.0, 1.0)) is None


def _big_hall(with_long_wall: bool) -> Costmap:
    """100 m x 100 m at 0.05 m (4 M cells); optionally a wall at x = 50 m from y = 0 to 95 m."""
    occ = np.zeros((2000, 2000), dtype=bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    if with_long_wall:
        occ[:1900, 1000:1004] = True
    return Costmap(OccupancyGrid(occ, 0.05, 0.0, 0.0))


def test_a_short_plan_on_a_large_map_searches_a_window_not_the_map():
    # a 2 m plan on a 100 m map used to build and search the whole 1000 x 1000 coarse grid
    costmap = _big_hall(with_long_wall=False)
    planner = MCPPlanner()
    path = planner.plan(costmap, Pose2D(20.0, 20.0, 0.0), Pose2D(22.0, 21.0, 0.0))
    assert path is not None and path.length_m == pytest.approx(math.hypot(2.0, 1.0), abs=0.05)
    window = planner._graph[0]
    searched = (window[1] - window[0]) * (window[3] - window[2])
    assert searched < 0.05 * 1000 * 1000


def test_a_detour_wider_than_the_window_is_still_found_on_the_whole_map():
    costmap = _big_hall(with_long_wall=True)
    planner = MCPPlanner()
    start, goal = Pose2D(49.0, 10.0, 0.0), Pose2D(51.5, 10.0, 0.0)  # 2.5 m apart, the wall's end 85 m north
    path = planner.plan(costmap, start, goal)
    assert path is not None and path.length_m > 160.0
    assert planner._graph[0] == (0, 1000, 0, 1000)  # it had to search the whole map
    assert not costmap.any_lethal(path.points[:, 0], path.points[:, 1])


def _plans_agree(a, b) -> bool:
    return (a is None) == (b is None) and (a is None or np.array_equal(a.points, b.points))


def test_a_path_proved_best_in_a_small_window_is_the_whole_map_search_path(room_costmap):
    # the first, small window keeps its path only when no path leaving it can be cheaper: the
    # same points as searching the whole map, with and without scan obstacles, snapped goals too
    rng = np.random.default_rng(3)
    free = np.argwhere(~room_costmap.lethal)
    small, whole = MCPPlanner(), MCPPlanner(first_margin_m=None, window_margin_m=None)
    searched = []
    for trial in range(120):
        r, c = free[rng.integers(len(free))]
        sx, sy = room_costmap.cell_to_world(r, c)
        d, a = rng.choice([0.5, 1.0, 2.0, 4.0]), rng.uniform(0.0, 2.0 * math.pi)
        goal = Pose2D(sx + d * math.cos(a), sy + d * math.sin(a))
        blobs = rng.uniform((0.5, 0.5), (5.5, 3.5), size=(int(rng.integers(0, 4)), 2))
        points = (blobs[:, None, :] + rng.normal(0.0, 0.1, (len(blobs), 20, 2))).reshape(-1, 2)
        tol = 0.5 if trial % 2 else 0.0
        cm = room_costmap.with_obstacles(points, float(trial), clear_center=(goal.x, goal.y), clear_radius=tol)
        fresh = room_costmap.with_obstacles(points, float(trial), clear_center=(goal.x, goal.y), clear_radius=tol)
        got = small.plan(cm, Pose2D(sx, sy), goal, goal_tolerance=tol)
        assert _plans_agree(got, whole.plan(fresh, Pose2D(sx, sy), goal, goal_tolerance=tol)), trial
        if got is not None and d <= 1.0:
            searched.append(_area(small._graph[0]))
    assert np.median(searched) < 0.5 * 60 * 40  # short plans searched a window, not the 60 x 40 coarse map


def test_a_cheaper_way_out_of_the_small_window_is_not_missed():
    # start and goal 1.1 m apart across a wall: a tight slot (costly, near both jambs) between them
    # inside the first window, a wide doorway outside it; the doorway is cheaper
    occ = np.zeros((200, 200), dtype=bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[:, 100:102] = True
    occ[94:106, 100:102] = False  # 0.6 m slot at y = 5 m
    occ[126:156, 100:102] = False  # 1.5 m doorway from y = 6.3 m, beyond the first window
    cm = Costmap(OccupancyGrid(occ, 0.05, 0.0, 0.0))
    start, goal = Pose2D(4.5, 5.0), Pose2D(5.6, 5.0)
    planner = MCPPlanner()
    path = planner.plan(cm, start, goal)
    reference = MCPPlanner(first_margin_m=None, window_margin_m=None).plan(cm, start, goal)
    assert _plans_agree(path, reference)
    assert path.points[:, 1].max() > 6.3  # through the doorway, not the slot
    slot_only = MCPPlanner(first_margin_m=None, window_margin_m=0.5).plan(cm, start, goal)
    assert slot_only is not None and slot_only.points[:, 1].max() < 6.0  # a window can hold the worse way


def test_a_path_through_a_slot_is_proved_best_in_the_small_window_on_a_small_map():
    # 6 m through a costly 0.6 m slot, with open space beside the first window: a path leaving it
    # may be no longer than this one, but on the static map it must come back through the same
    # slot, so the small window's path is kept (a leader replanning to its goal every second)
    occ = np.zeros((100, 200), dtype=bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[:, 100:102] = True
    occ[44:56, 100:102] = False  # 0.6 m slot at y = 2.5 m
    cm = Costmap(OccupancyGrid(occ, 0.05, 0.0, 0.0))
    start, goal = Pose2D(2.0, 2.5), Pose2D(8.0, 2.5)
    planner = MCPPlanner()
    path = planner.plan(cm, start, goal)
    assert _plans_agree(path, MCPPlanner(first_margin_m=None, window_margin_m=None).plan(cm, start, goal))
    rows = planner._graph[0][1] - planner._graph[0][0]
    assert rows < 40  # the first window: 1.2 m around the straight line, not the whole 5 m
