"""Teams of N robots: names and automatic start poses in free space.

Owns: team names (robot_1 .. robot_N), the team size limits, and `place_behind`, which puts a team
on a lattice in free space behind its leader, ordered along the way to a goal. Must not know:
missions, the simulator, the radio.

How `place_behind` works: every free cell gets its path distance to the goal (scikit-image's
MCP_Geometric over the cells a TurtleBot 2's centre may occupy with `clearance_m` to spare). Lattice
points `spacing_m` apart, aligned on the leader's start, are candidates when they are reachable,
no nearer the goal than the leader (nobody starts ahead of it) and, if `allowed` is given, inside one
of those rectangles. The N - 1 candidates nearest the leader (by path) are taken and numbered as a
chain: robot_2 is the nearest to the leader in line of sight, robot_3 the nearest to robot_2, and
so on (ties: the one nearer the goal). Every robot then starts one lattice step from the robot it
will follow, so it does not drive off while the chain forms, and no follower has to squeeze past
another robot to reach its own.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from skimage.graph import MCP_Geometric

from rescuemesh.geometry import Pose2D
from rescuemesh.maps.grid import OccupancyGrid
from rescuemesh.maps.model import Rect
from rescuemesh.nav.costmap import grid_clearance
from rescuemesh.robot.naming import MAX_ROBOT_ADDRESS

#: Largest team a scenario accepts: every robot needs a unicast address (robot/naming.py).
MAX_TEAM = MAX_ROBOT_ADDRESS
#: Start lattice spacing in m: a TurtleBot 2 (0.354 m across) with about a follow distance between.
TEAM_SPACING_M = 0.95
#: Distance in m a placed robot's centre keeps from any obstacle: the footprint radius (0.177 m) and
#: room to turn in place next to its neighbours.
TEAM_CLEARANCE_M = 0.3


class PlacementError(ValueError):
    """The map has no room for the team as asked; the message says how many fit."""


def team_names(count: int) -> tuple[str, ...]:
    """robot_1 .. robot_`count`."""
    return tuple(f"robot_{k}" for k in range(1, count + 1))


def place_behind(grid: OccupancyGrid, leader: Pose2D, goal: tuple[float, float], count: int, *,
                 spacing_m: float = TEAM_SPACING_M, clearance_m: float = TEAM_CLEARANCE_M,
                 allowed: Sequence[Rect] = ()) -> list[Pose2D]:
    """`count` start poses: the leader's first, then count - 1 lattice points behind it (see the
    module docstring), each facing the way to the goal. PlacementError when fewer fit."""
    if count < 1:
        raise PlacementError(f"a team needs at least one robot, got {count}")
    free = grid_clearance(grid) >= clearance_m  # cells whose centre keeps clearance_m from every obstacle
    to_goal, toward_goal = _path_distance(grid, free, goal)
    leader_cell = grid.world_to_cell(leader.x, leader.y)
    if not _inside(grid, leader_cell) or not np.isfinite(to_goal[leader_cell]):
        raise PlacementError(f"the leader's start ({leader.x:.2f}, {leader.y:.2f}) has no path to the goal "
                             f"({goal[0]:.2f}, {goal[1]:.2f}) with {clearance_m} m to spare")
    from_leader, _ = _path_distance(grid, free, (leader.x, leader.y))
    candidates = []
    for x, y in _lattice(grid, leader, spacing_m):
        cell = grid.world_to_cell(x, y)
        if not _inside(grid, cell) or not free[cell] or (x, y) == (leader.x, leader.y):
            continue
        if allowed and not any(r.contains(x, y) for r in allowed):
            continue
        if not (np.isfinite(to_goal[cell]) and to_goal[cell] >= to_goal[leader_cell]):
            continue
        candidates.append((float(from_leader[cell]), float(to_goal[cell]), x, y))
    if len(candidates) < count - 1:
        raise PlacementError(f"room for {len(candidates) + 1} robots behind the leader here "
                             f"({spacing_m} m apart, {clearance_m} m from walls), {count} asked")
    chosen = [(x, y, goal_m) for _, goal_m, x, y in sorted(candidates)[:count - 1]]
    poses = [leader]
    for x, y in _chain_order(grid, free, (leader.x, leader.y), chosen):
        poses.append(Pose2D(x, y, _heading_to_goal(grid, toward_goal, x, y)))
    return poses


def _chain_order(grid: OccupancyGrid, free: np.ndarray, leader: tuple[float, float],
                 points: list[tuple[float, float, float]]) -> list[tuple[float, float]]:
    """`points` (x, y, path distance to the goal) numbered as a chain from the leader: each next
    robot is the nearest remaining point in line of sight of the previous one (ties: the one nearer
    the goal), so that every robot starts within one lattice step of the robot it follows and no
    follower has to pass another robot to reach its leader."""
    remaining = list(points)
    order = []
    current = leader
    while remaining:
        def rank(p):
            seen = _line_of_sight(grid, free, current, (p[0], p[1]))
            return (not seen, round(math.hypot(p[0] - current[0], p[1] - current[1]), 6), p[2])
        best = min(remaining, key=rank)
        remaining.remove(best)
        current = (best[0], best[1])
        order.append(current)
    return order


def _line_of_sight(grid: OccupancyGrid, free: np.ndarray, a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Whether the straight segment a -> b (m) stays in `free` cells (sampled every half cell)."""
    n = max(2, math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / (0.5 * grid.resolution)) + 1)
    for t in np.linspace(0.0, 1.0, n):
        cell = grid.world_to_cell(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
        if not _inside(grid, cell) or not free[cell]:
            return False
    return True


def _inside(grid: OccupancyGrid, cell: tuple[int, int]) -> bool:
    return grid.in_bounds(*cell)


def _path_distance(grid: OccupancyGrid, free: np.ndarray, origin: tuple[float, float]):
    """Path length in m from `origin` to every cell through `free` cells (inf where unreachable),
    and the MCP whose traceback(cell) leads from a cell back to `origin` (None if unreachable)."""
    cell = grid.world_to_cell(*origin)
    if not _inside(grid, cell) or not free[cell]:
        return np.full(free.shape, np.inf), None
    mcp = MCP_Geometric(np.where(free, 1.0, np.inf), fully_connected=True)
    distances, _ = mcp.find_costs([cell])
    return distances * grid.resolution, mcp


def _lattice(grid: OccupancyGrid, anchor: Pose2D, spacing_m: float):
    """Points `spacing_m` apart on a square lattice through `anchor`, covering the grid."""
    rows, cols = grid.shape
    x0, y0 = grid.origin_x, grid.origin_y
    x1, y1 = x0 + cols * grid.resolution, y0 + rows * grid.resolution
    i_lo, i_hi = math.ceil((x0 - anchor.x) / spacing_m), math.floor((x1 - anchor.x) / spacing_m)
    j_lo, j_hi = math.ceil((y0 - anchor.y) / spacing_m), math.floor((y1 - anchor.y) / spacing_m)
    for i in range(i_lo, i_hi + 1):
        for j in range(j_lo, j_hi + 1):
            yield round(anchor.x + i * spacing_m, 3), round(anchor.y + j * spacing_m, 3)


#: A placed robot faces the point this far (m) along its path to the goal.
HEADING_LOOKAHEAD_M = 1.0


def _heading_to_goal(grid: OccupancyGrid, toward_goal, x: float, y: float) -> float:
    """Yaw in rad toward the point HEADING_LOOKAHEAD_M along the shortest path from (x, y) to the goal."""
    row, col = grid.world_to_cell(x, y)
    path = toward_goal.traceback((row, col))[::-1]  # skimage lists it from the goal to (row, col)
    ahead = path[min(len(path) - 1, max(1, round(HEADING_LOOKAHEAD_M / grid.resolution)))]
    dr, dc = ahead[0] - row, ahead[1] - col
    return math.atan2(dr, dc) if (dr or dc) else 0.0
