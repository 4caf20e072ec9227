"""Global planners on a Costmap, registered by name (pyrobosim style) so a scenario can pick one.

Owns: the Planner interface, the PLANNERS registry, the default "mcp" planner (scikit-image
minimum-cost path) and path shortcutting. Must not know: robots, the controller, time, the protocol.
"""

from __future__ import annotations

import abc
import math
from collections import OrderedDict
from typing import Callable, ClassVar

import numpy as np
from skimage.graph import MCP_Geometric

from rescuemesh.geometry import Pose2D
from rescuemesh.nav import kernels
from rescuemesh.nav.costmap import LETHAL, Costmap
from rescuemesh.nav.path import Path


class Planner(abc.ABC):
    """Plans a collision-free path for the robot's centre from `start` to `goal` on a costmap."""

    name: ClassVar[str] = ""

    @abc.abstractmethod
    def plan(self, costmap: Costmap, start: Pose2D, goal: Pose2D, *, goal_tolerance: float = 0.0) -> Path | None:
        """A Path from start to goal, or None when there is none.

        A start in lethal space is moved to the nearest free cell (a robot that brushed a wall can
        still plan out). A goal in lethal space gives None, unless a free cell lies within
        `goal_tolerance` m of it: the path then ends there. Yaws are ignored.
        """


PLANNERS: dict[str, type[Planner]] = {}
"""Planner classes by name."""


def register_planner(name: str) -> Callable[[type[Planner]], type[Planner]]:
    """Class decorator: register a Planner subclass under `name`."""

    def deco(cls: type[Planner]) -> type[Planner]:
        if name in PLANNERS:
            raise ValueError(f"planner {name!r} is already registered")
        cls.name = name
        PLANNERS[name] = cls
        return cls

    return deco


def make_planner(name: str = "mcp", **kw) -> Planner:
    """An instance of the planner registered as `name`, built with keyword arguments `kw`."""
    try:
        cls = PLANNERS[name]
    except KeyError:
        raise ValueError(f"unknown planner {name!r}; known: {', '.join(sorted(PLANNERS))}") from None
    return cls(**kw)


def shortcut(
    costmap: Costmap, points: np.ndarray, *, max_segment_m: float = 2.0, cost_tolerance: float = 0.05
) -> np.ndarray:
    """Line-of-sight shortcutting of a cell path (N, 2) m on the costmap.

    From each kept point, jump to the farthest later point (at most `max_segment_m` away along the
    raw path) whose straight segment is not lethal and whose highest cost exceeds the highest cost of
    the raw path it replaces by no more than `cost_tolerance`: the result stays in the middle of
    doorways as the raw path did, without its 45-degree staircase. The farthest point is tried
    first (mostly it fits, and the nearer ones need not be sampled). A segment from a to b is
    sampled at np.linspace(0, 1, n) between them, n giving a sample every 0.75 cell along the
    longest segment tried from a; costs are float32, the tolerance added in float32. Compiled
    (nav/kernels.py, `shortcut_kept`).
    """
    if len(points) <= 2:
        return points
    pts = np.ascontiguousarray(points, dtype=float)
    h, w = costmap.shape
    grid = (h, w, costmap.grid.origin_x, costmap.grid.origin_y, costmap.resolution, float(max_segment_m),
            np.float32(cost_tolerance))
    cost, r0, c0 = costmap.known_costs()
    kept = kernels.shortcut_kept(pts, cost, r0, c0, *grid)
    if len(kept) == 0:  # a sample off the stamped window: the whole map's costs (the same values there)
        kept = kernels.shortcut_kept(pts, costmap.cost, 0, 0, *grid)
    return points[kept]


#: A search window covering at least this share of the map searches the whole map at once.
WHOLE_MAP_SHARE = 0.5

#: Search graphs are built over arrays of rows and columns rounded up to a multiple of this (the
#: rest impassable), so that windows of nearby sizes share one graph.
GRAPH_BLOCK = 16
#: Graphs a planner keeps, the least recently used given up first.
GRAPH_SLOTS = 4


def _graphs_read_costs_in_place() -> bool:
    """Whether MCP_Geometric searches a float64 Fortran-ordered cost array in place (scikit-image
    keeps `costs.astype(float64, copy=False).ravel("F")`, a view of such an array): new costs
    written into it are then searched without building the graph again. Checked once."""
    step = np.ones((2, 3), order="F")
    mcp = MCP_Geometric(step, fully_connected=True)
    step[0, 1] = np.inf
    cum, _ = mcp.find_costs([(0, 0)], [(0, 2)])
    return bool(cum[0, 2] > 2.0)  # around the blocked cell: 2 * sqrt(2); through it: 2


def _traceback_offsets() -> np.ndarray | None:
    """The steps MCP_Geometric's traceback array indexes (scikit-image's `make_offsets(2, True)`,
    which it does not expose on the graph), when reading the path back with them gives what its
    own `traceback` does on a probe search; else None (its `traceback` is then used). Checked once."""
    try:
        from skimage.graph._mcp import make_offsets

        offsets = np.array(make_offsets(2, True), dtype=np.int64).reshape(-1, 2)
    except (ImportError, TypeError, ValueError):
        return None
    costs = np.ones((6, 7), order="F")
    costs[1:5, 3] = np.inf
    mcp = MCP_Geometric(costs, fully_connected=True)
    _, traceback = mcp.find_costs([(4, 1)], [(1, 5)], find_all_ends=True)
    try:
        ours = kernels.trace_back(traceback, 1, 5, offsets)
    except ValueError:
        return None
    return offsets if [tuple(rc) for rc in ours.tolist()] == [tuple(rc) for rc in mcp.traceback((1, 5))] else None


class SearchGraph:
    """An `MCP_Geometric` over the step costs of a window of `shape` (rows, cols), built over a
    float64 Fortran-ordered array of at least that shape whose cells beyond it are impassable
    (inf): the search never pushes them, so it pushes and pops the window's cells in the same
    order, with the same costs and ties, as a graph of the window's own shape (its cells are the
    array's first rows and columns). `refill` makes it the graph of new step costs of the same or
    a smaller shape without building a new MCP, when scikit-image searches the array in place:
    building one costs in proportion to the array (0.1 ms for a 30 x 30 window, 1 ms for a
    100 x 200 map), and a robot plans several times a second, mostly on a new scan.

    A refilled graph searches as a new one would. MCP's `find_costs` resets the costs but not its
    heap's entry count: a search that stopped at its goal leaves entries behind (costs reset to
    inf), which a later search pops once it runs out of cells (no goal, or none reachable), each
    pop writing inf over the cumulative cost of the cell the entry names. `refill` first runs a
    search on all-impassable costs, which pops every leftover and leaves the heap empty at its
    initial size, as a new graph's.
    """

    in_place: ClassVar[bool | None] = None  # _graphs_read_costs_in_place(), on first use
    offsets: ClassVar[np.ndarray | None | bool] = False  # _traceback_offsets(), on first use

    def __init__(self, capacity: tuple[int, int]) -> None:
        if SearchGraph.in_place is None:
            SearchGraph.in_place = _graphs_read_costs_in_place()
        if SearchGraph.offsets is False:
            SearchGraph.offsets = _traceback_offsets()
        self._traceback: np.ndarray | None = None  # of the last search
        self.step = np.full(capacity, np.inf, order="F")
        self.shape = capacity
        self._mcp: MCP_Geometric | None = None
        self._used = False
        self.contents = object()  # a new token at every refill: who kept a graph knows if it still holds their costs

    def refill(self, fill: Callable[[np.ndarray], np.ndarray], shape: tuple[int, int]) -> np.ndarray:
        """Empty the heap, then call `fill(step)` (writes the step costs of `shape` into the first
        rows and columns of `step` and inf everywhere else; returns what the graph's user keeps)."""
        if self._mcp is not None and self._used and SearchGraph.in_place:
            self.step.fill(np.inf)
            self._mcp.find_costs([(0, 0)])  # pops every entry left by the last search
        kept = fill(self.step)
        self.shape = shape
        self._used = False
        self.contents = object()
        if self._mcp is None or not SearchGraph.in_place:
            self._mcp = MCP_Geometric(self.step, fully_connected=True)
        return kept

    def find_costs(self, starts: list[tuple[int, int]], ends: list[tuple[int, int]] | None = None) -> np.ndarray:
        """MCP's cumulative costs from `starts` over the window (inf where the search did not
        finish), stopping when every one of `ends` is reached; a view the next search overwrites."""
        self._used = True
        cum, self._traceback = self._mcp.find_costs(starts, ends, find_all_ends=True)
        return cum[: self.shape[0], : self.shape[1]]

    def traceback(self, end: tuple[int, int]) -> list[tuple[int, int]]:
        """The cells of the cheapest path from the last search's starts to `end` (reached), start
        first: MCP's `traceback`, read from its traceback array in one compiled call."""
        if SearchGraph.offsets is None or self._traceback is None:
            return [tuple(rc) for rc in self._mcp.traceback(end)]
        cells = kernels.trace_back(self._traceback, int(end[0]), int(end[1]), SearchGraph.offsets)
        return [(r, c) for r, c in cells.tolist()]


@register_planner("mcp")
class MCPPlanner(Planner):
    """Minimum-cost path with `skimage.graph.MCP_Geometric` (8-connected Dijkstra), then shortcutting.

    The per-cell cost of travel is `1 + cost_weight * cost` per cell length; lethal cells are
    impassable (inf). `downsample` > 1 plans on blocks of downsample x downsample cells with the
    highest cost of each block (conservative: a block is lethal if any of its cells is); 2 turns the
    0.05 m office grid into 0.1 m and one plan from about 20 ms into about 5 ms. The shortcut pass
    always checks the full-resolution costmap.

    The search is bounded on large maps: it runs in a window, the box around start and goal grown
    by `window_margin_m` (8 m), and on the whole map only when the window holds no path (a detour
    wider than the margin) or covers half the map anyway. A path found in the window is the best
    one inside it; a shorter path leaving the window by more than the margin is not looked for.

    Building the MCP graph costs in proportion to the window's area, whatever the path's length
    (a follower plans about 1 m every second), so a smaller window is tried first: the box grown by
    `first_margin_m` (1 m). Its path is kept only when it is provably the best on the whole map: a
    path leaving the window first reaches a cell on the window's edge, along a way inside the window
    that costs at least that cell's cost from the start as the window's search found it (at least the
    path's own cost for a cell the search did not finish before reaching the goal); every step costs
    at least its length (cell costs are >= 1), so the rest, out of the window and back to the goal,
    costs at least its shortest length. A path found at most as dear as the cheapest such exit cannot
    be beaten. When the larger windows would search the whole map anyway, the rest is bounded more
    tightly by the cost from each edge cell to the goal on the static layer alone (scan obstacles
    only raise costs), searched once on the whole map from the goal and kept while the goal's
    cell stays (a leader replans to the same goal every second). Otherwise the window grows once
    to the margin that cost proves enough, then the 8 m window and the whole map as above. The
    certified path is the one the larger windows find too (up to ties between equally cheap cell
    paths).

    Only the window's costs are stamped with scan obstacles (`Costmap.cost_in`). The coarse grid
    and its MCP graph are kept for the last window and costs planned on (the same static layer and
    obstacle cells): costmaps are never modified. Searches on the kept graph give the same paths,
    as `find_costs` resets it. A new window or new costs refill one of the planner's few
    `SearchGraph`s (by size) instead of building a new graph: the same searches, without the cost
    of building one.
    """

    def __init__(
        self,
        *,
        downsample: int = 2,
        cost_weight: float = 8.0,
        start_snap_radius: float = 0.5,
        max_segment_m: float = 2.0,
        smooth: bool = True,
        window_margin_m: float | None = 8.0,
        first_margin_m: float | None = 1.0,
    ) -> None:
        """`start_snap_radius` in m: how far a start inside lethal space may be moved; `max_segment_m` in m.
        `window_margin_m`: search the box around start and goal grown by this many m first, and the
        whole map only when that box holds no path (None: always the whole map).
        `first_margin_m`: before that, the box grown by this many m, its path kept when provably
        the best on the whole map (None: skip)."""
        if downsample < 1:
            raise ValueError("downsample must be >= 1")
        self.downsample = int(downsample)
        self.cost_weight = float(cost_weight)
        self.start_snap_radius = float(start_snap_radius)
        self.max_segment_m = float(max_segment_m)
        self.smooth = smooth
        self.window_margin_m = window_margin_m
        self.first_margin_m = first_margin_m
        # (window, static cost, obstacle cells, coarse lethal, graph, its contents then) of the last search
        self._graph: tuple | None = None
        # (static cost, goal's coarse cell, static cost from every coarse cell to it) of the last goal
        self._field: tuple | None = None
        self._graphs: OrderedDict[tuple[int, int], SearchGraph] = OrderedDict()  # by capacity, recent last
        self._field_graph: SearchGraph | None = None  # the goal field's own: its costs outlive other searches

    def _search_graph(self, costmap: Costmap, window: tuple[int, int, int, int]) -> tuple[np.ndarray, SearchGraph]:
        """(coarse lethal mask, MCP graph over the coarse costs) of `window` (coarse rows r0:r1,
        cols c0:c1) of `costmap`, reused for the same window and costs."""
        kept = self._graph
        if (kept is None or kept[0] != window or kept[1] is not costmap.static_cost
                or not np.array_equal(kept[2], costmap.obstacle_cells) or kept[4].contents is not kept[5]):
            k = self.downsample
            r0, r1, c0, c1 = window
            lethal, graph = self._graph_over(costmap.cost_in(r0 * k, r1 * k, c0 * k, c1 * k), window)
            self._graph = kept = (window, costmap.static_cost, costmap.obstacle_cells, lethal, graph, graph.contents)
        return kept[3], kept[4]

    def _goal_field(self, costmap: Costmap, goal: tuple[int, int]) -> np.ndarray:
        """MCP cost (coarse cells) from every coarse cell of the whole map to the coarse cell
        `goal` on the static layer alone (inf where unreachable), kept for the last goal."""
        kept = self._field
        if kept is None or kept[0] is not costmap.static_cost or kept[1] != goal:
            whole = self._whole(costmap)
            if self._field_graph is None or self._field_graph.step.shape != (whole[1], whole[3]):
                self._field_graph = SearchGraph((whole[1], whole[3]))
            _, graph = self._graph_over(costmap.static_cost, whole, self._field_graph)
            field = graph.find_costs([goal])  # the same step costs both ways: the cost to the goal
            self._field = kept = (costmap.static_cost, goal, field)
        return kept[2]

    def _graph_over(self, cost: np.ndarray, window: tuple[int, int, int, int],
                    graph: SearchGraph | None = None) -> tuple[np.ndarray, SearchGraph]:
        """(coarse lethal mask, MCP graph) of the full-resolution costs `cost` (float32, clipped to
        the map) of `window`: each coarse cell holds the highest cost of its k x k block (blocks past
        the map's edge count as lethal), a step into it costs 1 + cost_weight * that (float32), inf
        when lethal. One compiled pass (nav/kernels.py, `coarse_step_costs`), into `graph` or one of
        the planner's graphs (the least recently used of its size, or a new one)."""
        k = self.downsample
        r0, r1, c0, c1 = window
        rows, cols = (r1 - r0, c1 - c0) if k > 1 else cost.shape
        if graph is None:
            graph = self._graph_for((rows, cols))
        cost32, weight = cost.astype(np.float32, copy=False), np.float32(self.cost_weight)
        lethal = graph.refill(lambda step: kernels.coarse_step_costs(cost32, k, rows, cols, weight, step),
                              (rows, cols))
        return lethal, graph

    def _graph_for(self, shape: tuple[int, int]) -> SearchGraph:
        """A graph of the planner's for a window of `shape`: of its size rounded up to GRAPH_BLOCK."""
        capacity = tuple(-(-n // GRAPH_BLOCK) * GRAPH_BLOCK for n in shape)
        graph = self._graphs.pop(capacity, None)
        if graph is None:
            graph = SearchGraph(capacity)
            if len(self._graphs) >= GRAPH_SLOTS:
                self._graphs.popitem(last=False)
        self._graphs[capacity] = graph
        return graph

    def _whole(self, costmap: Costmap) -> tuple[int, int, int, int]:
        """The window of the whole map's coarse cells."""
        k = self.downsample
        return (0, -(-costmap.shape[0] // k), 0, -(-costmap.shape[1] // k))

    def _box(self, costmap: Costmap, start: Pose2D, goal: Pose2D, margin: int) -> tuple[int, int, int, int] | None:
        """The coarse-cell window around start and goal grown by `margin` cells, clipped to the
        map; None when empty (both off the map)."""
        cell = costmap.resolution * self.downsample
        _, rows, _, cols = self._whole(costmap)
        ox, oy = costmap.grid.origin_x, costmap.grid.origin_y
        r = [math.floor((y - oy) / cell) for y in (start.y, goal.y)]
        c = [math.floor((x - ox) / cell) for x in (start.x, goal.x)]
        window = (max(0, min(r) - margin), min(rows, max(r) + margin + 1),
                  max(0, min(c) - margin), min(cols, max(c) + margin + 1))
        return None if window[0] >= window[1] or window[2] >= window[3] else window

    def _windows(self, costmap: Costmap, start: Pose2D, goal: Pose2D) -> list[tuple[int, int, int, int]]:
        """Coarse-cell windows to search, smallest first: the box around start and goal grown by
        `window_margin_m` (when that is well under the whole map), then the whole map."""
        whole = self._whole(costmap)
        if self.window_margin_m is None:
            return [whole]
        window = self._box(costmap, start, goal, int(math.ceil(self.window_margin_m / (costmap.resolution * self.downsample))))
        if window is None:
            return [whole]
        return [window, whole] if _area(window) < WHOLE_MAP_SHARE * _area(whole) else [whole]

    def plan(self, costmap: Costmap, start: Pose2D, goal: Pose2D, *, goal_tolerance: float = 0.0) -> Path | None:
        windows = self._windows(costmap, start, goal)
        path = self._plan_certified(costmap, start, goal, goal_tolerance, _area(windows[0]))
        if path is not None:
            return path
        for window in windows:
            found = self._plan_in(costmap, start, goal, goal_tolerance, window)
            if found is not None:
                return found[0]
        return None

    def _plan_certified(self, costmap: Costmap, start: Pose2D, goal: Pose2D, goal_tolerance: float,
                        area_limit: int) -> Path | None:
        """The best path on the whole map found in a window smaller than `area_limit` coarse cells
        (see the class docstring), or None when no such window proves its path the best."""
        if self.first_margin_m is None:
            return None
        cell = costmap.resolution * self.downsample
        # the snapping searches (nearest_free) must not be clipped by the window's edge
        reach = max(self.start_snap_radius, goal_tolerance, 1.5 * cell)
        margin = int(math.ceil(max(self.first_margin_m, reach) / cell)) + 2
        whole = self._whole(costmap)
        for _ in range(2):
            window = self._box(costmap, start, goal, margin)
            if window is None or _area(window) >= area_limit:
                return None
            found = self._plan_in(costmap, start, goal, goal_tolerance, window)
            if found is None:
                return None  # no path near: a detour, for the larger windows
            path, cost, cum, goal_rc = found
            if cost <= _exit_bound(cum, window, goal_rc, whole):
                return path
            if area_limit >= _area(whole):  # a whole-map search is what the larger windows would cost
                field = self._goal_field(costmap, (goal_rc[0] + window[0], goal_rc[1] + window[2]))
                if cost <= _exit_bound(cum, window, goal_rc, whole, field):
                    return path
            # a window whose every exit costs more than this path: margin >= cost / 2 cells
            margin = max(margin + 1, int(math.ceil(cost / 2.0)) + 2)
        return None

    def _plan_in(self, costmap: Costmap, start: Pose2D, goal: Pose2D, goal_tolerance: float,
                 window: tuple[int, int, int, int]) -> tuple[Path, float, np.ndarray, tuple[int, int]] | None:
        """(path, its MCP cost in coarse cells, the search's cumulative costs over the window (inf
        where it did not finish), the goal's cell in the window) of the best path within `window`, or None."""
        k = self.downsample
        cell = costmap.resolution * k
        r_off, c_off = window[0], window[2]
        ox, oy = costmap.grid.origin_x, costmap.grid.origin_y
        lethal, mcp = self._search_graph(costmap, window)

        # cells of the window; positions computed from whole-map cells, the same in every window
        def to_cell(x: float, y: float) -> tuple[int, int]:
            return (math.floor((y - oy) / cell) - r_off, math.floor((x - ox) / cell) - c_off)

        def centre(rc: tuple[int, int]) -> tuple[float, float]:
            return (ox + (rc[1] + c_off + 0.5) * cell, oy + (rc[0] + r_off + 0.5) * cell)

        def nearest_free(x: float, y: float, radius: float) -> tuple[int, int] | None:
            r0, c0 = to_cell(x, y)
            n = int(math.ceil(radius / cell)) + 1
            h, w = lethal.shape
            rlo, rhi, clo, chi = max(r0 - n, 0), min(r0 + n + 1, h), max(c0 - n, 0), min(c0 + n + 1, w)
            if rlo >= rhi or clo >= chi:
                return None
            rr, cc = np.nonzero(~lethal[rlo:rhi, clo:chi])
            if len(rr) == 0:
                return None
            rr, cc = rr + rlo, cc + clo
            d = np.hypot(ox + (cc + c_off + 0.5) * cell - x, oy + (rr + r_off + 0.5) * cell - y)
            i = int(np.argmin(d))
            return (int(rr[i]), int(cc[i])) if d[i] <= radius else None

        def free_cell(x: float, y: float) -> tuple[int, int] | None:
            rc = to_cell(x, y)
            h, w = lethal.shape
            if 0 <= rc[0] < h and 0 <= rc[1] < w and not lethal[rc]:
                return rc
            return None

        start_rc = free_cell(start.x, start.y) or nearest_free(start.x, start.y, self.start_snap_radius)
        if start_rc is None:
            return None
        goal_free = costmap.is_free(goal.x, goal.y)
        if goal_free:
            # the goal is free at full resolution; its block may not be (conservative downsampling)
            goal_rc = free_cell(goal.x, goal.y) or nearest_free(goal.x, goal.y, 1.5 * cell)
        else:
            goal_rc = nearest_free(goal.x, goal.y, goal_tolerance) if goal_tolerance > 0.0 else None
        if goal_rc is None:
            return None

        cells = [start_rc]
        cost = 0.0
        cum = np.full(lethal.shape, math.inf)
        if goal_rc != start_rc:
            cum = mcp.find_costs([start_rc], [goal_rc])
            cost = float(cum[goal_rc])
            if not math.isfinite(cost):
                return None
            cells = mcp.traceback(goal_rc)
        pts = [centre(rc) for rc in cells]
        start_xy = (start.x, start.y)
        start_free = costmap.is_free(start.x, start.y)
        if start_free and to_cell(start.x, start.y) == start_rc:
            pts[0] = start_xy
        else:
            pts.insert(0, start_xy)
        if goal_free:
            if len(pts) > 1 and to_cell(goal.x, goal.y) == goal_rc:
                pts[-1] = (goal.x, goal.y)
            else:
                pts.append((goal.x, goal.y))
        points = np.asarray(pts, dtype=float)
        if self.smooth:
            points = shortcut(costmap, points, max_segment_m=self.max_segment_m)
        return Path.from_points(points), cost, cum, goal_rc


def _area(window: tuple[int, int, int, int]) -> int:
    return (window[1] - window[0]) * (window[3] - window[2])


def _exit_bound(cum: np.ndarray, window: tuple[int, int, int, int], goal: tuple[int, int],
                whole: tuple[int, int, int, int], field: np.ndarray | None = None) -> float:
    """Least MCP cost (coarse cells) of a path to the cell `goal` (in the window) that visits a
    coarse cell outside `window`, given the search's cumulative costs `cum` over the window: over
    the cells on the window's sides that border a cell of the `whole` map, their cost plus a
    lower bound on the rest: the shortest way from them to a line of cells just outside that side
    and on to the goal (the mirror image of the goal), or, given `field` (the cost from every
    coarse cell of the whole map to the goal on the static layer), their field. inf when no side
    borders a cell of the map."""
    r0, r1, c0, c1 = window
    sides = (r0 > whole[0], r1 < whole[1], c0 > whole[2], c1 < whole[3])
    # one compiled pass over the four sides (nav/kernels.py, exit_bound); tests/oracles/nav.py has the numpy
    return kernels.exit_bound(cum, r0, r1, c0, c1, int(goal[0]), int(goal[1]), *sides,
                              _NO_FIELD if field is None else field, field is not None)


_NO_FIELD = np.zeros((0, 0))


@register_planner("straight")
class StraightLinePlanner(Planner):
    """The straight segment from start to goal when it is not lethal, else None (for tests and open spaces)."""

    def plan(self, costmap: Costmap, start: Pose2D, goal: Pose2D, *, goal_tolerance: float = 0.0) -> Path | None:
        if not costmap.is_free(goal.x, goal.y):
            return None
        a, b = np.array([start.x, start.y]), np.array([goal.x, goal.y])
        n = max(2, int(math.ceil(float(np.hypot(*(b - a))) / (0.5 * costmap.resolution))) + 1)
        lethal = costmap.costs_at(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)) >= LETHAL
        # a start inside lethal space may drive out, but once free the segment must stay free
        first_free = int(np.argmin(lethal))
        if lethal[first_free:].any():
            return None
        return Path.from_points(np.stack([a, b]))
