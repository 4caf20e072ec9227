"""The brain's typed events (robot/events.py) and the command table (robot/commands.py): each event
renders the log text the brain always wrote (result.json, MCAP and timelines keep it), crosses the
control plane as itself, and each command type has one row that the brain follows."""

import json
import typing

import pytest

from rescuemesh.protocol import DataKind, MessageType as T, Reason, ResultCode as R
from rescuemesh.protocol.messages import COMMAND_TYPES
from rescuemesh.protocol import events as protocol_events
from rescuemesh.robot import RobotBrain
from rescuemesh.robot import events as ev
from rescuemesh.robot.commands import COMMANDS, traits
from rescuemesh.robot.policy import Resource
from rescuemesh.robot.records import LinkLossPolicy
from rescuemesh.runtime.processes.control_codec import decode, encode

#: One event of each kind (and each way of rendering one), with the text the brain's old
#: `_note(now, kind, f"...")` lines wrote for it.
RENDERED = [
    (ev.PoseFault(1.0, "robot_1", "pose (400.00, 0.00, 0.00) is outside the wire's range"),
     "pose (400.00, 0.00, 0.00) is outside the wire's range: halted, the pose is not sent"),
    (ev.PoseFaultCleared(1.0, "robot_1", 3.14159, -2.0), "pose (3.14, -2.00) fits the wire again"),
    (ev.CommandSent(1.0, "robot_1", T.FORWARD_MSG, 2, 7), "ForwardMsg to robot_2"),
    (ev.CommandReceived(1.0, "robot_2", T.GOTO, 1, 12, 1), "Goto from robot_1 (seq 12)"),
    (ev.CommandReceived(1.0, "robot_3", T.SHOW_SCAN, 1, 12, 2), "ShowScan from robot_1 (seq 12) (2 hops)"),
    (ev.CommandRejected(1.0, "robot_2", T.GOTO, 3, Reason.MOTION_HELD, T.FOLLOW, 1),
     "Goto from robot_3: MOTION_HELD by FOLLOW from robot_1"),
    (ev.CommandRejected(1.0, "robot_2", T.MOVE_AROUND, 3, Reason.MOTION_HELD, None, None),
     "MoveAround from robot_3: MOTION_HELD by own mission"),
    (ev.CommandDenied(1.0, "robot_2", T.MOVE_AROUND, Reason.BLOCKED),
     "MoveAround: every waypoint is inside an obstacle"),
    (ev.CommandDenied(1.0, "robot_2", T.FORWARD_MSG, Reason.BUSY, 9), "ForwardMsg to 9: BUSY"),
    (ev.CommandFailed(1.0, "robot_2", T.SHOW_CAM, Reason.NO_PATH, "no viewpoint"), "ShowCam: no viewpoint"),
    (ev.CommandGivenUp(1.0, "robot_1", T.FOLLOW, 2, 4, 3), "Follow to robot_2 after 3 sends"),
    (ev.Confirm(1.0, "robot_1", T.FOLLOW, 2, 4, R.ACCEPTED, Reason.NONE, 255, 1), "Follow by robot_2: ACCEPTED"),
    (ev.Confirm(1.0, "robot_1", T.GOTO, 3, 4, R.FAILED, Reason.LINK_LOST, 40, 2),
     "Goto by robot_3: FAILED (LINK_LOST), 2 hops"),
    (ev.FrameRejected(1.0, "robot_1", "bad tag", "AuthenticationError"), "bad tag"),
    (ev.Stopped(1.0, "robot_2", 1), "by robot_1"),
    (ev.WaypointsSkipped(1.0, "robot_2", (3, 4, 11)), "3, 4, 11"),
    (ev.DataSent(1.0, "robot_2", DataKind.LASER_SCAN, 180, 1), "LASER_SCAN 180 B to robot_1"),
    (ev.DataReceived(1.0, "robot_1", DataKind.IMAGE_JPEG, 1536, 2), "IMAGE_JPEG 1536 B from robot_2"),
    (ev.ForwardAccepted(1.0, "robot_2", T.STOP, 3), "Stop for robot_3"),
    (ev.ForwardSent(1.0, "robot_2", T.DATA, 3, 1), "Data to robot_3 for robot_1"),
    (ev.ForwardData(1.0, "robot_2", DataKind.LASER_SCAN, 90, 3, 1), "LASER_SCAN 90 B from robot_3 to robot_1"),
    (ev.ForwardUndelivered(1.0, "robot_2", 3), "to robot_3: will try again while reachable"),
    (ev.ForwardEnded(1.0, "robot_2", R.DONE, Reason.NONE, 3, answered=R.DONE), "DONE: robot_3 answered DONE"),
    (ev.ForwardEnded(1.0, "robot_2", R.FAILED, Reason.TIMEOUT, 3, waited_s=30.0),
     "FAILED TIMEOUT: robot_3 not reached in 30 s"),
    (ev.FollowEnded(1.0, "robot_1", 2, R.DENIED), "robot_2 answered DENIED"),
    (ev.FollowGivenUp(1.0, "robot_1", 2, Reason.LINK_LOST), "robot_2: link lost"),
    (ev.FollowGivenUp(1.0, "robot_1", 2, Reason.PARTNER_SILENT, 10.04), "robot_2: no PoseUpdate confirmed for 10.0 s"),
    (ev.PeerRestarted(1.0, "robot_1", 2, 5), "robot_2 in epoch 5"),
    (ev.TransferFailed(1.0, "robot_1", 2, 3, 9), "to robot_2: 3 of 9 segments acknowledged"),
    (ev.BehaviourStarted(1.0, "robot_2", "follow"), "follow"),
    (ev.BehaviourStarted(1.0, "robot_2", "show-scan", beside=True), "show-scan (beside the drive)"),
    (ev.BehaviourEnded(1.0, "robot_2", "follow", R.FAILED, Reason.LINK_LOST, "link lost"), "follow: FAILED link lost"),
    (ev.BehaviourEnded(1.0, "robot_2", "navigate", R.DONE, Reason.NONE), "navigate: DONE"),
    (ev.LinkLost(1.0, "robot_2", 1, 4.5, LinkLossPolicy.HOLD, window_s=5.0),
     "robot_1 silent since 4.50 s: paused, reconnect window 5 s"),
    (ev.LinkLost(1.0, "robot_2", 1, 4.5, LinkLossPolicy.CONTINUE, "navigate"),
     "robot_1 silent since 4.50 s: navigate continues (link-loss policy continue)"),
    (ev.LinkLost(1.0, "robot_2", 1, 4.5, LinkLossPolicy.RETURN_TO_BASE),
     "robot_1 silent since 4.50 s: returning to base (link-loss policy return_to_base)"),
    (ev.LinkResumed(1.0, "robot_2", 1, 2), "robot_1 heard again (2 hops): resumed"),
    (ev.ReportHeld(1.0, "robot_2", T.GOTO, R.DONE, 1), "GOTO DONE for robot_1, out of reach"),
    (ev.ReportDelivered(1.0, "robot_2", T.GOTO, R.DONE, 1, 12.34), "GOTO DONE to robot_1, held 12.3 s"),
    (ev.ReportDropped(1.0, "robot_2", T.GOTO, R.FAILED, 1, 600.0), "GOTO FAILED for robot_1: not heard in 600 s"),
]


@pytest.mark.parametrize("event, text", RENDERED, ids=[f"{type(e).__name__}-{i}" for i, (e, _) in enumerate(RENDERED)])
def test_each_event_renders_the_logs_text(event, text):
    assert event.detail == text


def test_every_kind_has_one_event_type_and_is_its_old_text():
    assert {type(e) for e, _ in RENDERED} == set(ev.EVENT_TYPES.values())
    for kind, cls in ev.EVENT_TYPES.items():
        assert cls.kind is kind and issubclass(cls, ev.BrainEvent)
    event = ev.Stopped(1.0, "robot_2", 1)
    assert event.kind == "stopped" and json.dumps([event.kind]) == '["stopped"]' and f"{event.kind}" == "stopped"


@pytest.mark.parametrize("event", [e for e, _ in RENDERED], ids=lambda e: type(e).__name__)
def test_every_event_crosses_the_control_plane_as_itself(event):
    copy = decode(encode([event]))[0]
    assert type(copy) is type(event) and copy == event and copy.detail == event.detail


def test_events_are_frozen_values():
    event = ev.Stopped(1.0, "robot_2", 1)
    with pytest.raises(AttributeError):
        event.src = 3
    assert event == ev.Stopped(1.0, "robot_2", 1) and hash(event) == hash(ev.Stopped(1.0, "robot_2", 1))


def test_one_row_per_command_and_each_names_a_handler_of_the_brain():
    assert set(COMMANDS) == COMMAND_TYPES
    for msg_type, row in COMMANDS.items():
        assert callable(getattr(RobotBrain, row.handler, None)), (msg_type, row.handler)
        assert row.motion == (Resource.MOTION in row.resources), msg_type  # a motion command holds the wheels
        assert not row.streamed or row.motion, msg_type  # the sender streams its pose to a moving receiver


def test_the_rows_say_what_each_command_obliges():
    assert {t for t, r in COMMANDS.items() if r.streamed} == {T.FOLLOW, T.LAND_ON_TOP}
    assert {t for t, r in COMMANDS.items() if r.reports_progress} == {
        T.GOTO, T.RETURN, T.MOVE_AROUND, T.SHOW_SCAN, T.SHOW_CAM, T.LAND_ON_TOP}
    assert {t for t, r in COMMANDS.items() if r.motion} == {T.FOLLOW, T.MOVE_AROUND, T.GOTO, T.RETURN, T.LAND_ON_TOP}
    for other in (None, T.POSE_UPDATE, T.DATA):  # not commands: they oblige nothing
        row = traits(other)
        assert not (row.streamed or row.reports_progress or row.motion) and row.resources == Resource.NONE


def test_every_endpoint_event_shares_one_base():
    types = typing.get_args(protocol_events.Event)
    assert types and all(issubclass(t, protocol_events.EndpointEvent) for t in types)
