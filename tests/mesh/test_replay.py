"""The replay window: every authenticated frame accepted once, at any delay; restarts accepted."""

import pytest

from rescuemesh.mesh.replay import ReplayVerdict as V
from rescuemesh.mesh.replay import MAX_SEGMENTED, ReplayWindow, SegmentState


def test_a_frame_is_accepted_once_and_its_replay_at_any_later_time_is_not():
    w = ReplayWindow(window=64)
    assert w.accept(1, 0, 10, 0) is V.ACCEPTED
    assert w.accept(1, 0, 10, 0) is V.REPLAY  # at once
    for seq in range(11, 60):
        w.accept(1, 0, seq, 0)
    assert w.accept(1, 0, 10, 0) is V.REPLAY  # later, still in the window
    for seq in range(60, 200):
        w.accept(1, 0, seq, 0)
    assert w.accept(1, 0, 10, 0) is V.TOO_OLD  # much later: beyond the window


def test_a_genuine_resend_is_accepted_once_even_after_later_frames():
    w = ReplayWindow(window=64)
    w.accept(1, 0, 10, 0)
    w.accept(1, 0, 11, 0)
    w.accept(1, 0, 12, 0)  # the source went on while its frame 10 waited for a Confirm
    assert w.accept(1, 0, 10, 1) is V.ACCEPTED  # the resend (attempt 1)
    assert w.accept(1, 0, 10, 1) is V.REPLAY


def test_frames_out_of_order_within_the_window_are_accepted():
    w = ReplayWindow(window=64)
    for seq in (5, 3, 4, 9, 6):
        assert w.accept(1, 0, seq, 0) is V.ACCEPTED


def test_a_restart_opens_a_new_epoch_and_old_epoch_frames_are_dropped():
    w = ReplayWindow(window=64)
    for seq in range(100):
        w.accept(1, 4, seq, 0)
    assert w.accept(1, 5, 0, 0) is V.NEW_EPOCH  # rebooted: seq 0 again, epoch 5
    assert w.accept(1, 5, 1, 0) is V.ACCEPTED
    assert w.accept(1, 4, 99, 1) is V.OLD_EPOCH  # anything captured before the reboot
    assert w.epoch_of(1) == 5 and w.epoch_of(2) is None


def test_sources_are_apart():
    w = ReplayWindow(window=64)
    w.accept(1, 0, 10, 0)
    assert w.accept(2, 0, 10, 0) is V.ACCEPTED


def test_memory_stays_bounded_by_the_window():
    w = ReplayWindow(window=32)
    for seq in range(10_000):
        w.accept(1, 0, seq, 0)
    assert len(w) <= 2 * 32 + 1


def test_an_unseen_frame_far_older_than_the_newest_is_too_old():
    # a replay of a Heartbeat the receiver never heard must not revive a robot's stale presence
    w = ReplayWindow()
    w.accept(1, 0, 10, 0)
    w.accept(1, 0, 200, 0)
    assert w.accept(1, 0, 100, 0) is V.TOO_OLD and w.accept(1, 0, 150, 0) is V.ACCEPTED


@pytest.mark.parametrize("window", [0, -1, 1.5])
def test_bad_window_is_refused(window):
    with pytest.raises(ValueError):
        ReplayWindow(window)


def test_a_segment_is_accepted_once_per_number_segment_and_round():
    # this used to accept any segment frame again and again within 1,024 numbers of the newest
    w = ReplayWindow(window=8, segment_window=8)
    assert w.accept_segment(1, 0, 3, 0, 0) is V.ACCEPTED
    assert w.accept_segment(1, 0, 3, 0, 0) is V.REPLAY
    assert w.accept_segment(1, 0, 3, 1, 0) is V.ACCEPTED  # another segment of the frame
    assert w.accept_segment(1, 0, 3, 0, 1) is V.ACCEPTED  # the same one retransmitted in round 1
    assert w.accept_segment(1, 0, 3, 0, 5) is V.REPLAY  # round 5 travels as 1: the same bytes again
    assert w.accept_segment(1, 0, 3, 4, 0, b"last+crc") is V.ACCEPTED
    assert w.accept_segment(1, 0, 3, 4, 0, b"last+crc") is V.REPLAY
    assert w.accept_segment(1, 0, 3, 4, 0, b"last+crc2") is V.ACCEPTED  # an endpoint resend's last segment
    for seq in range(4, 20):
        w.accept(1, 0, seq, 0)
    assert w.accept_segment(1, 0, 3, 2, 0) is V.TOO_OLD
    assert w.accept_segment(1, 0, 19, 0, 0) is V.ACCEPTED and w.accept_segment(1, 1, 19, 0, 0) is V.NEW_EPOCH
    assert w.accept_segment(1, 0, 19, 1, 0) is V.OLD_EPOCH


def test_a_finished_transfer_opens_no_reassembly_and_an_expired_one_takes_no_segment():
    w = ReplayWindow()
    w.accept_segment(1, 0, 3, 0, 0)
    w.accept_segment(1, 0, 4, 0, 0)
    assert w.may_open(1, 3) and w.may_open(1, 4) and w.may_open(1, 5)
    w.mark(1, 3, SegmentState.COMPLETE)
    w.mark(1, 4, SegmentState.EXPIRED)
    assert not w.may_open(1, 3) and not w.may_open(1, 4)
    assert w.accept_segment(1, 0, 3, 1, 0) is V.ACCEPTED  # unseen: may repeat the complete ack, opens nothing
    assert w.accept_segment(1, 0, 4, 1, 0) is V.CLOSED
    w.mark(1, 99, SegmentState.EXPIRED)  # unknown: ignored
    assert w.may_open(1, 99)


def test_segment_memory_stays_bounded():
    w = ReplayWindow()
    for seq in range(5000):
        for segment in range(3):
            w.accept_segment(1, 0, seq, segment, 0)
    assert len(w) <= MAX_SEGMENTED + 1
    assert w.accept_segment(1, 0, 4000, 0, 0) is V.TOO_OLD  # forgotten, never accepted again
