"""The brain's command handler over the real protocol and radio link, on unicycle bodies."""

import pytest

from team import Team

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import (Confirm, Endpoint, ForwardMsg, Goto, LandOnTop, MoveAround, Pose, ResultCode, Return,
                                 ShowCam, ShowScan)
from rescuemesh.protocol.codec import decode_frame

ONE, TWO = 1, 2


def two_robots(**kw):
    return Team({"robot_1": Pose2D(3.0, 6.0), "robot_2": Pose2D(1.5, 6.0)}, **kw)


@pytest.mark.parametrize("command", [
    Goto(Pose(5, 5, 0, 0)), Return(), LandOnTop(Pose(1, 1, 0.3, 0)), ShowCam(Pose(1, 1, 0, 0), 1.0, 1),
    ShowScan(Pose(1, 1, 0, 0), 0.5, 0), ForwardMsg(3, b"\x05"),
])
def test_commands_not_built_yet_are_answered_unsupported_and_do_nothing(command):
    team = two_robots()
    seq = team.brains["robot_1"].send(TWO, command, 0.0)
    team.run(1.0)
    assert team.brains["robot_1"].outgoing[seq].result == ResultCode.UNSUPPORTED
    assert team.brains["robot_2"].behaviour == "idle"
    assert team.bodies["robot_2"].pose() == Pose2D(1.5, 6.0)


def test_follow_streams_poses_and_the_follower_keeps_its_distance():
    team = two_robots()
    leader, follower = team.brains["robot_1"], team.brains["robot_2"]
    leader.command_follow(TWO, 0.0)
    team.run(0.5)
    leader.navigate_to(Pose2D(9.0, 6.0), team.time)
    team.run(25.0)
    assert follower.behaviour == "follow" and TWO in leader.streams
    gap = team.bodies["robot_1"].pose().distance_to(team.bodies["robot_2"].pose())
    assert 0.8 <= gap <= 1.3
    assert follower.endpoint.stats.confirms_sent >= 2 * 25 * 0.9  # every PoseUpdate confirmed (2 Hz)


def test_leader_gives_follow_up_after_three_unconfirmed_updates_and_follower_stops_safely():
    team = two_robots()
    leader, follower = team.brains["robot_1"], team.brains["robot_2"]
    leader.command_follow(TWO, 0.0)
    team.run(2.0)
    team.link.channel = type(team.link.channel)(range_m=0.5)  # the follower drops out of radio range
    lost_at = team.time
    team.run(5.0)
    assert "follow_given_up" in team.kinds("robot_1") and TWO not in leader.streams
    # the Follow stream, then the Stop sent after it (best effort) into the same silence
    assert leader.commands_failed == 2 and [c.kind for c in leader.outgoing.values()] == ["Follow", "Stop"]
    given_up = next(e.time_s for e in leader.log if e.kind == "follow_given_up")
    assert given_up - lost_at <= 2.5  # three updates at 2 Hz, each retried for 0.3 s
    ended = [e for e in follower.log if e.kind == "behaviour_ended"]
    assert ended and "leader silent" in ended[-1].detail and follower.behaviour == "idle"
    assert team.bodies["robot_2"].command == (0.0, 0.0)


def test_stop_preempts_follow_and_reports_cancelled_to_the_commander():
    team = two_robots()
    leader, follower = team.brains["robot_1"], team.brains["robot_2"]
    follow = leader.command_follow(TWO, 0.0)
    team.run(1.0)
    stop = leader.command_stop(TWO, team.time)
    team.run(1.0)
    assert leader.outgoing[stop].result == ResultCode.DONE
    assert leader.outgoing[follow].result == ResultCode.CANCELLED  # the unsolicited final report
    assert follower.behaviour == "idle" and TWO not in leader.streams
    assert team.bodies["robot_2"].command == (0.0, 0.0)


def test_pose_update_from_a_robot_we_do_not_follow_is_denied():
    team = two_robots()
    seq = team.brains["robot_1"].endpoint.send_pose_update(TWO, Pose(2, 2, 0, 0), 0.0)
    team.run(0.5)
    assert team.brains["robot_2"].behaviour == "idle"
    assert team.brains["robot_1"].endpoint.stats.confirms_received == 1
    assert seq is not None


def test_move_around_inside_a_wall_is_denied():
    team = two_robots()
    # a circle of radius 20 m around robot_1 lies wholly outside the 12 m room
    seq = team.brains["robot_1"].send(TWO, MoveAround(Pose(3, 6, 0, 0), 20.0), 0.0)
    team.run(1.0)
    assert team.brains["robot_1"].outgoing[seq].result == ResultCode.DENIED
    assert "command_denied" in team.kinds("robot_2")


def test_garbage_frames_are_counted_and_dropped_without_crashing_the_robot():
    team = two_robots()
    follower = team.brains["robot_2"]
    for garbage in (b"", b"\x00", b"\xff" * 20, bytes(range(40)), b"\x40\x01\x01\x02\x00\x01junk"):
        follower.endpoint.receive(garbage, 0.0)
    team.run(0.2)
    assert follower.frames_rejected == 5 and follower.endpoint.stats.frames_rejected == 5
    # and it still works afterwards
    team.brains["robot_1"].command_follow(TWO, team.time)
    team.run(1.0)
    assert follower.behaviour == "follow"


def test_a_resent_command_is_not_executed_twice():
    # the same frame heard twice (a resend after a lost Confirm) starts one behaviour, gets two Confirms
    team = two_robots()
    leader, follower = team.brains["robot_1"], team.brains["robot_2"]
    leader.command_follow(TWO, 0.0)
    (frame,) = leader.endpoint.frames_to_send(0.0)
    follower.endpoint.receive(frame, 0.01)
    follower.step(0.05)
    follower.endpoint.receive(frame, 0.06)
    follower.step(0.1)
    starts = [e for e in follower.log if e.kind == "behaviour_started"]
    assert len(starts) == 1 and follower.endpoint.stats.duplicates == 1
    messages = [decode_frame(f)[1] for f in follower.endpoint.frames_to_send(0.1)]
    confirms = [m for m in messages if isinstance(m, Confirm)]
    assert [c.result for c in confirms] == [ResultCode.ACCEPTED, ResultCode.ACCEPTED]  # the cached one again


@pytest.mark.parametrize("then", ["stop", "follow"])
def test_a_restarted_leader_reusing_sequence_numbers_does_not_crash_the_follower(then):
    # this used to raise ValueError in the follower: its CANCELLED report answered the leader's new frame
    team = two_robots()
    follower = team.brains["robot_2"]
    team.brains["robot_1"].command_follow(TWO, 0.0)
    team.run(1.0)
    restarted = Endpoint(ONE)  # a rebooted leader: its sequence numbers start at 0 again
    team.brains["robot_1"].endpoint = restarted
    team.link._radios[ONE].endpoint = restarted
    brain = team.brains["robot_1"]
    team.bodies["robot_1"].teleport(Pose2D(4.0, 7.0))  # a new Follow, not a byte-identical resend
    seq = brain.command_stop(TWO, team.time) if then == "stop" else brain.command_follow(TWO, team.time)
    team.run(1.0)
    expected = ResultCode.DONE if then == "stop" else ResultCode.ACCEPTED
    assert brain.outgoing[seq].result == expected
    assert follower.behaviour == ("idle" if then == "stop" else "follow")


def test_an_undelivered_showcam_is_not_followed_by_an_automatic_stop():
    team = two_robots()
    team.link.channel = type(team.link.channel)(range_m=0.5)
    team.brains["robot_1"].send(TWO, ShowCam(Pose(1, 1, 0, 0), 1.0, 1), 0.0)
    team.run(2.0)
    kinds = [c.kind for c in team.brains["robot_1"].outgoing.values()]
    assert kinds == ["ShowCam"]
