"""A resend after a lost epoch, and a segmented frame's transfer after its endpoint stops waiting:
real network stacks (endpoint + mesh node, authenticated) on test_node_security's in-memory air.

Found by running every mission on seeds 0-4 at --loss 0.2: in forwarded-show-scan (seed 2), robot_2
missed robot_1's first two Heartbeats, so it could not open any of robot_1's ForwardMsgs, and each
of those segmented frames was given up after one air round while its transfer went on, delivering
the command after robot_1 had given it up and holding the next one back."""

from __future__ import annotations

from rescuemesh.protocol import (CommandReceived, ConfirmReceived, DeliveryFailed, ForwardMsg, Follow, MessageType,
                                 Pose, ResultCode, Stop)

from .test_node_security import Air, events
from .test_node_security import stack as secure_stack


def stack(address: int, announce: bool = True):
    return secure_stack(address, relay=False, announce=announce)


def heartbeat(data: bytes) -> bool:
    return (data[1] & 0x3F) == MessageType.HEARTBEAT


def test_a_robot_that_missed_our_heartbeat_learns_our_epoch_before_our_resend():
    a, b = stack(1), stack(2)
    lost = {"first heartbeat of a": True}

    def lose(sender, receiver, data):  # a's first Heartbeat never reaches b
        if sender == 1 and heartbeat(data) and lost["first heartbeat of a"]:
            lost["first heartbeat of a"] = False
            return True
        return False

    air = Air([a, b], lose=lose)
    a.endpoint.send_heartbeat(air.now)
    b.endpoint.send_heartbeat(air.now)
    air.pump()
    seq = a.endpoint.send_command(2, Stop(), air.now)
    air.pump(until=0.2)  # the first send at 0, the resend at 0.15 s
    assert b.node.stats.dropped_unknown_epoch == 1  # the first send: b cannot open it
    assert a.endpoint.stats.epoch_announcements == 1 and a.endpoint.stats.retries == 1
    assert [e.seq for e in events(b) if isinstance(e, CommandReceived)] == [seq]
    b.endpoint.confirm(1, seq, MessageType.STOP, ResultCode.DONE, air.now)
    air.pump()
    air.pump(until=1.0)
    assert any(isinstance(e, ConfirmReceived) and e.ref_seq == seq for e in events(a))
    assert a.endpoint.stats.epoch_announcements == 1


def test_without_the_announcement_every_send_goes_unopened_and_the_command_is_given_up():
    a, b = stack(1, announce=False), stack(2)
    air = Air([a, b], lose=lambda sender, receiver, data: sender == 1 and heartbeat(data))
    a.endpoint.send_heartbeat(air.now)
    air.pump()
    a.endpoint.send_command(2, Stop(), air.now)
    air.pump(until=1.0)
    assert b.node.stats.dropped_unknown_epoch == 3
    assert a.endpoint.stats.epoch_announcements == 0
    assert any(isinstance(e, DeliveryFailed) for e in events(a))


def test_a_robot_that_has_answered_us_gets_no_announcement():
    a, b = stack(1), stack(2)
    confirms_lost = {"on": False}
    air = Air([a, b], lose=lambda sender, receiver, data: confirms_lost["on"] and sender == 2)
    for s in (a, b):
        s.endpoint.send_heartbeat(air.now)
    air.pump()
    seq = a.endpoint.send_command(2, Stop(), air.now)
    air.pump()
    b.endpoint.confirm(1, seq, MessageType.STOP, ResultCode.DONE, air.now)
    air.pump(until=0.1)  # confirmed: b has opened a frame of ours
    assert a.endpoint.stats.retries == 0
    confirms_lost["on"] = True
    follow = a.endpoint.send_command(2, Follow(Pose(1, 2, 0, 0)), air.now)
    air.pump()
    b.endpoint.confirm(1, follow, MessageType.FOLLOW, ResultCode.ACCEPTED, air.now)  # lost
    air.pump(until=2.0)
    assert a.endpoint.stats.retries == 2 and a.endpoint.stats.epoch_announcements == 0


def test_resends_to_two_silent_robots_at_once_announce_the_epoch_once():
    a, b, c = stack(1), stack(2), stack(3)
    air = Air([a, b, c], lose=lambda sender, receiver, data: sender == 1)  # nothing of a's arrives
    a.endpoint.send_heartbeat(air.now)
    air.pump()
    a.endpoint.send_command(2, Stop(), air.now)
    a.endpoint.send_command(3, Stop(), air.now)
    air.pump(until=0.2)  # one resend each, at the same instant
    assert a.endpoint.stats.retries == 2 and a.endpoint.stats.epoch_announcements == 1


def test_a_segmented_frame_given_up_by_its_endpoint_is_not_delivered_later_nor_holds_the_next_back():
    a, b = stack(1), stack(2)
    deaf = {"on": False}
    air = Air([a, b], lose=lambda sender, receiver, data: deaf["on"])
    for s in (a, b):
        s.endpoint.send_heartbeat(air.now)
    air.pump()
    deaf["on"] = True
    first = a.endpoint.send_command(2, ForwardMsg(3, b"\x05" * 11), air.now)  # 22 bytes: one segment
    air.pump(until=1.0)
    assert [e.seq for e in events(a) if isinstance(e, DeliveryFailed)] == [first]
    assert a.node.stats.transfers_abandoned == 1
    assert a.node.stats.segments_sent == 3  # a round for each of the endpoint's sends (0, 0.18, 0.36 s)
    deaf["on"] = False
    second = a.endpoint.send_command(2, ForwardMsg(3, b"\x06" * 11), air.now)
    air.pump(until=1.1)
    assert [e.seq for e in events(b) if isinstance(e, CommandReceived)] == [second]  # never the given-up one
    assert a.node.stats.segments_sent == 4


def test_a_commander_that_cannot_open_our_acks_gets_our_epoch_and_confirm_when_it_resends_segments():
    # b's Heartbeats never reach a, so a cannot open b's SegmentAck or Confirm; a's resend puts its
    # segment on the air again; b's node recognises a frame it has reassembled (SegmentsResent), and
    # b's endpoint repeats its Heartbeat (free of loss) and its cached Confirm
    a, b = stack(1), stack(2)
    air = Air([a, b], lose=lambda sender, receiver, data: sender == 2 and heartbeat(data)
              and b.endpoint.stats.epoch_announcements == 0)
    for s in (a, b):
        s.endpoint.send_heartbeat(air.now)
    air.pump()
    seq = a.endpoint.send_command(2, ForwardMsg(3, b"\x05" * 11), air.now)  # one segment
    air.pump()
    assert [e.seq for e in events(b) if isinstance(e, CommandReceived)] == [seq]
    b.endpoint.confirm(1, seq, MessageType.FORWARD_MSG, ResultCode.ACCEPTED, air.now)
    air.pump(until=0.1)
    assert a.node.stats.dropped_unknown_epoch == 2  # b's SegmentAck and Confirm
    air.pump(until=0.2)  # a's resend at 0.18 s: a round of the transfer
    assert b.node.stats.segments_late == 1 and b.endpoint.stats.epoch_announcements == 1
    assert any(isinstance(e, ConfirmReceived) and e.ref_seq == seq for e in events(a))
    assert a.node.stats.transfers_abandoned == 1  # the Confirm ended the transfer
    assert not [e for e in events(b) if isinstance(e, CommandReceived)]  # nothing delivered twice


def test_announcements_for_one_robot_stop_after_three():
    a, b = stack(1), stack(2)
    air = Air([a, b], lose=lambda sender, receiver, data: sender == 1)  # nothing of a's arrives
    a.endpoint.send_heartbeat(air.now)
    air.pump()
    for _ in range(3):
        a.endpoint.send_command(2, Stop(), air.now)
        air.pump(until=air.now + 1.0)  # 2 resends each
    assert a.endpoint.stats.retries == 6 and a.endpoint.stats.epoch_announcements == 3
