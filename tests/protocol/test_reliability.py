"""Retransmission queue, duplicate cache and the result-report state machine."""

from __future__ import annotations

import math

import pytest

from rescuemesh.protocol import Follow, MessageType, Pose, ResultCode, Stop
from rescuemesh.protocol.messages import PoseUpdate
from rescuemesh.protocol.reliability import RESULT_TRANSITIONS
from rescuemesh.protocol.reliability import (
    DuplicateCache,
    ReliabilityConfig,
    RetransmissionQueue,
    TimeoutAction,
    Verdict,
)

R = ResultCode


@pytest.mark.parametrize(
    "kwargs",
    [
        {"ack_timeout_s": 0.0},
        {"ack_timeout_s": -0.1},
        {"ack_timeout_s": math.nan},
        {"max_sends": 0},
        {"max_sends": 2.5},
        {"duplicate_cache_size": 0},
        {"duplicate_window_s": 0.3},  # < 3 sends * 0.15 s: a late resend would run twice
    ],
)
def test_bad_configs_are_refused(kwargs):
    with pytest.raises(ValueError):
        ReliabilityConfig(**kwargs)


def test_default_config_is_the_papers_rule():
    config = ReliabilityConfig()
    assert (config.ack_timeout_s, config.max_sends, config.duplicate_cache_size) == (0.15, 3, 256)


# --- sender side --------------------------------------------------------------------------------


def test_a_frame_is_resent_until_max_sends_then_given_up():
    queue = RetransmissionQueue(ReliabilityConfig(ack_timeout_s=0.25, max_sends=3))
    queue.add(2, 7, None, Stop(), now=1.0)
    assert queue.next_deadline() == 1.25
    assert queue.expire(1.2) == []
    (action, frame), = queue.expire(1.25)
    assert action is TimeoutAction.RESEND and frame.sends == 2 and frame.last_sent_s == 1.25
    (action, frame), = queue.expire(1.5)
    assert action is TimeoutAction.RESEND and frame.sends == 3
    (action, frame), = queue.expire(1.75)
    assert action is TimeoutAction.GIVE_UP and frame.sends == 3
    assert len(queue) == 0 and queue.next_deadline() is None


def test_max_sends_one_means_no_resend():
    queue = RetransmissionQueue(ReliabilityConfig(max_sends=1))
    queue.add(2, 7, None, Stop(), now=0.0)
    assert [a for a, _ in queue.expire(1.0)] == [TimeoutAction.GIVE_UP]


def test_acknowledge_needs_the_right_source_seq_and_type():
    queue = RetransmissionQueue(ReliabilityConfig())
    queue.add(2, 7, None, Stop(), now=0.0)
    assert queue.acknowledge(3, 7, MessageType.STOP) is None  # another robot
    assert queue.acknowledge(2, 8, MessageType.STOP) is None  # another frame
    assert queue.acknowledge(2, 7, MessageType.FOLLOW) is None  # stale Confirm for a reused seq
    assert (2, 7) in queue
    assert queue.acknowledge(2, 7, MessageType.STOP).message == Stop()
    assert (2, 7) not in queue


def test_cancel_by_destination_or_all():
    queue = RetransmissionQueue(ReliabilityConfig())
    for dst, seq in [(2, 0), (3, 1), (2, 2)]:
        queue.add(dst, seq, None, Stop(), now=0.0)
    assert sorted(f.seq for f in queue.cancel(2)) == [0, 2]
    assert len(queue) == 1
    assert [f.seq for f in queue.cancel()] == [1]


# --- receiver side ------------------------------------------------------------------------------

POSE = Pose(1.0, 2.0, 0.0, 0.5)


def test_new_then_unanswered_then_answered_duplicate():
    cache = DuplicateCache(ReliabilityConfig())
    assert cache.observe(1, 7, Follow(POSE), 0.0) == (Verdict.NEW, None)
    assert cache.observe(1, 7, Follow(POSE), 0.15) == (Verdict.DUPLICATE_UNANSWERED, None)
    assert cache.record_confirm(1, 7, R.ACCEPTED, b"confirm")
    assert cache.observe(1, 7, Follow(POSE), 0.3) == (Verdict.DUPLICATE_ANSWERED, b"confirm")


def test_a_later_report_replaces_the_cached_confirm():
    cache = DuplicateCache(ReliabilityConfig())
    cache.observe(1, 7, Follow(POSE), 0.0)
    cache.record_confirm(1, 7, R.ACCEPTED, b"accepted")
    cache.record_confirm(1, 7, R.DONE, b"done")
    assert cache.observe(1, 7, Follow(POSE), 0.3) == (Verdict.DUPLICATE_ANSWERED, b"done")


def test_sources_are_separate():
    cache = DuplicateCache(ReliabilityConfig())
    assert cache.observe(1, 7, Stop(), 0.0)[0] is Verdict.NEW
    assert cache.observe(2, 7, Stop(), 0.0)[0] is Verdict.NEW


def test_same_seq_with_another_message_is_new():
    # a restarted or wrapped sender reuses seqs; a resend is always the same message
    cache = DuplicateCache(ReliabilityConfig())
    cache.observe(1, 0, Follow(POSE), 0.0)
    cache.record_confirm(1, 0, R.ACCEPTED, b"old")
    assert cache.observe(1, 0, Stop(), 1.0) == (Verdict.NEW, None)
    assert cache.lookup(1, 0).confirm_frame is None


def test_entries_expire_after_the_window():
    cache = DuplicateCache(ReliabilityConfig(duplicate_window_s=5.0))
    cache.observe(1, 0, Stop(), 0.0)
    assert cache.observe(1, 0, Stop(), 5.0)[0] is Verdict.DUPLICATE_UNANSWERED
    assert cache.observe(1, 0, Stop(), 5.01)[0] is Verdict.NEW


def test_cache_is_bounded_per_source_least_recently_seen_first():
    cache = DuplicateCache(ReliabilityConfig(duplicate_cache_size=3))
    for seq in range(3):
        cache.observe(1, seq, PoseUpdate(POSE), 0.0)
    cache.observe(1, 0, PoseUpdate(POSE), 0.1)  # seq 0 seen again: now the most recent
    cache.observe(1, 3, PoseUpdate(POSE), 0.2)  # evicts seq 1
    assert cache.lookup(1, 1) is None
    assert cache.observe(1, 0, PoseUpdate(POSE), 0.3)[0] is Verdict.DUPLICATE_UNANSWERED
    assert len(cache) == 3


def test_record_confirm_for_an_unknown_frame_is_not_cached():
    cache = DuplicateCache(ReliabilityConfig())
    assert not cache.record_confirm(1, 99, R.DONE, b"x")


# --- result reports -----------------------------------------------------------------------------


def test_transition_table_covers_every_result():
    assert set(RESULT_TRANSITIONS) == {None, *ResultCode}
    assert RESULT_TRANSITIONS[None] == frozenset(ResultCode)


@pytest.mark.parametrize(
    "history, allowed",
    [
        ([], True),
        ([R.ACCEPTED, R.DONE], True),
        ([R.ACCEPTED, R.IN_PROGRESS, R.IN_PROGRESS, R.FAILED], True),
        ([R.IN_PROGRESS, R.CANCELLED], True),
        ([R.DENIED], True),
        ([R.ACCEPTED, R.ACCEPTED], False),
        ([R.DONE, R.DONE], False),
        ([R.DENIED, R.DONE], False),
        ([R.UNSUPPORTED, R.ACCEPTED], False),
        ([R.FAILED, R.CANCELLED], False),
        ([R.ACCEPTED, R.DENIED], False),
    ],
)
def test_which_report_may_follow_which(history, allowed):
    cache = DuplicateCache(ReliabilityConfig())
    cache.observe(1, 7, Follow(POSE), 0.0)
    *earlier, last = history or [R.ACCEPTED]
    for result in earlier:
        cache.check_report(1, 7, MessageType.FOLLOW, result)
        cache.record_confirm(1, 7, result, b"")
    if allowed:
        cache.check_report(1, 7, MessageType.FOLLOW, last)
    else:
        with pytest.raises(ValueError):
            cache.check_report(1, 7, MessageType.FOLLOW, last)


def test_report_with_the_wrong_type_is_refused():
    cache = DuplicateCache(ReliabilityConfig())
    cache.observe(1, 7, Follow(POSE), 0.0)
    with pytest.raises(ValueError):
        cache.check_report(1, 7, MessageType.STOP, R.ACCEPTED)
    cache.check_report(1, 8, MessageType.STOP, R.DONE)  # unknown frame: not checked


@pytest.mark.parametrize("seed", range(6))
def test_next_deadline_kept_between_changes_is_the_earliest_pending(seed):
    """The queue keeps its earliest deadline between changes; it is always the minimum over the
    frames pending, after any mix of sends (a seq reused included), Confirms, timeouts and cancels."""
    import random
    rng = random.Random(seed)
    queue = RetransmissionQueue(ReliabilityConfig())
    now = 0.0
    for _ in range(400):
        now += rng.choice((0.0, 0.05, 0.2))
        step, dst, seq = rng.random(), rng.randrange(2, 5), rng.randrange(0, 8)
        if step < 0.45:
            queue.add(dst, seq, None, Stop(), now, rng.choice((None, 0.1, 0.7)))
        elif step < 0.75:
            queue.acknowledge(dst, seq, MessageType.STOP)
        elif step < 0.95:
            queue.expire(now)
        else:
            queue.cancel(rng.choice((None, dst)))
        frames = [queue._pending[key] for key in list(queue._pending)]
        assert queue.next_deadline() == min((f.deadline_s for f in frames), default=None)
