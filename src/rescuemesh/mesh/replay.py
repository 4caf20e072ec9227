"""Replay protection: which authenticated frames from each source have been accepted, so that none is
accepted twice, at any delay. Owns the per-source window; must not know keys, frame layout, clocks.
After Bluetooth Mesh's replay protection list (Mesh Profile 1.0, 3.8.8), widened to a window.
"""

# Theory of operation
# ===================
#
# Bluetooth Mesh keeps, per source, the highest sequence number accepted and drops anything at or
# below it; every PDU there, resends included, carries a new number. Our resends keep their number
# and raise the 2-bit attempt count instead (the receiver recognises a resend by its number), and
# a robot's frames may arrive out of order over relays. So the list becomes a sliding window, as
# IPsec and DTLS anti-replay do (RFC 4303 3.4.3, RFC 6347 4.1.2.6). Per source it holds:
#
#   epoch    the source's epoch (boot counter plus sequence wraps, authenticated in its nonce);
#   highest  the highest sequence number accepted in that epoch;
#   seen     for each of the last WINDOW (64) numbers, which sends (attempt 0..3) were accepted.
#
# A frame (epoch e, seq s, send a) is
#
#   e < epoch                      -> OLD_EPOCH: dropped (captured before the source restarted)
#   e > epoch                      -> accepted; the window restarts at (e, s): the source rebooted
#                                     or wrapped (the MIC proved it holds the key)
#   s <= highest - WINDOW          -> TOO_OLD: dropped (outside the window, whatever its send)
#   (s, a) already seen            -> REPLAY: dropped
#   otherwise                      -> accepted and recorded; highest = max(highest, s)
#
# So a captured frame replayed at any later time is dropped: within the window it was seen,
# beyond it it is too old, across a restart its epoch is old. A genuine resend (a new attempt
# number) is accepted once; the endpoint above recognises its number and answers from its cache
# of the last WINDOW commands, so it never executes twice. Only frames that authenticate reach
# the window, so no flood from a radio without the key can move it. Memory: at most WINDOW
# entries per source, 255 sources.
#
# The window is short on purpose: an unseen frame a little older than the newest is accepted (a
# resend, or a frame overtaken on another path), but one more than 64 numbers old is not, so a
# replay can never revive a robot's stale Heartbeat or PoseUpdate from seconds ago (64 numbers are
# 9 s of a robot's own traffic at 7 frames/s, and a resend comes within 0.5 s).
#
# Segment frames share their message's number across all segments and rounds, and a transfer takes
# seconds while its source goes on numbering other frames: they are judged over SEGMENT_WINDOW
# numbers, by their own identity. A segment frame (epoch e, seq s, SegO o, round r) is
#
#   e < epoch, or s <= highest - SEGMENT_WINDOW, or s at or below the
#   oldest segmented number forgotten (more than MAX_SEGMENTED per source)  -> OLD_EPOCH / TOO_OLD
#   s's transfer EXPIRED here                    -> CLOSED: its reassembly timed out; nothing reopens it
#   (o, r) already accepted for s                -> REPLAY
#   otherwise                                    -> accepted and recorded (s becomes OPEN if new)
#
# with one refinement: the last segment (o = SegN) also counts its bytes (`variant`). An endpoint
# *resend* of a segmented command restarts its rounds at 0, and its last segment, which carries the
# logical frame's CRC-32 (the attempt bits changed), is the only one that differs: it must pass
# once, so that the receiver delivers the command again and its Confirm is repeated; a byte-identical
# copy is a replay. Up to MAX_SEND_VARIANTS such last segments per round count (the attempt bits
# saturate at 3); beyond them, REPLAY.
#
# The node marks a transfer COMPLETE when its reassembly delivered the frame, and EXPIRED when the
# reassembly timed out (mark()); `may_open(src, s)` is False for both, so a late or replayed segment
# of a finished transfer never opens a reassembly slot again (a COMPLETE transfer's unseen segments
# still reach the receiver's memory of completed frames, to repeat the complete ack). So a recorded
# segment replayed later neither refreshes its source's liveness, nor opens a reassembly, nor is
# relayed: only a frame this window accepts goes on (docs/security.md, "Segments under the replay
# rule"). Memory: MAX_SEGMENTED numbers per source, each 4 round masks of up to 512 bits and at most
# 4 * MAX_SEND_VARIANTS last segments of at most 16 bytes.

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

#: Numbers below a source's newest that may still be accepted once (resends, reordering).
REPLAY_WINDOW = 64
#: The same for segment frames: a segmented transfer lasts seconds (docs/mesh.md).
SEGMENT_WINDOW = 1024
#: The endpoint's duplicate cache must hold at least this many commands per source.
DUPLICATE_MEMORY = SEGMENT_WINDOW
MAX_SENDS_TRACKED = 4  # attempt bits 0..3
#: Segmented numbers remembered per source (a robot runs one transfer per destination at a time).
MAX_SEGMENTED = 64
#: Distinct last segments accepted per (number, round): an endpoint's sends 0..3 of the command.
MAX_SEND_VARIANTS = 4
_ROUNDS = 4  # the round travels in 2 bits


class SegmentState(Enum):
    """What a receiver knows of a segmented number: segments arriving, delivered, or timed out."""

    OPEN = "open"
    COMPLETE = "complete"
    EXPIRED = "expired"


class ReplayVerdict(Enum):
    ACCEPTED = "accepted"
    NEW_EPOCH = "new_epoch"  # accepted, and the source's epoch moved forward
    REPLAY = "replay"
    TOO_OLD = "too_old"
    OLD_EPOCH = "old_epoch"
    CLOSED = "closed"  # a segment of a transfer whose reassembly expired here


    @property
    def accepted(self) -> bool:
        return self in (ReplayVerdict.ACCEPTED, ReplayVerdict.NEW_EPOCH)


@dataclass(slots=True)
class _Segmented:
    state: SegmentState = SegmentState.OPEN
    rounds: list[int] = field(default_factory=lambda: [0] * _ROUNDS)  # per round: mask of SegO accepted
    last: set[tuple[int, bytes]] = field(default_factory=set)  # (round, bytes) of last segments accepted


@dataclass(slots=True)
class _Source:
    epoch: int
    highest: int
    seen: dict[int, int] = field(default_factory=dict)  # seq -> bit mask of accepted sends
    segmented: dict[int, _Segmented] = field(default_factory=dict)  # seq -> its segments, oldest first
    segment_floor: int = -1  # segmented numbers at or below it were forgotten (MAX_SEGMENTED)


class ReplayWindow:
    """Per-source replay state. `accept(...)` decides and records; `epoch_of(src)` says which epoch
    a source's next frame should open under (None before any frame from it)."""

    def __init__(self, window: int = REPLAY_WINDOW, segment_window: int = SEGMENT_WINDOW) -> None:
        for name, value in (("window", window), ("segment_window", segment_window)):
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(f"{name} must be an int >= 1, got {value!r}")
        self.window = window
        self.segment_window = segment_window
        self._sources: dict[int, _Source] = {}

    def __len__(self) -> int:
        return sum(len(s.seen) + len(s.segmented) for s in self._sources.values())

    def epoch_of(self, src: int) -> int | None:
        source = self._sources.get(src)
        return None if source is None else source.epoch

    def accept(self, src: int, epoch: int, seq: int, send: int) -> ReplayVerdict:
        """Judge frame `seq` (send `send`, 0..3) of `src` in `epoch`, and record it if accepted.
        Segment frames go through accept_segment."""
        source = self._sources.get(src)
        if source is None or epoch > source.epoch:
            verdict = ReplayVerdict.ACCEPTED if source is None else ReplayVerdict.NEW_EPOCH
            source = self._sources[src] = _Source(epoch, seq)
            source.seen[seq] = 1 << min(send, MAX_SENDS_TRACKED - 1)
            return verdict
        if epoch < source.epoch:
            return ReplayVerdict.OLD_EPOCH
        if seq <= source.highest - self.window:
            return ReplayVerdict.TOO_OLD
        bit = 1 << (send if send < MAX_SENDS_TRACKED else MAX_SENDS_TRACKED - 1)
        mask = source.seen.get(seq, 0)
        if mask & bit:
            return ReplayVerdict.REPLAY
        source.seen[seq] = mask | bit
        if seq > source.highest:
            self._advance(source, seq)
        return ReplayVerdict.ACCEPTED

    def accept_segment(self, src: int, epoch: int, seq: int, segment: int, round_: int,
                       variant: bytes = b"") -> ReplayVerdict:
        """Judge segment `segment` (SegO) of frame `seq`, sent in round `round_` (0..3), of `src` in
        `epoch`, and record it if accepted. `variant`: the bytes of a last segment (b"" for others):
        a last segment with other bytes is another send of the frame (module comment)."""
        source = self._sources.get(src)
        verdict = ReplayVerdict.ACCEPTED
        if source is None or epoch > source.epoch:
            verdict = ReplayVerdict.ACCEPTED if source is None else ReplayVerdict.NEW_EPOCH
            source = self._sources[src] = _Source(epoch, seq)
        elif epoch < source.epoch:
            return ReplayVerdict.OLD_EPOCH
        elif seq <= source.highest - self.segment_window:
            return ReplayVerdict.TOO_OLD
        entry = source.segmented.get(seq)
        if entry is None:
            if seq <= source.segment_floor:
                return ReplayVerdict.TOO_OLD
            entry = source.segmented[seq] = _Segmented()
            while len(source.segmented) > MAX_SEGMENTED:
                oldest = next(iter(source.segmented))
                del source.segmented[oldest]
                source.segment_floor = max(source.segment_floor, oldest)
        elif entry.state is SegmentState.EXPIRED:
            return ReplayVerdict.CLOSED
        round_ &= _ROUNDS - 1
        if variant:
            sent = (round_, bytes(variant))
            if sent in entry.last or sum(1 for r, _ in entry.last if r == round_) >= MAX_SEND_VARIANTS:
                return ReplayVerdict.REPLAY
            entry.last.add(sent)
        else:
            bit = 1 << segment
            if entry.rounds[round_] & bit:
                return ReplayVerdict.REPLAY
            entry.rounds[round_] |= bit
        if seq > source.highest:
            self._advance(source, seq)
        return verdict

    def mark(self, src: int, seq: int, state: SegmentState) -> None:
        """The receiver's reassembly of `src`'s frame `seq` (in its current epoch) completed or expired."""
        source = self._sources.get(src)
        entry = None if source is None else source.segmented.get(seq)
        if entry is not None:
            entry.state = state

    def may_open(self, src: int, seq: int) -> bool:
        """Whether a segment of `src`'s frame `seq` may open a reassembly: not once it completed or
        expired here."""
        source = self._sources.get(src)
        entry = None if source is None else source.segmented.get(seq)
        return entry is None or entry.state is SegmentState.OPEN

    def _advance(self, source: _Source, seq: int) -> None:
        source.highest = seq
        floor = seq - self.window
        if len(source.seen) > self.window:
            for old in [s for s in source.seen if s <= floor]:
                del source.seen[old]
        if source.segmented and next(iter(source.segmented)) <= seq - self.segment_window:
            for old in [s for s in source.segmented if s <= seq - self.segment_window]:
                del source.segmented[old]
