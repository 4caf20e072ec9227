"""Retransmission and duplicate detection: which sent frames await a Confirm, when to resend or give
up, which received (source, seq) pairs were seen, and which result report may follow which.
Must not know the wire format beyond opaque cached Confirm bytes, nor events, clocks or robots.
"""

# Theory of operation
# ===================
#
# Every command and every PoseUpdate (a "confirmable" frame) is answered by a Confirm, and must be
# executed at most once however often it is sent. Two tables make that happen; everything that
# decides "resend?", "give up?", "new or duplicate?" or "may this result follow that one?" lives
# in this module.
#
# Sender side: RetransmissionQueue. A confirmable frame enters the queue when it is first sent,
# keyed by (destination, seq), with sends = 1 and deadline = now + ack_timeout_s. Then:
#
#     AWAITING --Confirm from dst, same seq and type--> removed (solicited Confirm: sends, rtt)
#     AWAITING --deadline, sends < max_sends----------> AWAITING (resend: same seq, attempt + 1,
#                                                                 sends + 1, new deadline)
#     AWAITING --deadline, sends == max_sends---------> removed (DeliveryFailed)
#     AWAITING --cancel--------------------------------> removed (silently)
#
# Paper IV.A: "If message receive was not acknowledged protocol retries two more times and then
# stop command execution", hence max_sends = 3 and the give-up one ack_timeout_s after the last
# send. A resend keeps its seq so the receiver can recognise it; only the attempt bits (and so the
# CRC) change, like MAVLink's COMMAND_LONG.confirmation counter.
#
# Receiver side: DuplicateCache. A confirmable frame from (src, seq) is NEW unless the cache holds
# an entry for (src, seq) that is younger than duplicate_window_s and carries the same message:
#
#     no entry, expired entry, different message -> NEW: one event; entry created, no Confirm yet
#     entry, application has not confirmed yet  -> DUPLICATE_UNANSWERED: dropped, nothing sent
#     entry with a cached Confirm                -> DUPLICATE_ANSWERED: cached Confirm sent again
#
# so a command never executes twice and a lost Confirm is repaired by the sender's own resend.
# "Same message" matters because seqs are reused: a sender that restarts counts from its initial
# seq again, and a busy one wraps past 65535. A resend is always the same message; a new frame
# with a reused seq almost never is, and the time window covers the rest (Bluetooth Mesh replay
# protection solves the same problem with a persistent 24-bit SEQ and the IV index). The cache is bounded:
# duplicate_cache_size seqs per source, least recently seen dropped first; sources are one byte.
#
# Result reports: the first Confirm may be interim (ACCEPTED, IN_PROGRESS) and a later one final
# (DONE, FAILED, CANCELLED); RESULT_TRANSITIONS says which report may follow which. Each report
# replaces the cached Confirm, so a resend that arrives later gets the latest word. Reports after
# the first are unsolicited and best effort: sent once, never retried.

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING

from .messages import Message, MessageType, ResultCode

if TYPE_CHECKING:  # annotations only: the queue stores the header, the endpoint encodes it
    from .codec import Header

_INTERIM_NEXT = frozenset(
    {ResultCode.IN_PROGRESS, ResultCode.DONE, ResultCode.FAILED, ResultCode.CANCELLED}
)
_FINAL_NEXT: frozenset[ResultCode] = frozenset()

#: Last result reported for a frame (None: not answered yet) -> results that may be reported next.
RESULT_TRANSITIONS: dict[ResultCode | None, frozenset[ResultCode]] = {
    None: frozenset(ResultCode),
    ResultCode.ACCEPTED: _INTERIM_NEXT,
    ResultCode.IN_PROGRESS: _INTERIM_NEXT,
    ResultCode.DONE: _FINAL_NEXT,
    ResultCode.DENIED: _FINAL_NEXT,
    ResultCode.UNSUPPORTED: _FINAL_NEXT,
    ResultCode.FAILED: _FINAL_NEXT,
    ResultCode.CANCELLED: _FINAL_NEXT,
    ResultCode.TEMPORARILY_REJECTED: _FINAL_NEXT,
}


@dataclass(frozen=True, slots=True)
class ReliabilityConfig:
    """Retry and duplicate-detection parameters.

    ack_timeout_s: wait for a Confirm before resending, in s (BLE connection intervals are
        7.5 ms to 4 s; 0.15 s allows a few hops at short intervals). max_sends: total sends of a frame
        (paper IV.A: first send + 2 retries = 3). duplicate_cache_size: seqs remembered per source.
        duplicate_window_s: how long, in s, a seen (src, seq) counts as a possible resend; at least
        max_sends * ack_timeout_s so every resend is recognised.
    per_hop_timeout_s: added to ack_timeout_s for every hop beyond the first to the destination, in
        s (Bluetooth Mesh SAR timers grow 50 ms per TTL: ack >= 150 + 50 * TTL ms).
    per_segment_timeout_s: added for every segment of a frame the mesh layer segments, in s (one
        segment per 20 ms segment interval plus advertising delay, docs/mesh.md).
    """

    ack_timeout_s: float = 0.15
    max_sends: int = 3
    duplicate_cache_size: int = 256
    duplicate_window_s: float = 10.0
    per_hop_timeout_s: float = 0.05
    per_segment_timeout_s: float = 0.03

    def __post_init__(self) -> None:
        if not self.ack_timeout_s > 0.0:  # also rejects NaN
            raise ValueError(f"ack_timeout_s must be > 0, got {self.ack_timeout_s!r}")
        if not (isinstance(self.max_sends, int) and self.max_sends >= 1):
            raise ValueError(f"max_sends must be an int >= 1, got {self.max_sends!r}")
        if not (isinstance(self.duplicate_cache_size, int) and self.duplicate_cache_size >= 1):
            raise ValueError(f"duplicate_cache_size must be >= 1, got {self.duplicate_cache_size!r}")
        if not (self.per_hop_timeout_s >= 0.0 and self.per_segment_timeout_s >= 0.0):
            raise ValueError("per_hop_timeout_s and per_segment_timeout_s must be >= 0")
        if not self.duplicate_window_s >= self.max_sends * self.ack_timeout_s:
            raise ValueError(
                f"duplicate_window_s ({self.duplicate_window_s!r} s) must cover all sends: "
                f">= max_sends * ack_timeout_s = {self.max_sends * self.ack_timeout_s} s"
            )


# --- sender side -------------------------------------------------------------------------------


class TimeoutAction(Enum):
    RESEND = "resend"
    GIVE_UP = "give_up"


#: What a passed deadline does, keyed by "all max_sends sends used".
_ON_DEADLINE: dict[bool, TimeoutAction] = {False: TimeoutAction.RESEND, True: TimeoutAction.GIVE_UP}


@dataclass(slots=True)
class PendingFrame:
    """A confirmable frame awaiting its Confirm. Times in s; `header` is the Header of the first
    send (the endpoint re-encodes resends with the attempt bits raised); `timeout_s` is this
    frame's wait for a Confirm (ack_timeout_s, longer over several hops or for a segmented frame)."""

    dst: int
    seq: int
    header: Header
    message: Message
    sends: int
    first_sent_s: float
    last_sent_s: float
    deadline_s: float
    timeout_s: float


class RetransmissionQueue:
    """Confirmable frames in flight, keyed by (dst, seq)."""

    def __init__(self, config: ReliabilityConfig) -> None:
        self._config = config
        self._pending: dict[tuple[int, int], PendingFrame] = {}
        # the earliest deadline, kept between changes: the endpoint's timer is asked after every
        # frame a robot hears, and the queue changes far less often (None: ask the frames again)
        self._next: float | None = None
        self._known = True

    def __len__(self) -> int:
        return len(self._pending)

    def __contains__(self, key: tuple[int, int]) -> bool:
        return key in self._pending

    def add(self, dst: int, seq: int, header: Header, message: Message, now: float,
            timeout_s: float | None = None) -> PendingFrame:
        """Record the first send of a frame at `now` s; it waits `timeout_s` (default ack_timeout_s)
        for each Confirm."""
        timeout = self._config.ack_timeout_s if timeout_s is None else timeout_s
        frame = PendingFrame(dst, seq, header, message, 1, now, now, now + timeout, timeout)
        self._known = False  # a frame replaced under the same (dst, seq) may have held the earliest
        self._pending[(dst, seq)] = frame
        return frame

    def acknowledge(self, src: int, ref_seq: int, ref_type: MessageType) -> PendingFrame | None:
        """Remove and return the frame a Confirm from `src` answers, or None if none is pending.

        A Confirm whose type does not match (a stale one for a reused seq) answers nothing.
        """
        frame = self._pending.get((src, ref_seq))
        if frame is None or frame.message.TYPE != ref_type:
            return None
        del self._pending[(src, ref_seq)]
        self._known = False
        return frame

    def next_deadline(self) -> float | None:
        """Earliest deadline in s, or None when nothing is pending."""
        if not self._known:
            self._next = min((frame.deadline_s for frame in self._pending.values()), default=None)
            self._known = True
        return self._next

    def expire(self, now: float) -> list[tuple[TimeoutAction, PendingFrame]]:
        """Apply every deadline passed by `now`: resend (frame updated in place) or give up (removed)."""
        actions = []
        self._known = False
        max_sends = self._config.max_sends
        for key, frame in list(self._pending.items()):
            if frame.deadline_s > now:
                continue
            action = _ON_DEADLINE[frame.sends >= max_sends]
            if action is TimeoutAction.GIVE_UP:
                del self._pending[key]
            else:
                frame.sends += 1
                frame.last_sent_s = now
                frame.deadline_s = now + frame.timeout_s
            actions.append((action, frame))
        return actions

    def cancel(self, dst: int | None = None) -> list[PendingFrame]:
        """Stop retrying the frames to `dst` (all frames if None); return them."""
        keys = [key for key in self._pending if dst is None or key[0] == dst]
        self._known = False
        return [self._pending.pop(key) for key in keys]


# --- receiver side -----------------------------------------------------------------------------


class Verdict(Enum):
    NEW = "new"
    DUPLICATE_UNANSWERED = "duplicate_unanswered"
    DUPLICATE_ANSWERED = "duplicate_answered"


#: Verdict on a recognised resend, keyed by "a Confirm is cached".
_ON_DUPLICATE: dict[bool, Verdict] = {
    False: Verdict.DUPLICATE_UNANSWERED,
    True: Verdict.DUPLICATE_ANSWERED,
}


@dataclass(slots=True)
class SeenFrame:
    """What the receiver remembers of one (src, seq): the message, when first seen (s), the latest
    result reported for it and the Confirm frame carrying that result."""

    message: Message
    first_seen_s: float
    last_result: ResultCode | None = None
    confirm_frame: object | None = None


class DuplicateCache:
    """Seen confirmable frames per source: an LRU of `size` seqs each."""

    def __init__(self, config: ReliabilityConfig) -> None:
        self._size = config.duplicate_cache_size
        self._window_s = config.duplicate_window_s
        self._by_source: dict[int, OrderedDict[int, SeenFrame]] = {}

    def __len__(self) -> int:
        return sum(len(seen) for seen in self._by_source.values())

    def observe(self, src: int, seq: int, message: Message, now: float) -> tuple[Verdict, object | None]:
        """Classify a received confirmable frame; returns the verdict and the Confirm to resend."""
        seen = self._by_source.get(src)
        if seen is None:
            seen = self._by_source[src] = OrderedDict()
        entry = seen.get(seq)
        if entry is not None and now - entry.first_seen_s <= self._window_s and entry.message == message:
            seen.move_to_end(seq)
            return _ON_DUPLICATE[entry.confirm_frame is not None], entry.confirm_frame
        seen[seq] = SeenFrame(message, now)
        seen.move_to_end(seq)
        if len(seen) > self._size:
            seen.popitem(last=False)
        return Verdict.NEW, None

    def forget(self, src: int) -> None:
        """Drop everything seen from `src` (it restarted: its sequence numbers start over)."""
        self._by_source.pop(src, None)

    def lookup(self, src: int, seq: int) -> SeenFrame | None:
        seen = self._by_source.get(src)
        return None if seen is None else seen.get(seq)

    def check_report(self, src: int, seq: int, ref_type: MessageType, result: ResultCode) -> None:
        """Raise ValueError if `result` may not be reported now for (src, seq). Unknown (never seen
        or evicted) frames are not checked."""
        entry = self.lookup(src, seq)
        if entry is None:
            return
        if entry.message.TYPE != ref_type:
            raise ValueError(
                f"seq {seq} from {src} was a {entry.message.TYPE.name}, not a {MessageType(ref_type).name}"
            )
        if result not in RESULT_TRANSITIONS[entry.last_result]:
            last = "nothing" if entry.last_result is None else entry.last_result.name
            raise ValueError(f"cannot report {ResultCode(result).name} after {last} (seq {seq} from {src})")

    def record_confirm(self, src: int, seq: int, result: ResultCode, frame: object) -> bool:
        """Cache `frame` (the Confirm the endpoint re-sends, opaque here) as the answer to (src,
        seq); False if that frame is not (or no longer) known."""
        entry = self.lookup(src, seq)
        if entry is None:
            return False
        entry.last_result = ResultCode(result)
        entry.confirm_frame = frame
        return True
