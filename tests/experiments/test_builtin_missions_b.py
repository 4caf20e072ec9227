"""The built-in scenarios relay, disconnect, convoy, show-scan and land-on-top, written as mission files
in missions/, give the built-in's verdict and every metric it reports (same names, same values) on
the same seed and loss: the mission issues the same commands at the same ticks (issue 18 item 1).

`make test` runs seed 0 without loss (the convoy with the smallest team it takes, 2, cut from
missions/convoy.yaml); `make test-slow` runs seeds 0-2 with and without 0.2 extra loss, the convoy
with its default team of 6 as the file has it.
"""

import re
from pathlib import Path

import pytest
import yaml

from rescuemesh.experiments.mission import MissionScenario
from rescuemesh.experiments.mission_spec import Drive, MissionError, OnGivenUp, OnLanded, load_mission
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.scenarios import ScenarioOptions
from rescuemesh.scenarios.convoy import ConvoyScenario
from rescuemesh.scenarios.runner import run_scenario

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
SCENARIOS = ("relay", "disconnect", "convoy", "show-scan", "land-on-top", "priority")


def run_builtin(name: str, seed: int, loss: float, **options):
    return run_scenario(name, ScenarioOptions(seed=seed, loss=loss, **options)).result


def run_mission(path: Path, seed: int, loss: float):
    mission = load_mission(path)
    options = MissionScenario.options_for(mission, seed, loss=loss)
    scenario = MissionScenario(mission, options, load_map(mission.map_path or office_map_path()))
    return run_scenario(None, options, scenario=scenario).result


def assert_same(builtin: dict, mission: dict) -> None:
    """The mission's verdict is the built-in's, every metric the built-in reports is the mission's
    (the mission adds its steps' STEP_started_s, STEP_finished_s and STEP_result), and the run ended
    on the same tick with the same protocol and network counters."""
    failed = [c["check"] for c in mission["criteria"] if not c["ok"]]
    assert mission["success"] == builtin["success"], (builtin["criteria"], failed)
    differ = {name: (value, mission["metrics"].get(name, "missing"))
              for name, value in builtin["metrics"].items() if mission["metrics"].get(name, "missing") != value}
    assert not differ, differ
    # the same commands at the same ticks: the run ends on the same tick, with the same traffic
    assert mission["sim_time_s"] == builtin["sim_time_s"]
    assert mission["protocol"] == builtin["protocol"] and mission["network"] == builtin["network"]


class _Loader(yaml.SafeLoader):
    """YAML 1.1 without `on`/`off`/`yes`/`no` as booleans (a step's `on:` stays the word, as the
    mission reader has it)."""


_Loader.yaml_implicit_resolvers = {
    first: [(tag, regexp) for tag, regexp in resolvers if tag != "tag:yaml.org,2002:bool"]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}
_Loader.add_implicit_resolver("tag:yaml.org,2002:bool", re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"),
                              list("tTfF"))


def convoy_of(n: int, tmp_path: Path) -> Path:
    """missions/convoy.yaml cut to the first `n` robots, with the starts the built-in gives a team of
    `n` (it places the team behind robot_1 by its size)."""
    doc = yaml.load((MISSIONS / "convoy.yaml").read_text(), Loader=_Loader)
    team = [f"robot_{k}" for k in range(1, n + 1)]
    links = {f"link_{k}" for k in range(1, n)}
    last = f"link_{n - 1}"
    starts = ConvoyScenario(ScenarioOptions(robots=n), load_map(office_map_path())).starts()
    doc["team"] = {name: {"start": [starts[name].x, starts[name].y, starts[name].yaw]} for name in team}
    doc["stop_when"] = [e for e in doc["stop_when"] if e["step"] in links]
    steps = [s for s in doc["steps"] if s["name"] in links or s["name"] in ("route", "settle")]
    for step in steps:
        if step["name"] == "route":
            step["on"]["step"] = last
        if step["name"] == "settle":
            step["settle"] = team
    doc["steps"] = steps
    doc["criteria"] = [c for c in doc["criteria"] if c.get("step", "route") in links | {"route"}
                       and c.get("robot", "robot_1") in team]
    for metric in doc["metrics"]:
        for spec in metric.values():
            if isinstance(spec, dict) and "robots" in spec:
                spec["robots"] = team
            if isinstance(spec, dict) and spec.get("from", "").startswith("link_"):
                spec["from"] = last
        if metric.get("finished", "").startswith("link_"):
            metric["finished"] = last
    path = tmp_path / f"convoy-{n}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.mark.parametrize("name", [s for s in SCENARIOS if s != "convoy"])
def test_the_mission_file_gives_the_builtins_verdict_and_metrics(name):
    assert_same(run_builtin(name, 0, 0.0), run_mission(MISSIONS / f"{name}.yaml", 0, 0.0))


def test_the_convoy_mission_cut_to_two_robots_gives_the_builtins_verdict_and_metrics(tmp_path):
    assert_same(run_builtin("convoy", 0, 0.0, robots=2), run_mission(convoy_of(2, tmp_path), 0, 0.0))


@pytest.mark.slow
@pytest.mark.parametrize("loss", [0.0, 0.2])
@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", SCENARIOS)
def test_the_mission_file_gives_the_builtins_verdict_and_metrics_on_seeds_0_to_2(name, seed, loss):
    assert_same(run_builtin(name, seed, loss), run_mission(MISSIONS / f"{name}.yaml", seed, loss))


BASE = """\
mission: t
team:
  robot_1: {}
  robot_2: {}
steps:
  - name: go
    at: 0.5
    command: {from: robot_1, to: robot_2, type: show_scan, spot: [3.0, 4.6]}
  - name: leg
    on: {step: go}
    drive: {robot: robot_1, by: [1.0, 0.0]}
criteria:
  - {step: go, result: done}
metrics:
  - {name: gap, gaps: {robots: [robot_1, robot_2]}}
"""


@pytest.mark.parametrize("change, line, words", [
    (("    drive: {robot: robot_1, by", "    attempts: 2\n    drive: {robot: robot_1, by"), 11,
     "`attempts` applies to a command step"),
    (("    on: {step: go}\n", "    on: {step: go}\n    data_wait: 3\n"), 11, "`data_wait` applies to a show_scan"),
    (("by: [1.0, 0.0]}", "by: [1.0, 0.0], to: [1.0, 1.0]}"), 11, "takes one of `to`, `route` or `by`"),
    (("on: {step: go}", "on: {step: go, given_up: 3}"), 10, "given_up must be true or false"),
    (("on: {step: go}", "on: {robot: robot_1, moving: 0}"), 10, "moving must be more than 0"),
    (("on: {step: go}", "on: {robot: robot_1, knows: robot_2, within: 2}"), 10, "`knows` takes `robot`"),
    (("{step: go, result: done}", "{metric: gap, min: 1, relative_to: speed}"), 13, "unknown metric 'speed'"),
    (("{step: go, result: done}", "{metric: gap, equals: 1, max: 2}"), 13, "takes `equals` alone"),
    (("gaps: {robots: [robot_1, robot_2]}", "gaps: {robots: [robot_1]}"), 15, "a chain has at least two robots"),
    (("gaps: {robots: [robot_1, robot_2]}", "gaps: {robots: [robot_1, robot_2], stat: median}"), 15,
     "stat must be one of min, mean, max, all"),
    (("{name: gap, gaps", "{name: gap, data: leg, gaps"), 15, "one kind per metric"),
    (("{name: gap, gaps: {robots: [robot_1, robot_2]}}", "{name: gap, started: nowhere}"), 15,
     "unknown step 'nowhere'"),
    (("metrics:\n", "stop_when:\n  - {step: gone, given_up: true}\nmetrics:\n"), 15, "step 'gone'"),
    (("mission: t\n", "mission: t\nend_after: -1\n"), 2, "end_after must be at least 0"),
])
def test_a_bad_addition_names_the_file_the_line_and_what_was_expected(tmp_path, change, line, words):
    path = tmp_path / "m.yaml"
    assert change[0] in BASE
    path.write_text(BASE.replace(*change))
    with pytest.raises(MissionError) as caught:
        load_mission(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: "), message
    assert words in message and "\n" not in message


def test_the_additions_read_into_typed_values(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text(BASE.replace("    on: {step: go}\n", "    on: {robot: robot_2, landed: true}\n    at_latest: 9\n")
                    .replace("metrics:\n", "end_after: 0\nstop_when:\n  - {step: go, given_up: true}\nmetrics:\n"))
    m = load_mission(path)
    leg = m.steps[1]
    assert leg.trigger == OnLanded("robot_2") and leg.at_latest == 9.0
    assert leg.action == Drive("robot_1", None, by=(1.0, 0.0))
    assert m.end_after_s == 0.0 and m.stop_when == (OnGivenUp("go"),)
    assert m.metrics[0].kind == "gaps" and m.metrics[0].arg == (("robot_1", "robot_2"), "all")
