"""The ROS body flags of `rescuemesh robot` (runtime/ros/ros_options.py): what reaches Ros1Body and Ros2Body,
and bad flags as one-line usage errors. No ROS needed: the bodies are not built here."""

import io

import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.runtime.onboard.linked_robot import UsageError, build_parser, main
from rescuemesh.runtime.ros.ros_options import (_limits, map_frame_warning, ros1_body_kwargs, ros2_body_kwargs,
                                            ros_body_options, split_ros_args)

BASE = ["--name", "robot_2", "--listen", "tcp/127.0.0.1:7447"]


def _ros(*args: str) -> dict:
    return ros_body_options(build_parser().parse_args([*BASE, *args]), UsageError)


def test_ros1_flags_reach_the_topics_mount_and_limits():
    kwargs = ros1_body_kwargs(_ros("--body", "ros1", "--odom-topic", "/{robot}/wheel_odom", "--pose-topic",
                                   "/{robot}/amcl_pose", "--laser-mount", "0.1,0,3.14159", "--max-linear-speed", "0.26"))
    topics = kwargs["topics"].resolve("robot_2")
    assert (topics.odom, topics.scan, topics.cmd_vel, topics.pose) == (
        "/robot_2/wheel_odom", "/robot_2/scan", "/robot_2/cmd_vel", "/robot_2/amcl_pose")
    assert kwargs["laser_offset"] == Pose2D(0.1, 0.0, 3.14159) and kwargs["max_linear_speed"] == 0.26
    assert "max_angular_speed" not in kwargs  # the body's default stays


def test_ros2_flags_reach_the_topics_and_twist_stamped():
    kwargs = ros2_body_kwargs(_ros("--body", "ros2", "--cmd-vel-topic", "diff_drive_controller/cmd_vel",
                                   "--twist-stamped", "--max-angular-speed", "1.9"))
    topics = kwargs["topics"]
    assert (topics.odom, topics.cmd_vel, topics.pose, topics.twist_stamped) == (
        "odom", "diff_drive_controller/cmd_vel", None, True)
    assert kwargs["max_angular_speed"] == 1.9


@pytest.mark.parametrize("args, message", [
    (["--body", "ros2", "--max-linear-speed", "-1"], "--max-linear-speed must be in (0, 10]"),
    (["--body", "ros2", "--max-angular-speed", "nan"], "--max-angular-speed must be in (0, 10]"),
    (["--body", "ros1", "--laser-mount", "1"], "--laser-mount takes X,Y[,YAW]"),
    (["--odom-topic", "/odom"], "--odom-topic: only for --body ros1 or ros2"),
    (["--body", "ros1", "--twist-stamped"], "--twist-stamped and --namespace are for --body ros2"),
    (["--body", "ros2", "--scan-topic", "a b"], "--scan-topic takes a topic name without spaces"),
])
def test_bad_ros_flags_are_one_line_usage_errors(args, message):
    err = io.StringIO()
    assert main([*BASE, *args], out=io.StringIO(), err=err) == 2
    assert message in err.getvalue() and len(err.getvalue().strip().splitlines()) == 1, err.getvalue()


def test_ros_args_go_to_ros2_only():
    assert split_ros_args(["--name", "robot_1", "--ros-args", "-r", "odom:=/odom"]) == (
        ["--name", "robot_1"], ["-r", "odom:=/odom"])
    err = io.StringIO()
    assert main([*BASE, "--ros-args", "-r", "odom:=/odom"], out=io.StringIO(), err=err) == 2
    assert "--ros-args is for --body ros2" in err.getvalue()


def test_the_map_frame_warning_comes_only_without_a_pose_topic():
    assert "no --pose-topic" in map_frame_warning("robot_2", _ros("--body", "ros2"), "/robot_2/odom")
    assert map_frame_warning("robot_2", _ros("--body", "ros2", "--pose-topic", "amcl_pose"), "/robot_2/odom") is None
    assert _limits(_ros()) == {}


def test_rescuemesh_robot_help_lists_every_option_of_both_kinds_of_robot_process(capsys):
    # this used to show only the world-connected robot's five options
    from rescuemesh.cli import main as cli_main

    assert cli_main(["robot", "--help"]) == 0
    text = capsys.readouterr().out
    for option in ("--run-id", "--link {zenoh,ble}", "--hci SPEC", "--body {kinematic,ros1,ros2}", "--odom-topic",
                   "--scan-topic", "--cmd-vel-topic", "--pose-topic", "--laser-mount", "--max-linear-speed",
                   "--max-angular-speed", "--twist-stamped", "--namespace", "--follow", "--exit-when-done"):
        assert option in text, option
