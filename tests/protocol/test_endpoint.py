"""Two (or three) endpoints over an in-memory link with a fake clock and scripted loss."""

from __future__ import annotations

import math
import zlib

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rescuemesh.protocol import (
    CommandReceived, ConfirmReceived, DataKind, DataReceived, DeliveryFailed, EncodeError, Endpoint,
    EndpointConfig, Follow, FrameRejected, Goto, HeartbeatReceived, MessageType, MoveAround, Pose,
    PoseUpdateReceived, Reason, ReliabilityConfig, ResultCode, Return, Stop, decode_frame, encode_frame)
from rescuemesh.protocol.codec import DEFAULT_TTL, MAX_CONTROL_FRAME_BYTES, FrameFlags, Header
from rescuemesh.protocol.messages import Confirm, Heartbeat, PoseUpdate, SegmentAck

from .link import Link, drain
from .strategies import frames as valid_frames

P = Pose(1.5, -2.25, 0.0, math.pi / 2)  # exactly representable on the wire
T, R = MessageType, ResultCode


def pair(drop=None, **config):
    a = Endpoint(1, EndpointConfig(**config))
    b = Endpoint(2)
    return a, b, Link([a, b], drop=drop)


def attempt_bits(data: bytes) -> int:
    return data[1] >> 6


def test_command_confirmed_first_try():
    a, b, link = pair()
    seq = a.send_command(2, Goto(P), link.now)
    link.pump()
    assert drain(b) == [CommandReceived(1, seq, Goto(P), 0.0)]
    link.now = 0.02
    b.confirm(1, seq, T.GOTO, R.ACCEPTED, link.now)
    link.pump()
    assert drain(a) == [ConfirmReceived(2, seq, T.GOTO, R.ACCEPTED, 255, True, 1, 0.02, 0.02)]
    assert a.get_timer() is None
    assert len(link.log) == 2
    assert (a.stats.frames_sent, a.stats.retries, a.stats.confirms_received) == (1, 0, 1)
    assert (b.stats.frames_received, b.stats.confirms_sent) == (1, 1)


def test_lost_command_is_resent_with_attempt_bits_and_confirmed():
    a, b, link = pair(drop={0})
    seq = a.send_command(2, Stop(), 0.0)
    link.pump()
    assert drain(b) == [] and a.get_timer() == 0.15
    link.run_until(0.15)
    first, resend = link.sent_by(1)
    assert (attempt_bits(first.data), attempt_bits(resend.data)) == (0, 1)
    assert resend.data[4:6] == first.data[4:6] == seq.to_bytes(2, "big")  # same seq
    assert drain(b) == [CommandReceived(1, seq, Stop(), 0.15)]
    link.now = 0.2
    b.confirm(1, seq, T.STOP, R.DONE, link.now)
    link.pump()
    (event,) = drain(a)
    assert event.solicited and event.sends == 2 and event.rtt_s == pytest.approx(0.05)
    assert a.stats.retries == 1 and a.get_timer() is None


def test_lost_confirm_is_repaired_from_the_cache_without_a_second_command_event():
    a, b, link = pair(drop={1})
    seq = a.send_command(2, Follow(P), 0.0)
    link.pump()
    assert [type(e) for e in drain(b)] == [CommandReceived]
    b.confirm(1, seq, T.FOLLOW, R.ACCEPTED, 0.0)
    link.pump()  # frame 1, the Confirm, is lost
    assert drain(a) == []
    link.run_until(0.15)  # frame 2: resend; frame 3: the cached Confirm again
    assert drain(b) == []
    (event,) = drain(a)
    assert (event.result, event.solicited, event.sends) == (R.ACCEPTED, True, 2)
    # the same Confirm again, under a fresh sequence number (replay protection accepts each once)
    first, again = decode_frame(link.log[1].data), decode_frame(link.log[3].data)
    assert again[1] == first[1] and again[0].seq == first[0].seq + 1
    assert (b.stats.duplicates, b.stats.confirms_sent) == (1, 2)


def test_three_lost_sends_then_delivery_failed():
    a, b, link = pair()
    link.drop_all_from = {1}
    seq = a.send_command(2, MoveAround(P, 2.0), 0.0)
    link.pump()
    link.run_until(2.0)
    sends = link.sent_by(1)
    assert [attempt_bits(s.data) for s in sends] == [0, 1, 2]
    assert [s.now for s in sends] == pytest.approx([0.0, 0.15, 0.30])
    (event,) = drain(a)
    assert isinstance(event, DeliveryFailed)
    assert (event.dst, event.seq, event.message, event.sends) == (2, seq, MoveAround(P, 2.0), 3)
    assert event.now == pytest.approx(0.45)
    assert a.get_timer() is None
    assert (a.stats.delivery_failures, a.stats.retries, a.stats.frames_sent) == (1, 2, 3)


def test_unsolicited_done_report_after_accepted():
    a, b, link = pair()
    seq = a.send_command(2, MoveAround(P, 2.0), 0.0)
    link.pump()
    drain(b)
    b.confirm(1, seq, T.MOVE_AROUND, R.ACCEPTED, 0.0)
    link.pump()
    assert drain(a)[0].solicited
    link.now = 5.0
    b.confirm(1, seq, T.MOVE_AROUND, R.DONE, 5.0, progress=100)
    link.pump()
    assert drain(a) == [ConfirmReceived(2, seq, T.MOVE_AROUND, R.DONE, 100, False, 0, None, 5.0)]
    # a late resend of the command now gets the latest word, DONE
    b.receive(link.log[0].data, 5.1)
    (again,) = b.frames_to_send(5.1)
    assert decode_frame(again)[1] == Confirm(seq, T.MOVE_AROUND, R.DONE, 100)
    with pytest.raises(ValueError):  # nothing may follow a final result
        b.confirm(1, seq, T.MOVE_AROUND, R.CANCELLED, 5.2)


def test_in_progress_reports_then_failed():
    a, b, link = pair()
    seq = a.send_command(2, Goto(P), 0.0)
    link.pump()
    for result, progress in [(R.IN_PROGRESS, 0), (R.IN_PROGRESS, 50), (R.FAILED, 255)]:
        b.confirm(1, seq, T.GOTO, result, link.now, progress=progress)
        link.pump()
    events = drain(a)
    assert [(e.result, e.progress, e.solicited) for e in events] == [
        (R.IN_PROGRESS, 0, True), (R.IN_PROGRESS, 50, False), (R.FAILED, 255, False),
    ]


def test_broadcast_heartbeat_reaches_everyone_unconfirmed():
    a, b, c = Endpoint(1), Endpoint(2), Endpoint(3)
    link = Link([a, b, c])
    a.send_heartbeat(0.0, active_command=T.FOLLOW)
    link.pump()
    for ep in (b, c):
        assert drain(ep) == [HeartbeatReceived(1, T.FOLLOW, 0.0)]
    (sent,) = link.log
    header, message = decode_frame(sent.data)
    assert (header.dst, header.ttl, message) == (0xFF, DEFAULT_TTL, Heartbeat(1, DEFAULT_TTL))
    assert a.get_timer() is None


def test_frames_for_another_address_are_ignored_and_counted():
    a, b, link = pair()
    a.send_command(3, Stop(), 0.0)
    link.pump()
    assert drain(b) == [] and b.frames_to_send(0.0) == []
    assert (b.stats.frames_received, b.stats.frames_not_for_us) == (1, 1)


def test_own_frames_heard_back_are_ignored():
    a = Endpoint(1)
    a.send_heartbeat(0.0)
    (frame,) = a.frames_to_send(0.0)
    a.receive(frame, 0.0)
    assert drain(a) == [] and a.stats.frames_not_for_us == 1


def test_sequence_numbers_wrap_around_65535():
    a, b, link = pair(initial_seq=65535)
    first = a.send_command(2, Stop(), 0.0)
    second = a.send_command(2, Return(), 0.0)
    assert (first, second) == (65535, 0)
    link.pump()
    received = drain(b)
    assert [(e.seq, e.command) for e in received] == [(65535, Stop()), (0, Return())]
    for e in received:
        b.confirm(1, e.seq, type(e.command).TYPE, R.DONE, 0.0)
    link.pump()
    # number 0 opened epoch 1 and gave the Stop (65535, epoch 0) up: its late Confirm answers nothing
    events = drain(a)
    assert [type(e).__name__ for e in events] == ["DeliveryFailed", "ConfirmReceived"]
    assert (events[0].seq, events[1].ref_seq, a.epoch) == (65535, 0, 1) and a.stats.confirms_unmatched == 1
    assert a.get_timer() is None


def test_a_wrap_starts_a_new_epoch_and_gives_up_what_awaits_a_confirm():
    # this used to skip the seqs still in flight and resend them later: under a new epoch those
    # resends would reuse numbers of the new epoch, so an authenticated nonce could repeat
    a = Endpoint(1, EndpointConfig(initial_epoch=7))
    assert a.send_command(2, Stop(), 0.0) == 0  # never confirmed: still pending at the wrap
    for _ in range(65535):  # seqs 1..65535
        a.send_heartbeat(0.0)
    frames = a.drain(0.0)
    assert (frames[0][1], frames[-1][1]) == (7, 7) and a.epoch == 7  # 0..65535 all in epoch 7
    assert a.send_command(2, Return(), 0.0) == 0  # number 0 again: epoch 8
    assert a.epoch == 8 and a.stats.epochs == 1 and a.drain(0.0)[0][1] == 8
    (failed,) = drain(a)
    assert isinstance(failed, DeliveryFailed) and failed.seq == 0 and failed.message == Stop()
    assert a.get_timer() == pytest.approx(0.15)  # only the new Return is pending


def test_pose_update_stream_with_loss_delivers_each_update_once():
    a, b, link = pair(drop={0, 4, 5, 9, 14})  # lost updates, lost confirms, a lost resend
    sent, received = [], []
    for k in range(20):  # 2 Hz for 10 s
        link.run_until(0.5 * k)
        sent.append(a.send_pose_update(2, Pose(0.1 * k, 0.0, 0.0, 0.0), link.now))
        link.pump()
        for _ in range(4):  # the follower answers every update; resends come 0.15 s apart
            for event in drain(b):
                received.append(event.seq)
                b.confirm(1, event.seq, T.POSE_UPDATE, R.ACCEPTED, link.now)
            link.pump()
            link.run_until(link.now + 0.1)
    events = drain(a)
    assert sorted(received) == sorted(sent)  # each update reached the application exactly once
    assert sorted(e.ref_seq for e in events if e.solicited) == sorted(sent)
    assert not any(isinstance(e, DeliveryFailed) for e in events)
    assert a.stats.retries >= 3 and b.stats.duplicates >= 1


def test_pose_update_is_confirmed_or_denied():
    a, b, link = pair()
    seq = a.send_pose_update(2, P, 0.0)
    link.pump()
    assert drain(b) == [PoseUpdateReceived(1, seq, P, 0.0)]
    b.confirm(1, seq, T.POSE_UPDATE, R.DENIED, 0.0)
    link.pump()
    (event,) = drain(a)
    assert (event.ref_type, event.result, event.solicited) == (T.POSE_UPDATE, R.DENIED, True)


def test_resend_before_the_application_confirms_is_dropped_silently():
    a, b, link = pair()
    link.drop_all_from = {2}  # nothing from b arrives yet
    seq = a.send_command(2, Stop(), 0.0)
    link.pump()
    assert len(drain(b)) == 1
    link.run_until(0.15)
    assert drain(b) == [] and b.stats.duplicates == 1 and len(link.sent_by(2)) == 0
    link.drop_all_from = set()
    b.confirm(1, seq, T.STOP, R.DONE, 0.2)
    link.pump()
    (event,) = drain(a)
    assert event.solicited and event.sends == 2


def test_a_restarted_sender_reusing_a_seq_is_not_taken_for_a_resend():
    a, b, link = pair()
    a.send_command(2, Follow(P), 0.0)
    link.pump()
    b.confirm(1, drain(b)[0].seq, T.FOLLOW, R.ACCEPTED, 0.0)
    link.pump()
    restarted = Endpoint(1)  # seq starts at 0 again
    link.endpoints[0] = restarted
    link.now = 1.0
    restarted.send_command(2, Stop(), link.now)
    link.pump()
    assert drain(b) == [CommandReceived(1, 0, Stop(), 1.0)]


def test_confirm_from_another_robot_does_not_stop_retries():
    a = Endpoint(1)
    seq = a.send_command(2, Stop(), 0.0)
    a.frames_to_send(0.0)
    header = Header(1, FrameFlags.NONE, 3, 0, T.CONFIRM, 3, 1, 0)  # from robot 3, not 2
    a.receive(encode_frame(header, Confirm(seq, T.STOP, R.DONE)), 0.0)
    assert drain(a) == [] and a.stats.confirms_unmatched == 1  # answers nothing we sent robot 3
    assert a.get_timer() == 0.15


def test_a_second_copy_of_a_final_confirm_answers_nothing_and_is_dropped():
    # this used to be reported as an unsolicited Confirm: any Confirm counted, outstanding or not
    a, b, link = pair()
    seq = a.send_command(2, Stop(), 0.0)
    link.pump()
    b.confirm(1, seq, T.STOP, R.DONE, 0.0)
    (frame,) = b.frames_to_send(0.0)
    a.receive(frame, 0.0)
    a.receive(frame, 0.01)
    assert [e.solicited for e in drain(a)] == [True] and a.stats.confirms_unmatched == 1


def test_after_an_interim_answer_the_final_report_is_accepted_once():
    a, b, link = pair()
    seq = a.send_command(2, Follow(P), 0.0)
    link.pump()
    b.confirm(1, seq, T.FOLLOW, R.ACCEPTED, 0.0)
    b.confirm(1, seq, T.FOLLOW, R.IN_PROGRESS, 0.1, progress=50)
    b.confirm(1, seq, T.FOLLOW, R.DONE, 0.2)
    frames = b.frames_to_send(0.2)
    for frame in frames + frames[-1:]:  # the final report heard twice
        a.receive(frame, 0.3)
    assert [(e.result, e.solicited) for e in drain(a)] == [(R.ACCEPTED, True), (R.IN_PROGRESS, False), (R.DONE, False)]
    assert a.stats.confirms_unmatched == 1


def test_a_restarted_peer_is_forgotten_so_its_new_seq_0_is_a_new_command():
    # this used to answer a rebooted robot's first new command from the old cache, unexecuted
    a, b, link = pair()
    seq = a.send_command(2, Stop(), 0.0)
    link.pump()
    drain(b)
    b.confirm(1, seq, T.STOP, R.DONE, 0.0)
    link.pump()
    rebooted = Endpoint(1)  # seq 0 again, same message
    link.endpoints[0] = rebooted
    b.forget_peer(1)  # what the mesh layer's new-epoch event leads to
    rebooted.send_command(2, Stop(), 1.0)
    link.pump()
    assert [type(e) for e in drain(b)] == [CommandReceived]


def test_cancel_pending_stops_retries_without_delivery_failed():
    a = Endpoint(1)
    a.send_command(2, Stop(), 0.0)
    a.send_command(3, Stop(), 0.0)
    assert a.cancel_pending(2) == 1
    a.handle_timer(0.15)
    assert len(a.frames_to_send(0.15)) == 3  # two first sends, one resend (to robot 3)
    assert a.cancel_pending() == 1
    a.handle_timer(10.0)
    assert a.get_timer() is None and drain(a) == []


@pytest.mark.parametrize(
    "dst, command, error",
    [
        (2, PoseUpdate(P), ValueError),
        (2, Confirm(1, T.STOP, R.DONE), ValueError),
        (2, Heartbeat(0, 3), ValueError),
        (2, "Stop", ValueError),
        (255, Stop(), ValueError),
        (1, Stop(), ValueError),  # our own address
        (300, Stop(), ValueError),
        (-1, Stop(), ValueError),
        (2, Goto(Pose(400.0, 0.0, 0.0, 0.0)), EncodeError),
        (2, MoveAround(P, 0.0), EncodeError),
    ],
)
def test_send_command_refuses(dst, command, error):
    a = Endpoint(1)
    with pytest.raises(error):
        a.send_command(dst, command, 0.0)
    assert a.frames_to_send(0.0) == [] and a.get_timer() is None
    assert a.send_command(2, Stop(), 0.0) == 0  # no seq was used up


def test_confirm_refuses_a_mismatched_type_and_bad_values():
    a, b, link = pair()
    seq = a.send_command(2, Stop(), 0.0)
    link.pump()
    with pytest.raises(ValueError):
        b.confirm(1, seq, T.GOTO, R.DONE, 0.0)
    with pytest.raises(EncodeError):
        b.confirm(1, seq, T.STOP, R.DONE, 0.0, progress=101)
    with pytest.raises(ValueError):
        b.confirm(255, seq, T.STOP, R.DONE, 0.0)
    assert b.frames_to_send(0.0) == []


@pytest.mark.parametrize(
    "make",
    [
        lambda: Endpoint(255),
        lambda: Endpoint(-1),
        lambda: EndpointConfig(initial_ttl=16),
        lambda: EndpointConfig(initial_seq=65536),
        lambda: EndpointConfig(reliability=ReliabilityConfig(max_sends=0)),
    ],
)
def test_bad_endpoint_settings_are_refused(make):
    with pytest.raises(ValueError):
        make()


def test_initial_ttl_is_used_in_headers_and_heartbeats():
    a = Endpoint(1, EndpointConfig(initial_ttl=7))
    a.send_heartbeat(0.0)
    a.send_command(2, Stop(), 0.0)
    for frame in a.frames_to_send(0.0):
        header, message = decode_frame(frame)
        assert header.ttl == 7
    assert message == Stop()


def test_stats():
    a, b, link = pair()
    seq = a.send_command(2, MoveAround(P, 2.0), 0.0)
    link.pump()
    b.confirm(1, seq, T.MOVE_AROUND, R.ACCEPTED, 0.0)
    link.pump()
    assert a.stats.as_dict() == {
        "frames_sent": 1, "broadcasts_sent": 0, "bytes_sent": 20, "max_frame_bytes": 20, "retries": 0,
        "confirms_sent": 0, "confirms_received": 1, "delivery_failures": 0, "duplicates": 0,
        "frames_rejected": 0, "frames_not_for_us": 0, "frames_received": 1, "confirms_unmatched": 0, "epochs": 0,
        "epoch_announcements": 0,
    }
    assert b.stats.max_frame_bytes == 16 and b.stats.confirms_sent == 1


# --- receive() never raises ---------------------------------------------------------------------


def test_a_corrupt_frame_becomes_a_frame_rejected_event():
    a = Endpoint(1)
    a.send_command(2, Stop(), 0.0)
    (frame,) = a.frames_to_send(0.0)
    b = Endpoint(2)
    b.receive(frame[:-1] + bytes([frame[-1] ^ 1]), 3.0)
    assert drain(b) == [FrameRejected("CRC-32 mismatch", "IntegrityError", 3.0)]
    assert b.stats.frames_rejected == 1


@given(st.lists(st.binary(max_size=24), max_size=5))
def test_receive_never_raises_for_arbitrary_bytes(frames):
    ep = Endpoint(2)
    for raw in frames:
        ep.receive(raw, 0.0)
    events = drain(ep)
    rejected = [e for e in events if isinstance(e, FrameRejected)]
    assert ep.stats.frames_received == len(frames)
    assert ep.stats.frames_rejected == len(rejected)
    assert all(e.error_type.endswith(("Frame", "Error", "Version", "Type", "Payload", "Feature")) for e in rejected)


#: Header and payload of a frame under a good CRC: arbitrary bytes (version 1, no flags), or a valid
#: frame for robot 2 (which the endpoint answers) or robot 3.
GOOD_CRC_BODIES = st.one_of(
    st.tuples(st.integers(0, 15), st.binary(min_size=5, max_size=16)).map(lambda t: bytes([0x40 | t[0]]) + t[1]),
    valid_frames(src=st.integers(0, 4), dst=st.sampled_from([2, 3])).map(lambda f: encode_frame(*f)[:-4]),
)


@given(st.lists(GOOD_CRC_BODIES, max_size=8))
def test_receive_never_raises_for_frames_with_a_good_crc(bodies):
    # this used to check max_frame_bytes on an endpoint that never sent a frame (it answered nothing,
    # and arbitrary bytes almost never make a command for it), so the check always saw 0
    ep = Endpoint(2)
    sent = []
    for body in bodies:
        ep.receive(body + zlib.crc32(body).to_bytes(4, "big"), 0.0)
        for event in drain(ep):  # answer what asks for an answer, as a robot does
            if isinstance(event, CommandReceived):
                ep.confirm(event.src, event.seq, event.command.TYPE, R.DONE, 0.0)
            elif isinstance(event, PoseUpdateReceived):
                ep.confirm(event.src, event.seq, T.POSE_UPDATE, R.DENIED, 0.0, reason=Reason.NOT_FOLLOWING)
            elif isinstance(event, DataReceived):
                ep.confirm(event.src, event.seq, T.DATA, R.ACCEPTED, 0.0)
        sent += ep.frames_to_send(0.0)
    s = ep.stats
    assert s.frames_received == len(bodies)
    assert s.frames_rejected + s.frames_not_for_us <= len(bodies)
    # everything it sent is an answer: a 16-byte Confirm, and max_frame_bytes measured them
    assert all(len(frame) == 16 and decode_frame(frame)[0].msg_type == T.CONFIRM for frame in sent)
    assert s.confirms_sent == len(sent) and s.frames_sent == len(sent)
    assert s.max_frame_bytes == max(map(len, sent), default=0) <= MAX_CONTROL_FRAME_BYTES


@given(st.lists(valid_frames(src=st.integers(0, 4), dst=st.sampled_from([2, 3])), max_size=12))
def test_each_valid_frame_is_one_event_a_duplicate_or_not_for_us(frames):
    ep = Endpoint(2)
    for header, message in frames:
        ep.receive(encode_frame(header, message), 0.0)
        ep.frames_to_send(0.0)
    s = ep.stats
    assert s.frames_rejected == 0 and s.frames_received == len(frames)
    assert len(drain(ep)) == len(frames) - s.frames_not_for_us - s.duplicates - s.confirms_unmatched


# --- hops, bulk data, mesh control frames (the mesh layer below the endpoint) ---------------------


def test_confirm_timeout_grows_by_50_ms_per_hop_beyond_the_first():
    a, b, link = pair(drop=set(range(10)))
    a.set_path_hops(2, 3)  # two relays between us: Bluetooth Mesh SAR timers grow 50 ms per TTL
    a.send_command(2, Stop(), 0.0)
    link.pump()
    assert a.get_timer() == pytest.approx(0.15 + 2 * 0.05)
    a.set_path_hops(2, None)
    a.send_command(2, Return(), 1.0)
    assert a.confirm_timeout_s(2, 10) == pytest.approx(0.15)


def test_a_segmented_frame_waits_for_its_segments_too():
    a = Endpoint(1)
    # 4,000 data bytes: a 4,013-byte logical frame, (4013 - 6) / 16 -> 251 segments of the mesh layer
    assert a.confirm_timeout_s(2, 4013) == pytest.approx(0.15 + 251 * 0.03)


def test_data_is_delivered_once_and_confirmed_like_a_command():
    a, b, link = pair(drop={1})  # the first Confirm is lost: a resends the Data, b answers from its cache
    payload = bytes(range(256)) * 16
    seq = a.send_data(2, DataKind.LASER_SCAN, 9, payload, 0.0)
    link.pump()
    (event,) = drain(b)
    assert event == DataReceived(1, seq, DataKind.LASER_SCAN, 9, payload, 0.0)
    b.confirm(1, seq, T.DATA, R.ACCEPTED, 0.0)
    link.pump()
    link.run_until(10.0)
    assert drain(b) == []  # the resend was recognised: no second DataReceived
    assert [e.result for e in drain(a)] == [R.ACCEPTED]
    assert len(link.sent_by(1)) == 2 and b.stats.duplicates == 1


def test_a_segment_ack_that_reaches_the_endpoint_is_not_for_it():
    b = Endpoint(2)
    b.receive(encode_frame(Header(1, FrameFlags.NONE, 3, 0, T.SEGMENT_ACK, 1, 2, 5), SegmentAck(4, 2, 1)), 0.0)
    assert drain(b) == [] and b.stats.frames_not_for_us == 1


def test_a_final_report_carries_its_reason():
    a, b, link = pair()
    seq = a.send_command(2, Follow(P), 0.0)
    link.pump()
    b.confirm(1, seq, T.FOLLOW, R.ACCEPTED, 0.0)
    b.confirm(1, seq, T.FOLLOW, R.FAILED, 0.5, reason=Reason.LINK_LOST)
    link.pump()
    assert [(e.result, e.reason) for e in drain(a)] == [(R.ACCEPTED, Reason.NONE), (R.FAILED, Reason.LINK_LOST)]


def test_a_final_report_can_be_repeated_under_a_fresh_number_and_counts_once():
    a, b, link = pair()
    seq = a.send_command(2, Follow(P), 0.0)
    link.pump()
    b.confirm(1, seq, T.FOLLOW, R.ACCEPTED, 0.0)
    b.confirm(1, seq, T.FOLLOW, R.CANCELLED, 0.5, reason=Reason.REPLACED)
    assert b.repeat_report(1, seq) and b.repeat_report(1, seq) and not b.repeat_report(1, seq + 99)
    frames = b.frames_to_send(0.5)
    assert len({decode_frame(f)[0].seq for f in frames}) == 4  # ACCEPTED, CANCELLED and two repeats
    for frame in frames:
        a.receive(frame, 0.6)
    assert [e.result for e in drain(a)] == [R.ACCEPTED, R.CANCELLED] and a.stats.confirms_unmatched == 2


def test_heartbeat_received_is_the_dataclass_built_field_by_field():
    """The endpoint builds a HeartbeatReceived straight into its slots (events.heartbeat_received)."""
    import dataclasses
    from rescuemesh.protocol.events import HeartbeatReceived, heartbeat_received
    built = heartbeat_received(4, 16, 2.5, 3, 5)
    assert type(built) is HeartbeatReceived and built == HeartbeatReceived(4, 16, 2.5, 3, 5)
    assert dataclasses.astuple(built) == (4, 16, 2.5, 3, 5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        built.hops = 1
