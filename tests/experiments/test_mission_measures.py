"""The mission vocabulary's moments and timed metrics, step events, `end` steps and `end_after`
(experiments/mission_measures.py, mission_spec.py): read into typed values, every error naming the
file and the line; and a mission's Stop behaves as a user's."""

from pathlib import Path

import pytest

from rescuemesh.experiments.mission import MissionScenario
from rescuemesh.experiments.mission_measures import Halted, Moment, Orbit, OrbitMeasure, When
from rescuemesh.experiments.mission_spec import EndMission, MissionError, OnSettled, OnSpeed, OnStep, load_mission
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.protocol import ResultCode
from rescuemesh.robot import robot_address
from rescuemesh.scenarios.runner import run_scenario

BASE = """\
mission: t
end_after: 0
team:
  robot_1: {}
  robot_2: {}
steps:
  - name: go
    at: 0.5
    command: {from: robot_1, to: robot_2, type: goto, pose: [3.0, 4.6, 0.0]}
  - name: quit
    on: {step: go, result: [failed, denied], at_receiver: true}
    end: true
  - name: moving
    on: {robot: robot_2, speed_at_least: 0.2}
    not_before: 1.0
    wait: 0
criteria:
  - {step: go, result: done, at_receiver: true}
metrics:
  - {name: t_done, time_of: {step: go, result: done}}
  - {name: halt, halted: robot_2, below: 0.02, from: {metric: t_done}}
  - {name: lap, orbit: robot_2, around: robot_1, radius: 1.5, from: {step: go, started: true}, measure: angle}
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(text)
    return path


def test_the_new_vocabulary_reads_into_typed_values(tmp_path):
    m = load_mission(write(tmp_path, BASE))
    assert m.end_after_s == 0.0
    quit_ = m.steps[1]
    assert isinstance(quit_.action, EndMission)
    assert quit_.trigger == OnStep("go", frozenset({ResultCode.FAILED, ResultCode.DENIED}), at_receiver=True)
    assert m.steps[2].trigger == OnSpeed("robot_2", 0.2) and m.steps[2].not_before_s == 1.0
    assert m.criteria[0].at_receiver
    assert m.metrics[1] == Halted("halt", "robot_2", 0.02, When(Moment.METRIC, "t_done"))
    assert m.metrics[2] == Orbit("lap", "robot_2", "robot_1", 1.5, When(Moment.STARTED, "go"), None,
                                 OrbitMeasure.ANGLE)
    settled = load_mission(write(tmp_path, BASE.replace("speed_at_least: 0.2", "settled: true")))
    assert settled.steps[2].trigger == OnSettled("robot_2")


@pytest.mark.parametrize("change, line, words", [
    (("end_after: 0", "end_after: -1"), 2, "end_after must be at least 0"),
    (("    end: true\n", "    end: false\n"), 12, "an end step is `end: true`"),
    (("result: [failed, denied]", "result: [failed, nope]"), 11, "result must be one of accepted"),
    (("{step: go, result: [failed, denied], at_receiver: true}", "{step: go, at_receiver: true}"), 11,
     "at_receiver goes with `result`"),
    (("{step: go, result: [failed, denied], at_receiver: true}", "{step: go, started: true, given_up: true}"), 11,
     "given_up is `{step: S, given_up: true}`"),
    (("{step: go, result: [failed, denied], at_receiver: true}", "{step: go, started: true, result: done}"), 11,
     "stands alone beside `step`"),
    (("speed_at_least: 0.2}", "speed_at_least: 0.2, within: 1}"), 14, "stand alone beside `robot`"),
    (("not_before: 1.0", "not_before: soon"), 15, "not_before must be a finite number"),
    (("from: {metric: t_done}", "from: {metric: lap}"), 21, "'lap' is not a metric defined above this one"),
    (("from: {metric: t_done}", "from: {step: gone}"), 21, "unknown step 'gone'"),
    (("below: 0.02, ", ""), 21, "halted needs 'below'"),
    (("{name: t_done, time_of:", "{name: t_done, round: 2, time_of:"), 20, "'round' does not apply to time_of"),
    (("measure: angle", "measure: wobble"), 22, "measure must be one of rms_error, angle, time"),
    (("around: robot_1", "around: robot_9"), 22, "unknown robot 'robot_9'"),
    (("{name: halt, halted: robot_2,", "{name: halt, distance: [robot_1, robot_2], halted: robot_2,"), 21,
     "one measure per metric"),
    (("{name: t_done, time_of: {step: go, result: done}}", "{name: t_done, path_length: robot_1, from: {step: go}}"),
     20, "'from' does not apply to distance, time_to or path_length"),
    (("{name: t_done, time_of: {step: go, result: done}}", "{name: t_done, brain_event: {robot: robot_2, kind: x}, "
      "from: {step: go}}"), 20, "brain_event.kind must be one of"),
])
def test_a_bad_measure_or_step_event_names_the_file_the_line_and_what_was_expected(tmp_path, change, line, words):
    text = BASE.replace(*change)
    assert text != BASE
    path = write(tmp_path, text)
    with pytest.raises(MissionError) as caught:
        load_mission(path)
    message = str(caught.value)
    assert message.startswith(f"{path}:{line}: "), message
    assert words in message and "\n" not in message


def test_a_missions_stop_ends_the_pose_stream_to_the_stopped_robot_as_it_is_sent():
    # this used to send a bare Stop: robot_1 kept streaming its pose to robot_2 until the Follow's
    # CANCELLED came back (a user's Stop, brain.command_stop, ends the stream at once)
    path = Path(__file__).resolve().parents[2] / "missions" / "stop.yaml"
    mission = load_mission(path)
    seen = {}

    class Watching(MissionScenario):
        def tick(self, rt):
            streaming_before = set(rt.brain("robot_1").streams)
            super().tick(rt)
            if self.state("stop").started_s == rt.time and "at_stop" not in seen:
                seen["before"], seen["at_stop"] = streaming_before, set(rt.brain("robot_1").streams)

    options = MissionScenario.options_for(mission, 0)
    run_scenario(None, options, scenario=Watching(mission, options, load_map(office_map_path())))
    robot_2 = robot_address("robot_2")
    assert robot_2 in seen["before"] and robot_2 not in seen["at_stop"]
