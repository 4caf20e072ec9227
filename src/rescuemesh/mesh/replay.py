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
# Segment frames share their message's number across all segments and rounds: for them only the
# epoch and a too-old rule over SEGMENT_WINDOW numbers apply (a transfer takes seconds while its
# source goes on numbering other frames; reassembly drops segments it already holds).

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


class ReplayVerdict(Enum):
    ACCEPTED = "accepted"
    NEW_EPOCH = "new_epoch"  # accepted, and the source's epoch moved forward
    REPLAY = "replay"
    TOO_OLD = "too_old"
    OLD_EPOCH = "old_epoch"

    @property
    def accepted(self) -> bool:
        return self in (ReplayVerdict.ACCEPTED, ReplayVerdict.NEW_EPOCH)


@dataclass(slots=True)
class _Source:
    epoch: int
    highest: int
    seen: dict[int, int] = field(default_factory=dict)  # seq -> bit mask of accepted sends


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
        return sum(len(s.seen) for s in self._sources.values())

    def epoch_of(self, src: int) -> int | None:
        source = self._sources.get(src)
        return None if source is None else source.epoch

    def accept(self, src: int, epoch: int, seq: int, send: int | None) -> ReplayVerdict:
        """Judge frame `seq` (send `send`, 0..3; None for a segment frame) of `src` in `epoch`, and
        record it if accepted."""
        source = self._sources.get(src)
        if source is None or epoch > source.epoch:
            verdict = ReplayVerdict.ACCEPTED if source is None else ReplayVerdict.NEW_EPOCH
            source = self._sources[src] = _Source(epoch, seq)
            if send is not None:
                source.seen[seq] = 1 << send
            return verdict
        if epoch < source.epoch:
            return ReplayVerdict.OLD_EPOCH
        if send is None:
            if seq <= source.highest - self.segment_window:
                return ReplayVerdict.TOO_OLD
            source.highest = max(source.highest, seq)
            return ReplayVerdict.ACCEPTED
        if seq <= source.highest - self.window:
            return ReplayVerdict.TOO_OLD
        bit = 1 << min(send, MAX_SENDS_TRACKED - 1)
        mask = source.seen.get(seq, 0)
        if mask & bit:
            return ReplayVerdict.REPLAY
        source.seen[seq] = mask | bit
        if seq > source.highest:
            source.highest = seq
            floor = seq - self.window
            if len(source.seen) > self.window:
                for old in [s for s in source.seen if s <= floor]:
                    del source.seen[old]
        return ReplayVerdict.ACCEPTED
