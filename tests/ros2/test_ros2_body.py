"""`rescuemesh robot --link zenoh --body ros2` on a fake ROS 2 robot (tests/ros2/fake_robot.py, its own
process): the robot process drives it to a goal over real rclpy topics, and its wheels stop however the
robot process ends (a zero Twist on the way out; the base's own cmd_vel timeout after a SIGKILL)."""

import json
import signal
import time

import pytest

from .graph import free_port

pytestmark = pytest.mark.ros2


def _listen() -> str:
    return f"tcp/127.0.0.1:{free_port()}"


def test_a_ros2_robot_process_drives_the_fake_robot_to_a_goal(ros2):
    ros2.fake_robot("robot_1", "0,0,0")
    ros2.wait_robots("robot_1")
    robot = ros2.robot("robot_1", "--listen", _listen(), "--goal", "2,0", "--exit-when-done")
    assert robot.wait(90) == 0, robot.stdout()[-2000:] + robot.stderr()[-2000:]
    assert "robot_1: ok" in robot.stdout()
    state = ros2.state("robot_1")
    assert state["x"] > 1.5 and abs(state["y"]) < 0.3, state  # at the goal, on the fake robot's own odometry
    assert state["v"] == 0.0 and state["w"] == 0.0 and state["stop_cause"] == "zero_twist", state
    # its loop commanded at its pace: no silence the base's 0.5 s cmd_vel timeout would have stopped
    # (with rclpy's multi-threaded executor on the sensors the loop stalled 0.3-2.6 s while driving)
    assert state["longest_cmd_gap_s"] < 0.5 and state["timeouts"] == 0, state
    assert "warning: no --pose-topic" in robot.stderr()  # its odom frame is taken as the map frame


def test_a_burst_of_action_goals_does_not_stall_a_driving_robots_loop(ros2):
    # the action server waits for each command's end in its callback, on the commands node's own
    # multi-threaded executor: eight goals waiting at once (Stops to a robot that never answers, each
    # given up by the protocol after its retries) are all answered, and the loop drives on meanwhile
    # without a cmd_vel silence (measured 0.055 s; with the action on the sensors' single-threaded
    # executor the goals wait in turn and half of them get no result in a minute)
    ros2.fake_robot("robot_1", "0,0,0")
    ros2.wait_robots("robot_1")
    robot = ros2.robot("robot_1", "--listen", _listen(), "--goal", "2.5,0", "--exit-when-done")
    ros2.wait_for_state("robot_1", lambda s: s["v"] > 0.05, 60.0, "robot_1 to drive")
    started = time.monotonic()
    lines = ros2.command("robot_1", {"type": "COMMAND_STOP", "receiver": "robot_2"}, copies=8, timeout_s=60)
    answered_s = time.monotonic() - started
    assert robot.wait(90) == 0, robot.stdout()[-2000:] + robot.stderr()[-2000:]
    assert len(lines) == 8 and all("result" in line and line["result"] != "REFUSED" for line in lines), lines
    state = ros2.state("robot_1")
    assert state["x"] > 2.0 and state["stop_cause"] == "zero_twist", state
    assert state["longest_cmd_gap_s"] < 0.5 and state["timeouts"] == 0, (state, answered_s)


def test_remapped_topics_twist_stamped_and_flags_reach_the_ros2_body(ros2):
    # a TurtleBot-4-like base: odometry on /tb/odom, TwistStamped on cmd_vel
    ros2.fake_robot("robot_3", "0,0,0", "--twist-stamped", "--odom-topic", "/tb/odom")
    ros2.wait_robots("robot_3")
    robot = ros2.robot("robot_3", "--listen", _listen(), "--goal", "1.5,0", "--exit-when-done", "--twist-stamped",
                       "--max-linear-speed", "0.3", "--odometry-wait", "20", "--ros-args", "-r", "odom:=/tb/odom")
    assert robot.wait(90) == 0, robot.stdout()[-2000:] + robot.stderr()[-2000:]
    state = ros2.state("robot_3")
    assert state["x"] > 1.0 and state["stamped"] > 0, state  # it drove on TwistStamped alone
    assert "(/tb/odom)" in robot.stderr()  # the remapped name is the one it read


def test_use_sim_time_steps_the_brain_on_the_clock_topic(ros2):
    # a Gazebo-like robot whose /clock runs at half the wall clock's pace
    ros2.fake_robot("robot_7", "0,0,0", "--clock-rate", "0.5")
    ros2.wait_robots("robot_7")
    report = ros2.workdir / "robot_7.json"
    began = time.monotonic()
    robot = ros2.robot("robot_7", "--listen", _listen(), "--duration", "6", "--json-out", str(report),
                       "--ros-args", "-p", "use_sim_time:=true")
    assert robot.wait(60) == 0, robot.stdout()[-2000:] + robot.stderr()[-2000:]
    wall_s = time.monotonic() - began
    ran_s = json.loads(report.read_text())["ran_s"]
    assert 5.9 < ran_s < 6.5 and wall_s > 11.0, (ran_s, wall_s)  # 6 s of /clock took 12 s of wall time


def _driving(ros2, name: str):
    ros2.fake_robot(name, "0,0,0")
    ros2.wait_robots(name)
    robot = ros2.robot(name, "--listen", _listen(), "--goal", "15,0")
    ros2.wait_for_state(name, lambda s: s["v"] > 0.2, 60, f"{name} to drive")
    return robot


def test_sigkill_of_the_robot_process_stops_the_wheels_by_the_bases_timeout(ros2):
    robot = _driving(ros2, "robot_4")
    robot.popen.send_signal(signal.SIGKILL)
    robot.popen.wait(10)
    state = ros2.wait_for_state("robot_4", lambda s: s["v"] == 0.0 and s["w"] == 0.0, 10, "the wheels to stop")
    assert state["stop_cause"] == "timeout" and state["timeouts"] >= 1, state  # no zero Twist could be sent


def test_ctrl_c_of_the_robot_process_sends_a_zero_twist(ros2):
    robot = _driving(ros2, "robot_5")
    robot.popen.send_signal(signal.SIGINT)
    assert robot.wait(20) == 1  # the mission (drive to 15,0) did not end
    assert "Traceback" not in robot.stderr(), robot.stderr()[-2000:]
    state = ros2.wait_for_state("robot_5", lambda s: s["v"] == 0.0 and s["w"] == 0.0, 5, "the wheels to stop")
    assert state["stop_cause"] == "zero_twist" and state["timeouts"] == 0, state  # stopped by the robot, not the base


def test_a_ros2_robot_without_odometry_is_a_one_line_error(ros2):
    lonely = ros2.robot("robot_6", "--listen", _listen(), "--odometry-wait", "1")
    assert lonely.wait(30) == 2
    err = lonely.stderr()
    assert "no nav_msgs/msg/Odometry on /robot_6/odom" in err and "Traceback" not in err, err
