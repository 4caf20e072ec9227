"""The paper's ROS 2 interface: two `--body ros2` robot processes complete a Follow over Zenoh while a
separate rclpy process (tests/ros2/reader.py) reads their comm_protocol topics; a ROS 2 node (tests/ros2/
commander.py) makes a robot send a command through the SendCommand action and gets DONE back, and its
malformed requests are refused with a warning and an error result while the robot goes on."""

import math
import re

import pytest

from .graph import free_port, wait_for

pytestmark = pytest.mark.ros2


def test_two_ros2_robots_complete_a_follow_and_a_ros2_reader_sees_the_papers_topics(ros2):
    ros2.fake_robot("robot_1", "0,0,0")
    ros2.fake_robot("robot_2", "-2,0,0")
    ros2.wait_robots("robot_1", "robot_2")
    reader = ros2.reader("/robot_2/comm_protocol/command:Command", "/robot_1/comm_protocol/command:Command",
                         "/robot_2/comm_protocol/follow:PoseStamped")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    follower = ros2.robot("robot_2", "--listen", endpoint, "--exit-when-done")
    # this used to race: a Follow recorded before the reader had discovered robot_2 was never read
    wait_for(lambda: "reader: publisher on /robot_2/comm_protocol/command" in reader.stdout(), 60, "robot_2's topics")
    leader = ros2.robot("robot_1", "--connect", endpoint, "--follow", "robot_2", "--goal", "3,0", "--exit-when-done")
    assert leader.wait(150) == 0, leader.stdout()[-2000:] + leader.stderr()[-3000:]
    assert follower.wait(30) == 0, follower.stdout()[-2000:] + follower.stderr()[-3000:]
    one, two = ros2.state("robot_1"), ros2.state("robot_2")
    assert one["x"] > 2.5  # the leader drove to its goal on its ROS 2 body
    gap = math.hypot(one["x"] - two["x"], one["y"] - two["y"])
    assert two["x"] > 0.0 and gap < 2.0, (two, gap)  # the follower came along over Zenoh
    reader.stop()
    text = reader.stdout()
    (ros2.workdir / "reader.txt").write_text(text)
    follow = re.search(r"# /robot_2/comm_protocol/command\nheader:\n  stamp:\n.*\n.*\n  frame_id: map\n"
                       r"type: COMMAND_FOLLOW\ndirection: RECEIVED\nsender: robot_1\nreceiver: robot_2\nseq: (\d+)\n", text)
    assert follow, text
    assert "type: COMMAND_FOLLOW\ndirection: SENT\nsender: robot_1\nreceiver: robot_2\n" in text
    assert re.search(r"type: COMMAND_CONFIRM\ndirection: SENT\nsender: robot_2\nreceiver: robot_1\n(?:(?!---).*\n)*?"
                     rf"ref_type: COMMAND_FOLLOW\nref_seq: {follow.group(1)}\nresult: ACCEPTED\n", text), text
    assert "type: COMMAND_POSE_UPDATE\ndirection: RECEIVED\nsender: robot_1\n" in text
    assert "# /robot_2/comm_protocol/follow\nheader:\n  stamp:" in text and "  frame_id: map\npose:\n" in text


def test_a_ros2_nodes_command_through_the_action_comes_back_done_and_bad_ones_are_refused(ros2):
    ros2.fake_robot("robot_1", "0,0,0")
    ros2.fake_robot("robot_2", "0,-1.5,0")
    ros2.wait_robots("robot_1", "robot_2")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    ros2.robot("robot_2", "--listen", endpoint)
    commander = ros2.robot("robot_1", "--connect", endpoint)
    refused = {"receiver robot_1 is this robot": {"type": "COMMAND_GOTO", "receiver": "robot_1", "x": 1.0},
               "receiver:": {"type": "COMMAND_STOP", "receiver": "robot_999"},
               "radius must be a positive number": {"type": "COMMAND_MOVE_AROUND", "receiver": "robot_2",
                                                    "radius": -1.0},
               "off robot_1's map": {"type": "COMMAND_GOTO", "receiver": "robot_2", "x": 100.0, "y": 0.0},
               "unknown type 'COMMAND_DANCE'": {"type": "COMMAND_DANCE", "receiver": "robot_2"}}
    for why, request in refused.items():
        lines = ros2.command("robot_1", request)
        assert lines[-1]["result"] == "REFUSED" and why in lines[-1]["error"], (why, lines)
        assert lines[-1]["status"] == 6  # GoalStatus.STATUS_ABORTED
    lines = ros2.command("robot_1", {"type": "COMMAND_GOTO", "receiver": "robot_2", "x": 1.5, "y": -1.5},
                         timeout_s=90)
    assert lines[-1]["result"] == "DONE" and lines[-1]["status"] == 4, lines  # STATUS_SUCCEEDED
    assert lines[-1]["confirm_result"] == "DONE" and lines[-1]["confirm_sender"] == "robot_2", lines
    feedback = [line["feedback"] for line in lines if "feedback" in line]
    assert feedback and feedback[0] == "ACCEPTED", lines  # each Confirm on the way came as feedback
    state = ros2.state("robot_2")
    assert math.hypot(state["x"] - 1.5, state["y"] + 1.5) < 0.4, state  # robot_2 drove there
    assert commander.alive()  # the bad requests did not end robot_1
    warnings = [line for line in commander.stderr().splitlines() if "refused a Command" in line]
    assert len(warnings) == len(refused) and all("WARN" in w for w in warnings), commander.stderr()[-3000:]
