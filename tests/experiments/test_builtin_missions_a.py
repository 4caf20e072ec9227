"""The built-in scenarios follow, stop, move-around, goto and return, shipped as mission files in
missions/, give the built-in's verdict and every one of its metrics (same names, same values) on the
same seed, with and without extra loss: the mission issues the same commands at the same control
steps, so the run itself is the same (its end time, protocol and network counters, robot logs)."""

from pathlib import Path

import pytest

from rescuemesh import Mission, run

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
SCENARIOS = ("follow", "stop", "move-around", "goto", "return")
#: What a mission's result.json adds for each step, beside the metrics it names.
STEP_BOOKKEEPING = ("_started_s", "_finished_s", "_result")


def assert_same_run(name: str, seed: int, loss: float | None):
    builtin = run(name, seed=seed, loss=loss)
    mission = run(Mission.load(MISSIONS / f"{name}.yaml"), seed=seed, loss=loss)
    assert mission.success == builtin.success, (builtin.criteria, mission.criteria)
    # every metric of the built-in, exactly: both round the same way (a float's digits included)
    assert {k: mission.metrics.get(k, "missing") for k in builtin.metrics} == builtin.metrics
    extra = set(mission.metrics) - set(builtin.metrics)
    assert all(k.endswith(STEP_BOOKKEEPING) for k in extra), extra
    for part in ("sim_time_s", "protocol", "network", "events"):
        assert mission.result[part] == builtin.result[part], part
    return builtin


@pytest.mark.parametrize("name", SCENARIOS)
def test_the_mission_file_reproduces_the_builtin_scenario(name):
    builtin = assert_same_run(name, seed=0, loss=None)
    assert builtin.success  # a comparison of two failed runs would show little


@pytest.mark.slow
@pytest.mark.parametrize("loss", [None, 0.2], ids=["no-loss", "loss-0.2"])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", SCENARIOS)
def test_the_mission_file_reproduces_the_builtin_scenario_on_seeds_0_to_2(name, seed, loss):
    assert_same_run(name, seed, loss)
