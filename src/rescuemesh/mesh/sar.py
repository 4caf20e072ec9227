"""Segmentation and reassembly (after Bluetooth Mesh Profile 1.0, 3.5.3): the sender's transfers
(pacing, block acks, retransmission rounds, give-up) and the receiver's reassemblies (ack timer,
incomplete timer, completed memory). Must not know relays, the cache, clocks or the endpoint.
"""

# Theory of operation
# ===================
#
# A logical frame longer than 20 bytes travels as 1..512 segment frames (segments.py). Everything
# that decides "release which segment when?", "resend?", "give up?", "ack now?", "deliver?" or
# "discard?" lives in this module; the node only moves bytes and counts.
#
# Sender: one Transfer per destination at a time (Mesh Profile 1.0, 3.5.3.3: one segmented message
# per destination; later ones wait in a FIFO). A shared pacer releases at most one segment per
# segment_interval_s for the whole node (Mesh 1.1: 20 ms), round-robin over destinations, so a
# long transfer never floods the radio queue and control frames interleave. A round releases the
# segments in the order last, 0, 1, ..., last - 1 (the last one first: it alone differs between
# an endpoint's resends, see below). A retransmission round releases only the segments a
# SegmentAck reported missing (indices below the highest base + 48 heard, not acknowledged), in
# index order; when none is known, the first unacknowledged one alone, as a probe that draws a
# fresh ack. So a lossy transfer resends what is missing, not its whole tail, and a receiver that
# is gone costs one segment per round. Then:
#
#     SENDING --ack, all acknowledged---------------------> done (TransferComplete)
#     SENDING --ack with progress-------------------------> SENDING (acked segments skipped)
#     SENDING --round's last segment released-------------> WAITING, deadline = release time
#                                                              + retransmit_timeout_s(hops)
#     WAITING --ack, all acknowledged---------------------> done (TransferComplete)
#     WAITING --ack with progress-------------------------> SENDING, round + 1 at once (the
#                                                              receiver has said what it lacks)
#     WAITING --deadline, progress in this round----------> SENDING, round + 1
#     WAITING --deadline, none, attempts_left > 0---------> SENDING, round + 1, attempts_left - 1
#     WAITING --deadline, none, attempts_left == 0--------> done (TransferFailed)
#     WAITING --the endpoint resends the frame------------> as if the deadline had passed
#     any     --the endpoint no longer awaits the frame---> done, no event (abandon())
#
# The endpoint above resends a frame whose Confirm did not come in its own time (0.15 s and more,
# docs/protocol.md section 7), and a resend of a frame whose transfer runs is absorbed (the
# transfer carries it). While the transfer waits, the resend starts its next round at once, so
# each of the endpoint's sends puts the frame on the air at least once, as an unsegmented frame's
# would: with the wait for a destination of unknown distance (0.55 s), the endpoint's three sends
# (0.54 s) used to see a single round. When the endpoint stops waiting (its Confirm came, it gave
# the frame up, it cancelled it), the node's stack calls abandon(): a given-up command is not
# delivered late, and the next frame to that destination does not queue behind it.
#
# "Progress" is an ack that acknowledges a segment not acknowledged before; it resets
# attempts_left to max_retransmissions (Zephyr's 4), so a transfer fails only after the first
# round and then that many retransmission rounds in a row without progress. hops is the
# neighbour table's hop count to the destination, or initial_ttl when unknown (a longer wait).
#
# Receiver: one Reassembly per (src, seq), created by its first segment, bounded in number per
# source and in total (beyond: the segment is dropped and counted). A new segment restarts the
# incomplete timer (3.5.3.4: 10 s without a new segment discards it) and starts the ack timer if
# it is not running (ack_delay_s(hops) = 0.15 + 0.05 * hops s), which sends a SegmentAck with the
# current (base, bitmap). The segment that completes it sends the SegmentAck at once and delivers
# the logical frame, rebuilt byte for byte and checked by its own CRC-32.
#
# A completed (src, seq) is remembered for incomplete_timeout_s: a late segment of it is not
# reassembled again but answered with the complete ack (at most one per
# duplicate_ack_interval_s), so a sender whose final ack was lost finishes. One exception: the
# endpoint above the source resends a frame with new attempt bits (its Confirm was lost). Its
# last segment ends with the frame's CRC-32, which the attempt bits change; that segment goes
# first, and when it differs from the remembered one the frame is delivered again, so the
# receiving endpoint answers from its duplicate cache (it never executes a resend twice).

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum

from .config import MeshConfig
from .events import MeshEvent, TransferComplete, TransferFailed
from .frames import FrameView
from .segments import BLOCK_ACK_BITS, acked_indices, make_segment, segment_count
from .stats import MeshStats

# --- sender ------------------------------------------------------------------------------------


class TransferState(Enum):
    SENDING = "sending"  # segments of the current round wait for the pacer
    WAITING = "waiting"  # round released; waiting for an ack or the retransmit deadline


@dataclass(slots=True)
class Transfer:
    """One segmented frame on its way to `dst`. Times in s."""

    view: FrameView
    frame: bytes
    total: int
    attempts_left: int
    acked: list[bool]
    acked_count: int = 0
    round: int = 0
    state: TransferState = TransferState.SENDING
    queue: deque[int] = field(default_factory=deque)
    window_end: int = 0  # segments below this were reported on by some SegmentAck
    progressed: bool = False  # an ack made progress since this round started
    last_release_s: float = 0.0
    deadline_s: float = 0.0

    def first_round(self) -> deque[int]:
        """Round 0: every segment, the last one first."""
        last = self.total - 1
        return deque([last, *range(last)])

    def retransmission_round(self) -> deque[int]:
        """Later rounds: the segments a SegmentAck reported missing, in index order; if none is
        known, the first unacknowledged one alone, as a probe that draws a fresh ack."""
        acked = self.acked
        missing = deque(i for i in range(self.window_end) if not acked[i])
        if not missing:
            missing.append(acked.index(False))
        return missing


#: (frame view, segment bytes, index, total, round, now) -> None: put one segment on the air.
SegmentSink = Callable[[FrameView, bytes, int, int, int, float], None]


class SarSender:
    """Transfers by destination, the pacer and the retransmission rounds of the module comment."""

    def __init__(
        self,
        config: MeshConfig,
        stats: MeshStats,
        hops_to: Callable[[int], int | None],
        transmit: SegmentSink,
        emit: Callable[[MeshEvent], None],
    ) -> None:
        self._config = config
        self._stats = stats
        self._hops_to = hops_to
        self._transmit = transmit
        self._emit = emit
        self._active: dict[int, Transfer] = {}  # by dst, in the order they started
        self._last_served: int | None = None  # dst of the last segment released
        self._waiting: dict[int, deque[tuple[FrameView, bytes]]] = {}
        self._next_release_s = float("-inf")

    def __len__(self) -> int:
        return len(self._active) + sum(len(q) for q in self._waiting.values())

    def start(self, view: FrameView, frame: bytes, now: float) -> None:
        """Accept a logical frame of more than 20 bytes for unicast `view.dst`."""
        dst, seq = view.dst, view.seq
        active = self._active.get(dst)
        queued = self._waiting.get(dst, ())
        if active is not None and active.view.seq == seq:
            self._stats.resends_absorbed += 1  # the running transfer carries it
            if active.state is TransferState.WAITING:  # the endpoint's timer ran out first: a round now
                self._round_on_deadline(active, now)
                self._release(now)
            return
        if any(v.seq == seq for v, _ in queued):
            self._stats.resends_absorbed += 1  # the queued transfer will carry it
            return
        self._stats.transfers_started += 1
        if active is not None:
            self._stats.transfers_queued += 1
            self._waiting.setdefault(dst, deque()).append((view, frame))
            return
        self._activate(view, frame, now)
        self._release(now)

    def on_ack(self, src: int, ref_seq: int, base: int, bitmap: int, now: float) -> None:
        """A SegmentAck from `src` for our frame `ref_seq`: every index < base, and base + i for
        each bit i set, received."""
        self._stats.acks_received += 1
        transfer = self._active.get(src)
        if transfer is None or transfer.view.seq != ref_seq or base > transfer.total:
            self._stats.acks_unmatched += 1
            return
        progress = False
        transfer.window_end = max(transfer.window_end, min(transfer.total, base + BLOCK_ACK_BITS))
        for index in acked_indices(base, bitmap, transfer.total):
            if not transfer.acked[index]:
                transfer.acked[index] = True
                transfer.acked_count += 1
                progress = True
        if transfer.acked_count == transfer.total:
            self._stats.transfers_complete += 1
            self._finish(transfer, TransferComplete(src, ref_seq, transfer.total, now), now)
        elif progress:
            transfer.attempts_left = self._config.max_retransmissions
            transfer.progressed = True
            if transfer.state is TransferState.WAITING:
                self._next_round(transfer, now)

    def next_timer(self) -> float | None:
        """Earliest time in s at which handle_timer() has work (pacer slot or deadline), or None."""
        if not self._active:  # the common case, asked after every frame heard
            return None
        times = [t.deadline_s for t in self._active.values() if t.state is TransferState.WAITING]
        if any(t.state is TransferState.SENDING for t in self._active.values()):
            times.append(self._next_release_s)
        return min(times, default=None)

    def handle_timer(self, now: float) -> None:
        """Give up or start a new round for every passed deadline; release a segment if due."""
        for transfer in list(self._active.values()):
            if transfer.state is TransferState.WAITING and transfer.deadline_s <= now:
                if not self._round_on_deadline(transfer, now):
                    view = transfer.view
                    failed = TransferFailed(view.dst, view.seq, transfer.acked_count, transfer.total, now)
                    self._stats.transfers_failed += 1
                    self._finish(transfer, failed, now)
        self._release(now)

    def abandon(self, awaited: Callable[[int, int], bool], now: float) -> None:
        """End every transfer, running or queued, whose frame `awaited(dst, seq)` says the endpoint
        above no longer waits for (its Confirm came, it gave the frame up, or it cancelled it): no
        event, counted in `transfers_abandoned`. The next transfer to that destination starts."""
        if not self._active:  # the common case, asked after every call into the stack
            return  # (a transfer waits in the queue only behind a running one)
        for dst, waiting in list(self._waiting.items()):
            kept = deque(item for item in waiting if awaited(dst, item[0].seq))
            self._stats.transfers_abandoned += len(waiting) - len(kept)
            if kept:
                self._waiting[dst] = kept
            else:
                del self._waiting[dst]
        ended = False
        for transfer in list(self._active.values()):
            if not awaited(transfer.view.dst, transfer.view.seq):
                self._stats.transfers_abandoned += 1
                self._finish(transfer, None, now)
                ended = True
        if ended:
            self._release(now)

    # internals

    def _activate(self, view: FrameView, frame: bytes, now: float) -> None:
        total = segment_count(len(frame))
        transfer = Transfer(view, frame, total, self._config.max_retransmissions, [False] * total)
        transfer.queue = transfer.first_round()
        self._active[view.dst] = transfer
        self._next_release_s = max(self._next_release_s, now)

    def _round_on_deadline(self, transfer: Transfer, now: float) -> bool:
        """What a passed deadline does (or an endpoint resend while waiting): the next round, out of
        the budget unless progress came in this one. False when the budget is spent."""
        if not transfer.progressed:
            if transfer.attempts_left == 0:
                return False
            transfer.attempts_left -= 1
        self._next_round(transfer, now)
        return True

    def _next_round(self, transfer: Transfer, now: float) -> None:
        transfer.round += 1
        transfer.progressed = False
        transfer.queue = transfer.retransmission_round()
        transfer.state = TransferState.SENDING
        self._next_release_s = max(self._next_release_s, now)

    def _finish(self, transfer: Transfer, event: MeshEvent | None, now: float) -> None:
        dst = transfer.view.dst
        del self._active[dst]
        if event is not None:
            self._emit(event)
        waiting = self._waiting.get(dst)
        if waiting:
            view, frame = waiting.popleft()
            if not waiting:
                del self._waiting[dst]
            self._activate(view, frame, now)

    def _release(self, now: float) -> None:
        """Release one segment if the pacer slot has come: from the first transfer with segments to
        release after the one served last (round-robin)."""
        if self._next_release_s > now:
            return
        dsts = list(self._active)
        if self._last_served in self._active:
            after = dsts.index(self._last_served) + 1
            dsts = dsts[after:] + dsts[:after]
        for dst in dsts:
            transfer = self._active[dst]
            if transfer.state is not TransferState.SENDING:
                continue
            queue = transfer.queue
            while queue and transfer.acked[queue[0]]:
                queue.popleft()
            if not queue:  # the rest of the round was acked meanwhile: wait from the last release
                self._wait(transfer)
                continue
            index = queue.popleft()
            data = make_segment(transfer.frame, index, transfer.round)
            self._stats.segments_sent += 1
            if transfer.round:
                self._stats.segments_retransmitted += 1
            self._transmit(transfer.view, data, index, transfer.total, transfer.round, now)
            self._next_release_s = now + self._config.segment_interval_s
            self._last_served = dst
            transfer.last_release_s = now
            if not queue:
                self._wait(transfer)
            return

    def _wait(self, transfer: Transfer) -> None:
        hops = self._hops_to(transfer.view.dst)
        hops = self._config.initial_ttl if hops is None else hops
        transfer.state = TransferState.WAITING
        transfer.deadline_s = transfer.last_release_s + self._config.retransmit_timeout_s(hops)
