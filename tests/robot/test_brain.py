"""The brain's command handler over the real protocol and radio link, on unicycle bodies."""

import math
from dataclasses import replace

import pytest

from team import Team

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import (
    ConfirmReceived, DataKind, Endpoint, ForwardMsg, Goto, LandOnTop, MessageType, MoveAround, Pose, Reason,
    ResultCode, Return, ShowCam, ShowScan, Stop)
from rescuemesh.protocol.codec import encode_inner
from rescuemesh.protocol.messages import Confirm, Data
from rescuemesh.protocol.codec import decode_frame
from rescuemesh.robot import BrainConfig
from rescuemesh.robot import events as ev
from rescuemesh.robot.policy import Rank

ONE, TWO = 1, 2


def two_robots(**kw):
    return Team({"robot_1": Pose2D(3.0, 6.0), "robot_2": Pose2D(1.5, 6.0)}, **kw)


def test_land_on_top_asked_of_a_ground_robot_is_unsupported_and_does_nothing():
    team = two_robots()
    seq = team.brains["robot_1"].send(TWO, LandOnTop(Pose(1, 1, 0.4, 0)), 0.0)
    team.run(1.0)
    sent = team.brains["robot_1"].outgoing[seq]
    assert (sent.result, sent.reason) == (ResultCode.UNSUPPORTED, Reason.NOT_FLYING)
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


def far_away(team, name):
    team.bodies[name].teleport(Pose2D(50.0, 50.0))  # beyond the 10 m disc: nothing gets through


def test_a_lost_follower_pauses_both_sides_and_after_the_reconnect_window_both_end_it_failed():
    # this used to give the Follow up after three unconfirmed PoseUpdates (about 1.5 s), with no
    # chance to resume; now missed heartbeats pause it and a 5 s reconnect window decides
    team = two_robots()
    leader, follower = team.brains["robot_1"], team.brains["robot_2"]
    follow = leader.command_follow(TWO, 0.0)
    leader.navigate_to(Pose2D(9.0, 6.0), 0.1)
    team.run(2.0)
    home = team.bodies["robot_2"].pose()
    far_away(team, "robot_2")
    cut = team.time
    team.run(3.0)
    assert ev.LinkLost not in team.kinds("robot_1")  # 3 missed heartbeats + half a period: not yet
    team.run(1.5)
    lost = [e.time_s for e in leader.log if isinstance(e, ev.LinkLost)]
    assert lost and 3.0 <= lost[0] - cut <= 4.6 and leader.streams[TWO].paused
    assert [e for e in follower.log if isinstance(e, ev.LinkLost)] and follower.running.behaviour.paused
    assert team.bodies["robot_2"].command == (0.0, 0.0)  # the follower halts at once
    team.run(6.0)
    assert TWO not in leader.streams and leader.outgoing[follow].result == ResultCode.FAILED
    assert leader.outgoing[follow].reason == Reason.LINK_LOST
    ended = follower.finished[-1]
    assert (ended.name, ended.result, ended.code) == ("follow", ResultCode.FAILED, Reason.LINK_LOST)
    assert follower.behaviour == "idle" and team.bodies["robot_2"].command == (0.0, 0.0)
    del home


def test_a_follower_heard_again_within_the_window_resumes():
    team = two_robots()
    leader, follower = team.brains["robot_1"], team.brains["robot_2"]
    leader.command_follow(TWO, 0.0)
    team.run(2.0)
    there = team.bodies["robot_2"].pose()
    far_away(team, "robot_2")
    team.run(5.0)  # lost at about 3.5 s
    assert follower.running.behaviour.paused
    team.bodies["robot_2"].teleport(there)  # back within the 5 s window
    team.run(2.0)
    assert ev.LinkResumed in team.kinds("robot_1") and ev.LinkResumed in team.kinds("robot_2")
    assert follower.behaviour == "follow" and not follower.running.behaviour.paused
    assert TWO in leader.streams and not leader.streams[TWO].paused
    assert leader.commands_failed == 0


def test_a_follower_whose_leader_stops_streaming_halts_and_then_gives_up():
    # heartbeats keep coming, PoseUpdates do not: a one-way problem the link-loss rule cannot see
    team = two_robots()
    leader, follower = team.brains["robot_1"], team.brains["robot_2"]
    leader.command_follow(TWO, 0.0)
    team.run(2.0)
    leader.streams.clear()  # the leader stops streaming (as a leader that crashed and rebooted would)
    team.run(3.5)
    assert follower.running.behaviour.holding and team.bodies["robot_2"].command == (0.0, 0.0)
    team.run(8.0)
    assert follower.finished[-1].code == Reason.PARTNER_SILENT and follower.behaviour == "idle"


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
    # this used to assert only that a seq came back, so it passed whatever robot_2 answered
    team = two_robots()
    leader, follower = team.brains["robot_1"], team.brains["robot_2"]
    heard = []  # the leader endpoint's events, on their way to its brain (which keeps no record of them)
    pull = leader.endpoint.next_event

    def next_event():
        event = pull()
        if event is not None:
            heard.append(event)
        return event

    leader.endpoint.next_event = next_event
    seq = leader.endpoint.send_pose_update(TWO, Pose(2, 2, 0, 0), 0.0)
    team.run(0.5)
    answers = [(e.src, e.ref_seq, e.ref_type, e.result, e.reason) for e in heard if isinstance(e, ConfirmReceived)]
    assert answers == [(TWO, seq, MessageType.POSE_UPDATE, ResultCode.DENIED, Reason.NOT_FOLLOWING)]
    # and nothing starts, on either side
    assert follower.behaviour == "idle" and follower.running is None
    assert ev.BehaviourStarted not in team.kinds("robot_2")
    assert team.bodies["robot_2"].pose() == Pose2D(1.5, 6.0) and team.bodies["robot_2"].command == (0.0, 0.0)
    assert TWO not in leader.streams


def test_move_around_inside_a_wall_is_denied():
    team = two_robots()
    # a circle of radius 20 m around robot_1 lies wholly outside the 12 m room
    seq = team.brains["robot_1"].send(TWO, MoveAround(Pose(3, 6, 0, 0), 20.0), 0.0)
    team.run(1.0)
    assert team.brains["robot_1"].outgoing[seq].result == ResultCode.DENIED
    assert ev.CommandDenied in team.kinds("robot_2")


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
    starts = [e for e in follower.log if isinstance(e, ev.BehaviourStarted)]
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
    brain = team.brains["robot_1"]
    brain.endpoint = brain.network.endpoint = restarted
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


# --- ForwardMsg, executed: store and forward -----------------------------------------------------


def three_in_a_row():
    """robot_1 hears robot_2, robot_2 hears robot_3; robot_1 and robot_3 are 16 m apart (disc: 10 m)."""
    return Team({"robot_1": Pose2D(1.0, 6.0), "robot_2": Pose2D(9.0, 6.0), "robot_3": Pose2D(17.0, 6.0)})


def test_forward_msg_is_delivered_to_the_target_and_the_sender_gets_done():
    team = three_in_a_row()
    seq = team.brains["robot_1"].send(TWO, ForwardMsg(3, encode_inner(Stop())), 0.0)
    team.run(3.0)
    sent = team.brains["robot_1"].outgoing[seq]
    assert (sent.result, sent.reason) == (ResultCode.DONE, Reason.NONE)
    assert ev.Stopped in team.kinds("robot_3")  # the inner Stop reached robot_3, from robot_2
    assert ev.ForwardSent in team.kinds("robot_2") and ev.ForwardEnded in team.kinds("robot_2")


def test_a_forwarders_final_report_goes_out_in_copies_like_any_final_report():
    # this used to go out once: a lost DONE left the sender at ACCEPTED for good (no resend)
    team = three_in_a_row()
    team.brains["robot_1"].send(TWO, ForwardMsg(3, encode_inner(Stop())), 0.0)
    team.run(3.0)
    reports = [decode_frame(r.frame)[1] for r in team.link.records
               if (r.transmitter, r.src, r.dst, r.relayed) == (TWO, TWO, ONE, False)]
    done = [m for m in reports if isinstance(m, Confirm) and m.result == ResultCode.DONE]
    assert len(done) == BrainConfig().final_report_copies == 3


def test_forward_msg_waits_for_an_unreachable_target_and_delivers_when_it_comes_back():
    team = three_in_a_row()
    far_away(team, "robot_3")
    seq = team.brains["robot_1"].send(TWO, ForwardMsg(3, encode_inner(Return())), 0.0)
    team.run(8.0)
    assert team.brains["robot_1"].outgoing[seq].result == ResultCode.ACCEPTED  # held, not sent
    assert ev.ForwardSent not in team.kinds("robot_2")
    team.bodies["robot_3"].teleport(Pose2D(17.0, 6.0))
    team.run(3.0)
    assert team.brains["robot_1"].outgoing[seq].result == ResultCode.DONE
    assert ev.CommandReceived in team.kinds("robot_3")


def test_forward_msg_to_a_target_never_reachable_fails_with_timeout_after_the_setting():
    team = three_in_a_row()
    far_away(team, "robot_3")
    seq = team.brains["robot_1"].send(TWO, ForwardMsg(3, encode_inner(Stop())), 0.0)
    team.run(29.0)
    assert team.brains["robot_1"].outgoing[seq].result == ResultCode.ACCEPTED
    team.run(2.0)
    sent = team.brains["robot_1"].outgoing[seq]
    assert (sent.result, sent.reason) == (ResultCode.FAILED, Reason.TIMEOUT)


def test_a_long_inner_message_goes_segmented_both_ways():
    team = three_in_a_row()
    blob = bytes(range(256)) * 6  # a 1,536-byte Data: segmented robot_1 -> robot_2 and robot_2 -> robot_3
    inner = encode_inner(Data(DataKind.RAW, 0, blob))
    seq = team.brains["robot_1"].send(TWO, ForwardMsg(3, inner), 0.0)
    team.run(10.0)
    assert team.brains["robot_1"].outgoing[seq].result == ResultCode.DONE
    received = [e for e in team.brains["robot_3"].log if isinstance(e, ev.DataReceived)]
    assert received and (received[0].size, received[0].src, received[0].data_kind) == (1536, TWO, DataKind.RAW)
    assert team.link.stats.segment_transmissions >= 2 * len(inner) // 16


@pytest.mark.parametrize("target, inner, reason", [
    (2, encode_inner(Stop()), Reason.UNKNOWN_TARGET),  # to the forwarder itself
    (255, encode_inner(Stop()), Reason.UNKNOWN_TARGET),
    (3, b"\x3f", Reason.BAD_REQUEST),  # not a message type
    (3, b"\x06\x00", Reason.BAD_REQUEST),  # a Stop with a payload
])
def test_forward_msg_that_cannot_be_done_is_denied_with_the_reason(target, inner, reason):
    team = three_in_a_row()
    seq = team.brains["robot_1"].send(TWO, ForwardMsg(target, inner), 0.0)
    team.run(1.0)
    sent = team.brains["robot_1"].outgoing[seq]
    assert (sent.result, sent.reason) == (ResultCode.DENIED, reason)


# --- Goto, Return, priorities ------------------------------------------------------------------------


def test_goto_reports_accepted_progress_and_done_at_the_goal():
    team = two_robots()
    leader = team.brains["robot_1"]
    seq = leader.command_goto(TWO, Pose2D(8.0, 9.0, 1.0), 0.0)
    reports = []
    for _ in range(40):
        team.run(0.5)
        reports.append((leader.outgoing[seq].result, team.brains["robot_1"].endpoint.stats.confirms_received))
        if leader.outgoing[seq].result == ResultCode.DONE:
            break
    assert leader.outgoing[seq].result == ResultCode.DONE
    end = team.bodies["robot_2"].pose()
    assert end.distance_to(Pose2D(8.0, 9.0)) <= 0.15 and abs(end.yaw - 1.0) <= 0.3
    results = [e.result for e in leader.log if isinstance(e, ev.Confirm) and e.seq == seq]
    assert results[0] is ResultCode.ACCEPTED and ResultCode.IN_PROGRESS in results and results[-1] is ResultCode.DONE


def test_return_drives_back_to_the_base():
    team = two_robots()
    team.brains["robot_2"].config = replace(team.brains["robot_2"].config, base=Pose2D(1.5, 6.0, 0.0))
    leader = team.brains["robot_1"]
    leader.command_goto(TWO, Pose2D(6.0, 9.0, 0.0), 0.0)
    team.run(15.0)
    seq = leader.command_return(TWO, team.time)
    team.run(20.0)
    assert leader.outgoing[seq].result == ResultCode.DONE
    assert team.bodies["robot_2"].pose().distance_to(Pose2D(1.5, 6.0)) <= 0.15


def three_with_ranks():
    team = Team({"robot_1": Pose2D(3.0, 6.0), "robot_2": Pose2D(1.5, 6.0), "robot_3": Pose2D(1.5, 3.0)})
    ranks = {1: Rank.TEAM_LEAD, 3: Rank.PEER}
    for brain in team.brains.values():
        brain.config = replace(brain.config, ranks=ranks)
    return team


def test_a_lower_ranked_goto_is_temporarily_rejected_while_a_team_lead_is_followed():
    team = three_with_ranks()
    follow = team.brains["robot_1"].command_follow(TWO, 0.0)
    team.run(1.0)
    goto = team.brains["robot_3"].command_goto(TWO, Pose2D(8.0, 2.0), team.time)
    team.run(1.0)
    sent = team.brains["robot_3"].outgoing[goto]
    assert (sent.result, sent.reason) == (ResultCode.TEMPORARILY_REJECTED, Reason.MOTION_HELD)
    assert team.brains["robot_2"].behaviour == "follow" and team.brains["robot_1"].outgoing[follow].result == ResultCode.ACCEPTED


def test_a_higher_rank_preempts_and_the_preempted_sender_gets_cancelled_with_the_reason():
    team = three_with_ranks()
    for brain in team.brains.values():
        brain.config = replace(brain.config, ranks={1: Rank.TEAM_LEAD, 3: Rank.OPERATOR})
    follow = team.brains["robot_1"].command_follow(TWO, 0.0)
    team.run(1.0)
    goto = team.brains["robot_3"].command_goto(TWO, Pose2D(8.0, 2.0), team.time)
    team.run(1.0)
    assert team.brains["robot_3"].outgoing[goto].result in (ResultCode.ACCEPTED, ResultCode.IN_PROGRESS)
    sent = team.brains["robot_1"].outgoing[follow]
    assert (sent.result, sent.reason) == (ResultCode.CANCELLED, Reason.REPLACED)
    assert team.brains["robot_2"].behaviour == "navigate"


def test_stop_always_wins_even_from_a_peer():
    team = three_with_ranks()
    team.brains["robot_1"].command_follow(TWO, 0.0)
    team.run(1.0)
    stop = team.brains["robot_3"].command_stop(TWO, team.time)
    team.run(1.0)
    assert team.brains["robot_3"].outgoing[stop].result == ResultCode.DONE and team.brains["robot_2"].behaviour == "idle"


# --- ShowScan, ShowCam --------------------------------------------------------------------------------


def fake_scan(body, stamp=0.0):
    import numpy as np

    from rescuemesh.body import LaserScan

    return LaserScan(stamp, body.pose(), -2.0, 4.0 / 99, 0.02, 5.6, np.full(100, np.inf))  # no returns: open room


def test_show_scan_drives_within_sight_faces_the_position_and_sends_the_scans_asked_for():
    team = two_robots()
    body = team.bodies["robot_2"]
    body.scan = lambda: fake_scan(body, team.time)
    seq = team.brains["robot_1"].send(TWO, ShowScan(Pose(9.0, 9.0, 0, 0), 0.5, 3), 0.0)
    team.run(30.0)
    leader = team.brains["robot_1"]
    assert leader.outgoing[seq].result == ResultCode.DONE
    scans = [d for d in leader.received_data if d[2] == DataKind.LASER_SCAN and d[3] == seq]
    assert len(scans) == 3
    pose = body.pose()
    assert pose.distance_to(Pose2D(9.0, 9.0)) <= 5.0  # it moved within the laser's reach
    assert abs(math.remainder(math.atan2(9.0 - pose.y, 9.0 - pose.x) - pose.yaw, 2 * math.pi)) < 0.1


def test_show_cam_on_a_body_that_cannot_render_fails_with_no_renderer():
    team = two_robots()
    seq = team.brains["robot_1"].send(TWO, ShowCam(Pose(2.0, 6.5, 0, 0), 1.0, 1), 0.0)
    team.run(3.0)
    sent = team.brains["robot_1"].outgoing[seq]
    assert (sent.result, sent.reason) == (ResultCode.FAILED, Reason.NO_RENDERER)


def test_show_scan_without_a_laser_is_unsupported_with_the_missing_sensor():
    team = two_robots()
    team.brains["robot_2"].config = replace(team.brains["robot_2"].config, has_laser=False)
    seq = team.brains["robot_1"].send(TWO, ShowScan(Pose(2.0, 6.5, 0, 0), 1.0, 1), 0.0)
    team.run(1.0)
    sent = team.brains["robot_1"].outgoing[seq]
    assert (sent.result, sent.reason) == (ResultCode.UNSUPPORTED, Reason.NO_SENSOR)


def test_robots_announce_their_capabilities_and_peers_can_look_them_up_before_asking():
    from rescuemesh.protocol.messages import Capability

    team = two_robots()
    team.brains["robot_2"].config = replace(team.brains["robot_2"].config, has_camera=False)
    team.run(1.5)
    seen = team.brains["robot_1"].capabilities_of(TWO)
    assert seen == Capability.LASER | Capability.RELAY  # a ground robot, laser, no camera, relays
    assert Capability.CAMERA not in seen and Capability.FLYING not in seen
    assert team.brains["robot_2"].capabilities_of(ONE) == Capability.CAMERA | Capability.LASER | Capability.RELAY


def test_a_show_scan_of_a_spot_in_sight_runs_beside_the_drive_without_turning_it():
    team = three_with_ranks()
    body = team.bodies["robot_2"]
    body.scan = lambda: fake_scan(body, team.time)
    follow = team.brains["robot_1"].command_follow(TWO, 0.0)
    team.run(1.0)
    ahead = body.pose()
    spot = Pose(ahead.x + 3.0 * math.cos(ahead.yaw), ahead.y + 3.0 * math.sin(ahead.yaw), 0, 0)
    scan = team.brains["robot_3"].send(TWO, ShowScan(spot, 0.5, 2), team.time)  # a peer, lower than the lead
    team.run(3.0)
    assert team.brains["robot_3"].outgoing[scan].result == ResultCode.DONE
    assert len([d for d in team.brains["robot_3"].received_data if d[3] == scan]) == 2
    assert team.brains["robot_2"].behaviour == "follow"  # the Follow was never interrupted
    assert team.brains["robot_1"].outgoing[follow].result == ResultCode.ACCEPTED


def test_a_show_scan_that_would_need_a_turn_waits_for_the_drive_to_end():
    team = three_with_ranks()
    body = team.bodies["robot_2"]
    body.scan = lambda: fake_scan(body, team.time)
    team.brains["robot_1"].command_follow(TWO, 0.0)
    team.run(1.0)
    behind = body.pose()
    spot = Pose(behind.x - 2.0 * math.cos(behind.yaw), behind.y - 2.0 * math.sin(behind.yaw), 0, 0)
    scan = team.brains["robot_3"].send(TWO, ShowScan(spot, 0.5, 1), team.time)
    team.run(1.0)
    sent = team.brains["robot_3"].outgoing[scan]
    assert (sent.result, sent.reason) == (ResultCode.TEMPORARILY_REJECTED, Reason.MOTION_HELD)
