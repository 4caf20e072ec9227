"""Inputs a user expects: --goal X,Y[,YAW] wherever a goal is taken, map YAML starts/goals/bases on
an own map, robots with no task placed automatically, and every option listed by --help."""

import json

import numpy as np
import pytest
from PIL import Image

from rescuemesh.cli import main
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import load_map
from rescuemesh.scenarios import ScenarioOptions, get_scenario


def ros_map_with(tmp_path, extra: str):
    """A 10 x 5 m ROS map_server map (outer walls, an inner wall at x = 5 m with a doorway) and `extra` YAML."""
    img = np.full((100, 200), 254, dtype=np.uint8)
    img[:2, :] = img[-2:, :] = img[:, :2] = img[:, -2:] = 0
    img[:, 99:101] = 0
    img[38:62, 99:101] = 254
    Image.fromarray(img).save(tmp_path / "lab.pgm")
    (tmp_path / "lab.yaml").write_text("image: lab.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
                                       "occupied_thresh: 0.65\nfree_thresh: 0.196\n" + extra)
    return load_map(tmp_path / "lab.yaml")


def test_goto_takes_a_heading_with_its_goal(tmp_path):
    # this used to refuse --goal 12.6,2.4,3.1416 ("expected X,Y in m")
    out = tmp_path / "out"
    assert main(["run", "goto", "--goal", "12.6,2.4,3.1416", "--quiet", "--out", str(out)]) == 0
    result = json.loads((out / "result.json").read_text())
    assert abs(abs(result["robots"]["robot_2"]["final_pose"]["yaw"]) - 3.1416) < 0.3


def test_a_robot_with_no_task_needs_no_start_on_an_own_map(tmp_path):
    # this used to ask for --start robot_3=X,Y,YAW though robot_3 only sits still
    lab = ros_map_with(tmp_path, "")
    options = ScenarioOptions(starts={"robot_1": Pose2D(2.5, 2.5, 0.0), "robot_2": Pose2D(1.2, 2.5, 0.0)},
                              goal=Pose2D(8.5, 2.5, 0.0))
    starts = get_scenario("follow")(options, lab).starts()
    placed = starts["robot_3"]
    assert not lab.grid.is_occupied(placed.x, placed.y)
    assert min(placed.distance_to(starts[n]) for n in ("robot_1", "robot_2")) >= 1.5


def test_a_robot_with_a_task_still_needs_its_start(tmp_path):
    lab = ros_map_with(tmp_path, "")
    options = ScenarioOptions(starts={"robot_1": Pose2D(2.5, 2.5, 0.0), "robot_2": Pose2D(1.2, 2.5, 0.0)})
    with pytest.raises(ValueError, match="robot_3"):
        get_scenario("relay")(options, lab).starts()


def test_map_starts_goals_and_bases_are_used(tmp_path):
    lab = ros_map_with(tmp_path, "starts:\n  robot_1: [2.5, 2.5, 0]\n  robot_2: [1.2, 2.5, 0]\n"
                                 "goals:\n  follow_leader: [8.5, 2.5, 0]\n  goto: [8.0, 1.0, 1.57]\n"
                                 "  show: [8.0, 4.0, 0]\nbases:\n  robot_2: [1.2, 1.0, 0]\n")
    assert lab.bases == {"robot_2": Pose2D(1.2, 1.0, 0.0)}
    assert get_scenario("follow")(ScenarioOptions(), lab).goal() == Pose2D(8.5, 2.5, 0.0)
    assert get_scenario("goto")(ScenarioOptions(), lab).goal() == Pose2D(8.0, 1.0, 1.57)
    assert get_scenario("show-scan")(ScenarioOptions(), lab).target() == Pose2D(8.0, 4.0, 0.0)
    assert "robot_3" in get_scenario("goto")(ScenarioOptions(), lab).starts()


def test_return_goes_to_the_base_the_map_names(tmp_path):
    from rescuemesh.runtime.inprocess.sim_loop import SimRuntime

    lab = ros_map_with(tmp_path, "bases:\n  robot_2: [1.2, 1.0, 0]\n")
    starts = {"robot_1": Pose2D(2.5, 2.5, 0.0), "robot_2": Pose2D(1.2, 2.5, 0.0), "robot_3": Pose2D(1.0, 4.3, 0.0)}
    rt = SimRuntime(lab, starts)
    assert rt.brain("robot_2").config.base == Pose2D(1.2, 1.0, 0.0)
    assert rt.brain("robot_1").config.base == starts["robot_1"]  # no base named: its start


def test_robot_help_lists_the_linked_robot_s_options(capsys):
    # this used to hide --link, --body, --listen, --follow and --goal unless --link zenoh came first
    assert main(["robot", "--help"]) == 0
    text = capsys.readouterr().out
    for option in ("--link", "--body", "--listen", "--follow", "--goal", "--connect", "--wait"):
        assert option in text


def test_a_goal_for_a_scenario_that_takes_none_is_refused(capsys):
    # this used to be ignored without a word (relay drives its own fixed leg)
    assert main(["run", "relay", "--goal", "3,3", "--quiet"]) == 2
    assert "--goal applies to follow" in capsys.readouterr().err
