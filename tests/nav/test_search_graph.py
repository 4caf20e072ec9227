"""The planner's reused search graphs (nav/planner.py, SearchGraph) search as new MCP_Geometric graphs would."""

import numpy as np
import pytest
from skimage.graph import MCP_Geometric

from rescuemesh.nav.planner import SearchGraph


def _fill(costs):
    def write(step):
        step[:, :] = np.inf
        step[: costs.shape[0], : costs.shape[1]] = costs
        return None
    return write


def _tied_costs(rng, shape):
    """Step costs of 1 and 2 with impassable cells: many paths of equal cost, ties for the heap to break."""
    costs = rng.choice([1.0, 1.0, 1.0, 2.0], size=shape)
    costs[rng.random(shape) < 0.15] = np.inf
    return costs


@pytest.mark.parametrize("in_place, own_traceback", [(True, True), (False, True), (True, False)])
def test_a_refilled_graph_finds_the_costs_and_paths_a_new_graph_finds(in_place, own_traceback, monkeypatch):
    # MCP's find_costs resets costs but not its heap's entry count: a search that stopped at its
    # goal leaves entries behind, which a later search that runs out of cells (no goal, or none
    # reachable) pops, writing inf over the cumulative costs of the cells they name
    assert SearchGraph((2, 2)) and SearchGraph.in_place  # this scikit-image searches the array in place
    monkeypatch.setattr(SearchGraph, "in_place", in_place)  # False: a new MCP at every refill
    assert SearchGraph.offsets is not None  # the path read back in a compiled call: this scikit-image's steps
    if not own_traceback:
        monkeypatch.setattr(SearchGraph, "offsets", None)  # MCP's own traceback
    rng = np.random.default_rng(5)
    graph = SearchGraph((48, 48))
    exhaustive = 0
    for trial in range(150):
        shape = (int(rng.integers(3, 49)), int(rng.integers(3, 49)))
        costs = _tied_costs(rng, shape)
        graph.refill(_fill(costs), shape)
        new = MCP_Geometric(costs, fully_connected=True)
        for search in range(int(rng.integers(1, 4))):
            free = np.argwhere(np.isfinite(costs))
            start, end = (tuple(int(v) for v in free[i]) for i in rng.integers(0, len(free), 2))
            ends = None if search == 0 and trial % 2 else [end]
            got = graph.find_costs([start], ends)
            want, _ = new.find_costs([start], ends, find_all_ends=True)
            assert got.shape == shape
            np.testing.assert_array_equal(got, want, err_msg=str(trial))
            exhaustive += ends is None or not np.isfinite(want[end])
            if np.isfinite(want[end]):
                assert graph.traceback(end) == new.traceback(end), trial
    assert exhaustive > 50


def test_the_search_never_reaches_the_cells_beyond_the_window():
    graph = SearchGraph((32, 32))
    costs = np.ones((5, 7))
    graph.refill(_fill(costs), (5, 7))
    cum = graph.find_costs([(0, 0)])
    assert cum.shape == (5, 7) and np.isfinite(cum).all()
    assert np.isinf(graph.step[5:]).all() and np.isinf(graph.step[:, 7:]).all()


def test_a_planner_reusing_its_graphs_plans_what_a_new_planner_plans(room_costmap):
    # one planner for 150 plans (its graphs refilled for windows of many sizes, scan obstacles
    # changing) against a new planner for each: the same points, and it kept at most GRAPH_SLOTS graphs
    import math

    from rescuemesh.geometry import Pose2D
    from rescuemesh.nav.planner import GRAPH_SLOTS, MCPPlanner

    rng = np.random.default_rng(8)
    free = np.argwhere(~room_costmap.lethal)
    kept = MCPPlanner()
    found = 0
    for trial in range(150):
        r, c = free[rng.integers(len(free))]
        sx, sy = room_costmap.cell_to_world(r, c)
        d, a = rng.choice([0.3, 1.0, 2.5, 5.0]), rng.uniform(0.0, 2.0 * math.pi)
        start, goal = Pose2D(sx, sy), Pose2D(sx + d * math.cos(a), sy + d * math.sin(a))
        blobs = rng.uniform((0.5, 0.5), (5.5, 3.5), size=(int(rng.integers(0, 3)), 2))
        points = (blobs[:, None, :] + rng.normal(0.0, 0.1, (len(blobs), 15, 2))).reshape(-1, 2)
        cm = room_costmap.with_obstacles(points, float(trial))
        got = kept.plan(cm, start, goal, goal_tolerance=0.3)
        want = MCPPlanner().plan(room_costmap.with_obstacles(points, float(trial)), start, goal, goal_tolerance=0.3)
        assert (got is None) == (want is None), trial
        if got is not None:
            found += 1
            np.testing.assert_array_equal(got.points, want.points, err_msg=str(trial))
    assert found > 60 and len(kept._graphs) <= GRAPH_SLOTS
