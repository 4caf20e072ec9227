"""The bench's goal budget: what a real-time goal leaves for everything but the world, read from a
run's result.json (a behaviour test: the figures come from the result, nothing here times anything)."""

import pytest

from rescuemesh.checks.bench import goal_budget
from rescuemesh.scenarios import ScenarioOptions
from rescuemesh.scenarios.runner import run_scenario


def _result(sim_s: float, wall_s: float, world_s: float | None) -> dict:
    parts = {} if world_s is None else {"world": world_s, "medium": 0.1, "robots": 0.1}
    return {"sim_time_s": sim_s, "wall_time_s": wall_s, "runtime": {"wall_s_by_part": parts}}


def test_the_budget_is_the_goals_wall_time_less_the_worlds():
    budget = goal_budget(_result(sim_s=20.0, wall_s=0.5, world_s=0.15), goal_rtf=100.0)
    assert budget["world_alone_real_time_factor"] == pytest.approx(133.3, abs=0.05)
    assert budget["rest_allowed_s"] == pytest.approx(0.2 - 0.15)
    assert budget["rest_took_s"] == pytest.approx(0.5 - 0.15)


def test_a_goal_past_what_the_world_allows_leaves_nothing():
    budget = goal_budget(_result(sim_s=10.0, wall_s=2.0, world_s=0.5), goal_rtf=40.0)
    assert budget["world_alone_real_time_factor"] == 20.0
    assert budget["rest_allowed_s"] < 0.0


def test_a_run_without_parts_has_no_budget():
    assert goal_budget(_result(sim_s=10.0, wall_s=2.0, world_s=None), goal_rtf=10.0) is None
    assert goal_budget({"sim_time_s": 5.0, "wall_time_s": 1.0}, goal_rtf=10.0) is None


def test_a_real_runs_result_gives_a_budget_within_its_wall_time():
    result = run_scenario("follow", ScenarioOptions(seed=0, time_limit_s=3.0)).result
    budget = goal_budget(result, goal_rtf=100.0)
    assert 0.0 < budget["world_wall_s"] < result["wall_time_s"]
    assert budget["rest_took_s"] == pytest.approx(result["wall_time_s"] - budget["world_wall_s"], abs=1e-3)
