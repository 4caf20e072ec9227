"""Start poses are checked over the robot's footprint, not only at its centre."""

import numpy as np
import pytest
from PIL import Image

from rescuemesh.cli import main
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import load_map
from rescuemesh.maps.model import office_map_path
from rescuemesh.scenarios import SCENARIOS, ScenarioError, ScenarioOptions, get_scenario
from rescuemesh.scenarios.base import START_CLEARANCE_M


@pytest.fixture(scope="module")
def office():
    return load_map(office_map_path())


def starts_of(map_model, scenario="follow", goal=None, **starts):
    return get_scenario(scenario)(ScenarioOptions(starts=starts, goal=goal), map_model).starts()


def test_a_start_0_05_m_from_a_wall_is_refused_naming_robot_pose_and_clearance(office):
    # this used to be accepted (only the centre cell was checked): the robot then scraped the west wall
    with pytest.raises(ScenarioError) as info:
        starts_of(office, robot_2=Pose2D(0.15, 4.6, 0.0))
    assert str(info.value) == ("start of robot_2 (0.15, 4.60) is 0.05 m from an obstacle: "
                               f"a TurtleBot 2 needs {START_CLEARANCE_M:.2f} m")


def test_a_start_beside_furniture_is_refused_and_one_just_clear_of_it_accepted(office):
    # this used to accept 0.10 m from the pillar (x 2.0..2.4, y 2.0..2.4): a collision at the first step
    with pytest.raises(ScenarioError, match=r"robot_3 \(2.50, 2.20\) is 0.10 m from an obstacle"):
        starts_of(office, robot_3=Pose2D(2.5, 2.2, 0.0))
    assert starts_of(office, robot_3=Pose2D(2.4 + START_CLEARANCE_M + 0.02, 2.2, 0.0))["robot_3"].x == pytest.approx(2.6)


def test_a_start_near_the_edge_of_a_map_without_walls_there_is_refused(tmp_path):
    # this used to be accepted: the footprint reached off the map (off the map counts as an obstacle)
    img = np.full((60, 60), 254, dtype=np.uint8)  # 3 x 3 m, all free, no walls
    Image.fromarray(img).save(tmp_path / "open.pgm")
    (tmp_path / "open.yaml").write_text("image: open.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    open_map = load_map(tmp_path / "open.yaml")
    goal = Pose2D(2.5, 2.5, 0.0)
    with pytest.raises(ScenarioError, match=r"robot_1 \(1.50, 0.08\) is 0.08 m from an obstacle"):
        starts_of(open_map, goal=goal, robot_1=Pose2D(1.5, 0.08, 0.0), robot_2=Pose2D(1.0, 1.5, 0.0),
                  robot_3=Pose2D(2.0, 2.0, 0.0))
    assert len(starts_of(open_map, goal=goal, robot_1=Pose2D(1.5, 0.5, 0.0), robot_2=Pose2D(1.0, 1.5, 0.0),
                         robot_3=Pose2D(2.0, 2.2, 0.0))) == 3


def test_a_start_inside_a_wall_is_still_refused_as_before(office):
    with pytest.raises(ScenarioError, match="robot_1 .* is inside an obstacle"):
        starts_of(office, robot_1=Pose2D(2.2, 2.2, 0.0))


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_every_scenario_s_own_office_starts_pass(name, office):
    scenario = get_scenario(name)(ScenarioOptions(), office)
    assert set(scenario.starts()) == set(scenario.robots)


def test_the_cli_prints_the_clearance_in_one_line(tmp_path, capsys):
    # this used to run for the whole time limit with robot_2 against the west wall
    assert main(["run", "follow", "--start", "robot_2=0.15,4.6,0", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "robot_2 (0.15, 4.60) is 0.05 m from an obstacle" in err


def test_starts_are_checked_once_and_each_call_gets_its_own_dict(office, monkeypatch):
    # run --processes asks for the starts before the world is built, and the run asks again:
    # a convoy of 30 took 0.1 s per check
    scenario = get_scenario("convoy")(ScenarioOptions(robots=12), office)
    checks = []
    check = type(scenario)._check_starts
    monkeypatch.setattr(type(scenario), "_check_starts", lambda self: checks.append(1) or check(self))
    first = scenario.starts()
    first.pop("robot_1")
    assert scenario.starts() == check(scenario) and "robot_1" in scenario.starts()
    assert len(checks) == 1
