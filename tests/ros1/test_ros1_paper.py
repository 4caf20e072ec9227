"""The paper's ROS 1 interface against a real roscore: two robots on ROS bodies (fake ROS robots in
processes of their own) follow each other, `rostopic echo` reads the paper's topics, a ROS node
commands the team, and bad requests are warned about and ignored."""

import math
import re
import time

import pytest

from rescuemesh.protocol import MessageType, MoveAround, Pose
from rescuemesh.runtime.ros.ros1_paper import (REQUESTS, TYPE_NAME, RequestError, Traffic, fill_command,
                                           load_command_class, parse_request)

pytestmark = pytest.mark.ros1

TEAM = ["robot_1", "robot_2"]
INPUT = "/robot_1/comm_protocol/command/input"


@pytest.fixture(scope="module")
def command_class(msg_cache):
    return load_command_class(msg_cache[1])


def test_command_type_names_are_the_protocols(command_class):
    constants = {name for name in dir(command_class) if name.startswith("COMMAND_")}
    assert constants == set(TYPE_NAME.values())
    assert {TYPE_NAME[t] for t in REQUESTS} <= constants
    assert TYPE_NAME[MessageType.FOLLOW] == "COMMAND_FOLLOW" and TYPE_NAME[MessageType.CONFIRM] == "COMMAND_CONFIRM"


def test_a_sent_command_fills_the_message(command_class):
    msg = command_class()
    fill_command(msg, Traffic("SENT", 1, 2, 7, MoveAround(Pose(1.0, 2.0, 0.0, math.pi / 2), 1.5)))
    assert (msg.type, msg.direction, msg.sender, msg.receiver, msg.seq) == \
        ("COMMAND_MOVE_AROUND", "SENT", "robot_1", "robot_2", 7)
    assert (msg.frame.position.x, msg.frame.position.y, msg.radius) == (1.0, 2.0, 1.5)
    assert msg.frame.orientation.z == pytest.approx(math.sin(math.pi / 4))


def _request(command_class, **fields):
    msg = command_class()
    for name, value in fields.items():
        if name == "frame_id":
            msg.header.frame_id = value
        elif name == "x":
            msg.frame.position.x = value
        else:
            setattr(msg, name, value)
    return msg


#: (Command fields, what the warning says): each is refused, none crashes. Also sent end to end below.
BAD_REQUESTS = [
    pytest.param({"type": "COMMAND_DANCE", "receiver": "robot_2"}, "unknown type 'COMMAND_DANCE'", id="unknown-type"),
    pytest.param({"type": "", "receiver": "robot_2"}, "unknown type ''", id="empty-type"),
    pytest.param({"type": "COMMAND_CONFIRM", "receiver": "robot_2"}, "COMMAND_CONFIRM is not accepted",
                 id="confirm-is-no-request"),
    pytest.param({"type": "COMMAND_FORWARD_MSG", "receiver": "robot_2"}, "COMMAND_FORWARD_MSG is not accepted",
                 id="forward-needs-inner"),
    pytest.param({"type": "COMMAND_FOLLOW", "receiver": "nobody"}, "receiver: unknown robot 'nobody'",
                 id="unknown-receiver"),
    pytest.param({"type": "COMMAND_FOLLOW", "receiver": ""}, "receiver: unknown robot ''", id="no-receiver"),
    pytest.param({"type": "COMMAND_FOLLOW", "receiver": "robot_1"}, "a robot does not command itself",
                 id="itself"),
    pytest.param({"type": "COMMAND_STOP", "receiver": "robot_2", "sender": "robot_3"}, "sender 'robot_3'",
                 id="other-sender"),
    pytest.param({"type": "COMMAND_FOLLOW", "receiver": "robot_2", "direction": "SENT"}, "not a request",
                 id="a-record-fed-back"),
    pytest.param({"type": "COMMAND_MOVE_AROUND", "receiver": "robot_2", "radius": -1.0},
                 "radius must be a positive number", id="negative-radius"),
    pytest.param({"type": "COMMAND_GOTO", "receiver": "robot_2", "x": float("nan")}, "not finite", id="nan-goal"),
    pytest.param({"type": "COMMAND_GOTO", "receiver": "robot_2", "frame_id": "odom"}, "only 'map' is known",
                 id="goal-in-odom"),
]


@pytest.mark.parametrize("fields, why", BAD_REQUESTS)
def test_a_bad_request_is_refused_with_a_reason(command_class, fields, why):
    with pytest.raises(RequestError, match=re.escape(why)):
        parse_request(_request(command_class, **fields), "robot_1")


def test_a_good_request_is_parsed(command_class):
    request = parse_request(_request(command_class, type="COMMAND_GOTO", receiver="robot_2", x=2.5), "robot_1")
    assert (request.type, request.receiver, request.frame.x) == (MessageType.GOTO, 2, 2.5)


def test_follow_between_two_ros_robots_is_seen_on_the_papers_topics(ros):
    ros.robot("robot_1", "0,0,0")
    ros.robot("robot_2", "-1.5,0,0")
    ros.wait_robots(*TEAM)
    echo_follower = ros.echo("/robot_2/comm_protocol/command", 4)
    echo_leader = ros.echo("/robot_1/comm_protocol/command", 4)
    echo_pose = ros.echo("/robot_2/comm_protocol/follow", 2)
    team = ros.team(TEAM, "--follow", "robot_1,robot_2,3,0", "--duration", "60", "--listen", "robot_1",
                    "--listen", "robot_2")
    assert team.wait(90) == 0, team.stderr()[-3000:]
    script = ros.report()["script"]
    assert script["accepted_s"] is not None and script["arrived_s"] is not None, script
    leader, follower = ros.state("robot_1"), ros.state("robot_2")
    assert leader["x"] > 2.5  # the leader drove its 3 m
    gap = math.hypot(leader["x"] - follower["x"], leader["y"] - follower["y"])
    assert follower["x"] > 1.0 and 0.5 < gap < 1.6, (follower, gap)  # the follower came along, ~1 m behind
    for echo in (echo_follower, echo_leader, echo_pose):
        assert echo.wait(20) == 0, echo.stderr()
    follower_text, leader_text = echo_follower.stdout(), echo_leader.stdout()
    for text, follow, confirm in ((follower_text, "RECEIVED", "SENT"), (leader_text, "SENT", "RECEIVED")):
        assert f'type: "COMMAND_FOLLOW"\ndirection: "{follow}"\nsender: "robot_1"\nreceiver: "robot_2"' in text
        assert f'type: "COMMAND_CONFIRM"\ndirection: "{confirm}"\nsender: "robot_2"\nreceiver: "robot_1"' in text
        assert 'ref_type: "COMMAND_FOLLOW"\nref_seq: 1\nresult: "ACCEPTED"' in text
        assert 'type: "COMMAND_POSE_UPDATE"' in text
    assert echo_pose.stdout().count('frame_id: "map"') == 2


def test_a_ros_node_commands_follow_then_stop_halts_the_follower(ros):
    ros.robot("robot_1", "0,0,0")
    ros.robot("robot_2", "-8,0,0")
    ros.wait_robots(*TEAM)
    echo_leader = ros.echo("/robot_1/comm_protocol/command")
    team = ros.team(TEAM, "--duration", "90", "--listen", "robot_1")
    ros.wait_ready(team)
    ros.rostopic_pub(INPUT, "{type: COMMAND_FOLLOW, receiver: robot_2}")
    ros.wait_for_state("robot_2", lambda s: s["v"] > 0.2, 20, "robot_2 driving after the Follow")
    ros.publish(INPUT, [{"type": "COMMAND_STOP", "receiver": "robot_2"}])
    halted = ros.wait_for_state("robot_2", lambda s: s["v"] == 0.0 and s["w"] == 0.0, 5, "robot_2 halted by Stop")
    time.sleep(1.5)
    still = ros.state("robot_2")
    assert math.hypot(still["x"] - halted["x"], still["y"] - halted["y"]) < 0.01 and still["v"] == 0.0
    assert still["x"] < -1.5  # halted on the way, not at the end of the Follow
    assert team.alive() and still["cmd_age_s"] < 1.0  # the brain still commands, and commands zero
    log = {kind: detail for _, kind, detail in ros.wait_for_report(
        lambda r: any(k == "stopped" for _, k, _ in r["robots"]["robot_2"]["log"]), 5, "robot_2's log")
        ["robots"]["robot_2"]["log"]}
    assert log["stopped"] == "by robot_1"
    echo_leader.stop()
    text = echo_leader.stdout()
    assert 'type: "COMMAND_FOLLOW"\ndirection: "SENT"' in text
    assert 'type: "COMMAND_STOP"\ndirection: "SENT"\nsender: "robot_1"\nreceiver: "robot_2"' in text
    assert 'ref_type: "COMMAND_STOP"\nref_seq: ' in text and 'result: "DONE"' in text


def test_bad_requests_from_a_ros_node_are_warned_about_and_ignored(ros):
    ros.robot("robot_1", "0,0,0")
    ros.robot("robot_2", "-2,0,0")
    ros.wait_robots(*TEAM)
    team = ros.team(TEAM, "--duration", "90")
    ros.wait_ready(team)
    bad = [dict(p.values[0]) for p in BAD_REQUESTS]
    for fields in bad:  # the test's field names to the publisher's
        if "x" in fields:
            fields["frame"] = [fields.pop("x"), 0.0, 0.0]
    # a message of another type on the input topic: rospy refuses the connection, nothing arrives
    ros.start("wrong_type", ["rostopic", "pub", "-1", INPUT, "std_msgs/String", "data: hello"]).wait(20)
    ros.publish(INPUT, bad + [{"type": "COMMAND_STOP", "receiver": "robot_2"}])
    report = ros.wait_for_report(lambda r: r["robots"]["robot_1"]["requests_done"] == 1, 10, "the good request")
    assert team.alive()
    robot_1 = report["robots"]["robot_1"]
    assert [c[1] for c in robot_1["outgoing"]] == ["Stop"]  # nothing but the good request was sent
    assert robot_1["requests_refused"] == len(bad)
    warnings = [line for line in team.stderr().splitlines() if "ignored a Command on " + INPUT in line]
    assert len(warnings) == len(bad) and all(line.startswith("[WARN]") for line in warnings), warnings
    for param, line in zip(BAD_REQUESTS, warnings):
        assert param.values[1] in line, (param.id, line)
