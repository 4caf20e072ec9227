"""`rescuemesh robot --link zenoh --body ros1`: each robot its own process, on a ROS 1 robot (a fake
one here), its frames over Zenoh, the paper's topics read by `rostopic echo`."""

import math
import sys

import pytest

from .rosproc import free_port

pytestmark = pytest.mark.ros1


def _robot(ros, name: str, *args: str):
    return ros.start(name, [sys.executable, "-m", "rescuemesh", "robot", "--link", "zenoh", "--body", "ros1",
                            "--name", name, "--duration", "90", "--exit-when-done", *args])


def test_two_ros_robots_as_processes_over_zenoh_complete_a_follow(ros):
    ros.robot("robot_1", "0,0,0")
    ros.robot("robot_2", "-2,0,0")
    ros.wait_robots("robot_1", "robot_2")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    echo = ros.echo("/robot_2/comm_protocol/command", 3)
    follower = _robot(ros, "robot_2", "--listen", endpoint)
    # this used to race: a Follow published before `rostopic echo` had subscribed was never echoed
    ros.wait_linked("/robot_2/comm_protocol/command")
    leader = _robot(ros, "robot_1", "--connect", endpoint, "--follow", "robot_2", "--goal", "3,0")
    assert leader.wait(120) == 0, leader.stdout()[-2000:] + leader.stderr()[-2000:]
    assert follower.wait(30) == 0, follower.stdout()[-2000:] + follower.stderr()[-2000:]
    assert "robot_1: ok" in leader.stdout()
    one, two = ros.state("robot_1"), ros.state("robot_2")
    assert one["x"] > 2.5  # the leader drove to its goal on its ROS body
    gap = math.hypot(one["x"] - two["x"], one["y"] - two["y"])
    assert two["x"] > 0.5 and gap < 2.0, (two, gap)  # the follower came along over Zenoh
    assert two["v"] == 0.0 and two["w"] == 0.0  # and both halted on the way out
    # both loops commanded at their pace: no silence the base's 0.5 s cmd_vel timeout would stop (0.05 s seen)
    assert one["longest_cmd_gap_s"] < 0.5 and two["longest_cmd_gap_s"] < 0.5, (one, two)
    assert echo.wait(20) == 0, echo.stderr()
    text = echo.stdout()
    assert 'type: "COMMAND_FOLLOW"\ndirection: "RECEIVED"\nsender: "robot_1"\nreceiver: "robot_2"' in text
    assert 'type: "COMMAND_CONFIRM"\ndirection: "SENT"\nsender: "robot_2"\nreceiver: "robot_1"' in text


def test_a_ros_robot_without_odometry_is_a_one_line_error(ros):
    lonely = _robot(ros, "robot_5", "--listen", f"tcp/127.0.0.1:{free_port()}", "--odometry-wait", "1")
    assert lonely.wait(30) == 2
    assert "no nav_msgs/Odometry on /robot_5/odom" in lonely.stderr() and "Traceback" not in lonely.stderr()
