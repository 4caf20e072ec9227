"""Mission files: validated with file:line errors, run by the scenario runner, triggers and
criteria judged on values (results, positions, reachability), never on log text."""

from pathlib import Path

import pytest

from rescuemesh.experiments.mission import MissionScenario
from rescuemesh.experiments.mission_spec import (At, CommandType, MissionError, OnLink, OnNear, OnStep, SendCommand,
                                                 load_mission)
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.protocol import ResultCode
from rescuemesh.scenarios import SCENARIOS, ScenarioError
from rescuemesh.scenarios.runner import run_scenario

MISSIONS = sorted((Path(__file__).resolve().parents[2] / "missions").glob("*.yaml"))
#: Missions that are a built-in scenario written as a file: test_builtin_missions_*.py runs each against
#: its built-in (same verdict and metrics), so they are not run a second time here.
NEW_MISSIONS = [p for p in MISSIONS if load_mission(p).name not in SCENARIOS]


def run(path: Path, seed: int = 0, **overrides):
    mission = load_mission(path)
    options = MissionScenario.options_for(mission, seed, **overrides)
    scenario = MissionScenario(mission, options, load_map(mission.map_path or office_map_path()))
    return run_scenario(None, options, scenario=scenario)


@pytest.mark.parametrize("path", NEW_MISSIONS, ids=lambda p: p.stem)
def test_every_shipped_mission_runs_and_succeeds(path):
    outcome = run(path)
    failed = [text for text, ok in outcome.verdict.criteria if not ok]
    assert outcome.verdict.success, failed
    assert outcome.result["scenario"] == load_mission(path).name


def test_the_goto_out_of_reach_mission_learns_done_only_after_the_commander_returns():
    outcome = run(next(p for p in MISSIONS if p.stem == "goto-out-of-reach"))
    m = outcome.result["metrics"]
    # robot_1 set off back toward robot_2 after robot_2 had arrived, and learned DONE on the way
    assert m["come_back_started_s"] < 0.5 + m["goto_done_at_commander_s"] < m["come_back_finished_s"]


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    return path


BASE = """\
mission: t
settings: {radio: disc}
team:
  robot_1: {}
  robot_2: {}
steps:
  - name: go
    at: 0.5
    command: {from: robot_1, to: robot_2, type: goto, pose: [3.0, 4.6, 0.0]}
criteria:
  - {step: go, result: done}
"""


def test_a_mission_reads_into_typed_values(tmp_path):
    m = load_mission(write(tmp_path, BASE.replace("  robot_2: {}\n", "  robot_2: {}\n  robot_3: {rank: operator}\n")))
    (step,) = m.steps
    assert step.trigger == At(0.5)
    assert isinstance(step.action, SendCommand) and step.action.command.type is CommandType.GOTO
    assert step.action.command.pose == (3.0, 4.6, 0.0)
    assert m.team["robot_3"].rank.name == "OPERATOR" and m.settings.radio == "disc"


@pytest.mark.parametrize("change, line, words", [
    (("mission: t\n", "mission: t\ncolour: red\n"), 2, "unknown key 'colour'"),
    (("to: robot_2,", "to: robot_9,"), 9, "unknown robot 'robot_9'"),
    (("pose: [3.0, 4.6, 0.0]", "radius: 2"), 9, "goto needs 'pose'"),
    (("type: goto,", "type: teleport,"), 9, "must be one of follow, stop"),
    (("    at: 0.5\n", ""), 7, "exactly one of `at`"),
    (("    at: 0.5\n", "    at: 0.5\n    on: {step: go}\n"), 7, "exactly one of `at`"),
    (("result: done}", "result: finished}"), 11, "result must be one of accepted"),
    (("{step: go, result: done}", "{step: gone, result: done}"), 11, "unknown step 'gone'"),
    (("{step: go, result: done}", "{metric: speed, max: 1}"), 11, "unknown metric 'speed'"),
    (("  robot_2: {}\n", ""), 4, "at least two robots"),
    (("  robot_2: {}\n", "  robot_2: {start: [1, 2, 3, 4]}\n"), 5, "start must be [X, Y] or [X, Y, YAW]"),
    (("settings: {radio: disc}", "settings: {loss: 1.5}"), 2, "settings.loss must be below 1"),
])
def test_a_bad_mission_names_the_file_the_line_and_what_was_expected(tmp_path, change, line, words):
    path = write(tmp_path, BASE.replace(*change))
    with pytest.raises(MissionError) as caught:
        load_mission(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: "), message
    assert words in message and "\n" not in message


def test_a_region_or_start_the_map_does_not_have_is_refused_before_the_run(tmp_path):
    text = BASE + "  - {robot: robot_2, ends_in: kitchen}\n"
    mission = load_mission(write(tmp_path, text))
    with pytest.raises(ScenarioError, match="no such region"):
        MissionScenario(mission, MissionScenario.options_for(mission), load_map(office_map_path()))
    mission = load_mission(write(tmp_path, BASE.replace("  robot_2: {}\n", "  robot_2: {}\n  robot_7: {}\n")))
    scenario = MissionScenario(mission, MissionScenario.options_for(mission), load_map(office_map_path()))
    with pytest.raises(ScenarioError, match="robot_7 has no start"):
        scenario.starts()


def test_triggers_on_link_loss_results_and_distance_fire_in_order(tmp_path):
    text = """\
mission: triggers
time_limit: 40
settings: {radio: disc}
team:
  robot_1: {}
  robot_2: {}
steps:
  - name: cut
    at: 1.0
    outage: {robot: robot_1, seconds: 6}
  - name: noticed
    on: {robot: robot_2, loses: robot_1}
    wait: 0.1
  - name: back
    on: {robot: robot_2, hears: robot_1}
    after_step: noticed
    wait: 0.1
  - name: go
    on: {step: back}
    command: {from: robot_1, to: robot_2, type: goto, pose: [3.0, 4.6, 0.0]}
  - name: after_accept
    on: {step: go, result: accepted}
    wait: 0.1
  - name: near
    on: {robot: robot_2, within: 0.5, of: [3.0, 4.6]}
    wait: 0.1
criteria:
  - {step: go, result: done}
"""
    mission = load_mission(write(tmp_path, text))
    assert isinstance(mission.steps[1].trigger, OnLink) and mission.steps[1].trigger.lost
    assert mission.steps[4].trigger == OnStep("go", ResultCode.ACCEPTED)
    assert isinstance(mission.steps[5].trigger, OnNear)
    outcome = run(mission.path)
    m = outcome.result["metrics"]
    assert outcome.verdict.success
    # lost 3-4.5 s into the silence (missed heartbeats), heard again once it ended at 7 s
    assert 4.0 <= m["noticed_started_s"] <= 5.6
    assert 7.0 <= m["back_started_s"] <= 8.5
    assert m["back_started_s"] <= m["go_started_s"] < m["after_accept_started_s"] < m["near_started_s"]
    assert m["go_result"] == "DONE"


def test_the_run_command_takes_a_mission_and_refuses_flags_that_belong_in_it(tmp_path):
    import subprocess
    import sys

    path = write(tmp_path, BASE)
    result = subprocess.run([sys.executable, "-m", "rescuemesh", "run", str(path), "--robots", "4", "--quiet",
                             "--out", str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and "--robots: set this in the mission file" in result.stderr
    bad = write(tmp_path, BASE.replace("type: goto,", "type: teleport,"))
    result = subprocess.run([sys.executable, "-m", "rescuemesh", "check", str(bad)], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 2 and f"{bad}:9:" in result.stderr and "Traceback" not in result.stderr


def test_the_python_api_runs_a_mission_and_a_scenario():
    import rescuemesh
    from rescuemesh import Mission, run

    mission = Mission.load(next(p for p in MISSIONS if p.stem == "forwarded-show-scan"))
    result = run(mission, seed=1, loss=0.1)
    assert result.success and result.result["seed"] == 1 and result.result["settings"]["loss"] == 0.1
    assert result.metrics["scan_result"] == "DONE" and all(result.criteria.values())
    stop = run("stop", seed=0, time_limit_s=3.0)
    assert stop.result["scenario"] == "stop" and stop.result["sim_time_s"] == pytest.approx(3.0, abs=0.1)
    assert set(rescuemesh.__all__) == {"Mission", "run", "sweep"}
    with pytest.raises(ValueError, match="not robots"):
        run(mission, robots=4)
