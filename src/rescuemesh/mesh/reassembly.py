"""The receiving half of segmentation and reassembly (theory of operation in sar.py): reassemblies
by (src, seq), the ack and incomplete timers, and the memory of completed frames. Must not know
relays, the cache, the sender's transfers, clocks or the endpoint.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

from rescuemesh.protocol import BROADCAST
from rescuemesh.protocol.errors import MalformedPayload

from .config import MeshConfig
from .frames import FrameView
from .segments import Segment, block_ack, is_resend_tail, parse_segment, rebuild_frame
from .stats import MeshStats

#: (dst, ref_seq, base, bitmap, now) -> None: send a SegmentAck.
AckSink = Callable[[int, int, int, int, float], None]
#: (frame, src, hops, rssi_dbm, now) -> None: hand a logical frame upward.
FrameSink = Callable[[bytes, int, int, "float | None", float], None]
#: (src, seq) -> whether a reassembly may open for it (the replay window: not once finished).
OpenCheck = Callable[[int, int], bool]
#: (src, seq, complete) -> None: a reassembly ended, delivered (True) or timed out or corrupt (False).
CloseSink = Callable[[int, int, bool], None]


@dataclass(slots=True)
class Reassembly:
    """Segments of frame `seq` from `src` received so far. Times in s."""

    first: bytes  # bytes 0-5 of its first segment: the frame's header, SEG set, round bits
    seg_n: int
    msg_type: int
    pieces: list[bytes | None]
    received: int
    base: int  # every index < base is held
    max_ttl: int  # highest TTL a segment arrived with (the frame's TTL is at least that)
    hops: int
    rssi_dbm: float | None
    last_new_s: float  # incomplete timer runs from here
    ack_due_s: float | None = None
    last_ack_s: float = float("-inf")


@dataclass(slots=True)
class Completed:
    """A reassembled frame, remembered for incomplete_timeout_s after completion."""

    seg_n: int
    frame: bytes
    last_piece: bytes
    expires_s: float
    last_ack_s: float


class SarReceiver:
    """Reassemblies keyed by (src, seq), bounded per source and in total."""

    def __init__(
        self,
        config: MeshConfig,
        stats: MeshStats,
        send_ack: AckSink,
        deliver: FrameSink,
        init_ttl_of: Callable[[int], int | None],
        may_open: OpenCheck | None = None,
        on_closed: CloseSink | None = None,
        on_resent: Callable[[int, int, float], None] | None = None,
    ) -> None:
        self._config = config
        self._on_resent = on_resent  # (src, seq, now): segments of a frame we acknowledged came again
        self._may_open = may_open
        self._on_closed = on_closed
        self._stats = stats
        self._send_ack = send_ack
        self._deliver = deliver
        self._init_ttl_of = init_ttl_of
        self._active: dict[tuple[int, int], Reassembly] = {}
        self._per_source: dict[int, int] = {}
        self._completed: OrderedDict[tuple[int, int], Completed] = OrderedDict()

    def __len__(self) -> int:
        return len(self._active)

    def on_segment(
        self, data: bytes, view: FrameView, hops: int, rssi_dbm: float | None, now: float
    ) -> None:
        """A segment frame for us (header and CRC checked). Raises MalformedPayload (the node
        counts it) for a bad segment header or one inconsistent with its reassembly."""
        if view.dst == BROADCAST:
            raise MalformedPayload("segmented frames are unicast only")
        segment = parse_segment(data)
        key = (view.src, view.seq)
        done = self._completed.get(key)
        if done is not None and self._is_same_message(done, segment):
            self._late(key, done, segment, hops, rssi_dbm, now)
            return
        if done is not None:  # another frame under a reused seq (the source restarted)
            del self._completed[key]
        entry = self._active.get(key)
        if entry is None:
            entry = self._open(key, data, segment, view, hops, rssi_dbm, now)
            if entry is None:
                return
        elif segment.seg_n != entry.seg_n or segment.msg_type != entry.msg_type:
            raise MalformedPayload(
                f"segment says SegN {segment.seg_n}, type {segment.msg_type}; its frame has "
                f"SegN {entry.seg_n}, type {entry.msg_type}"
            )
        if entry.pieces[segment.seg_o] is not None:  # the sender missed our last ack
            self._stats.segments_duplicate += 1
            if now - entry.last_ack_s >= self._config.duplicate_ack_interval_s:
                self._ack(key, entry, now)
                return
        else:
            self._stats.segments_received += 1
            entry.pieces[segment.seg_o] = segment.data
            entry.received += 1
            entry.max_ttl = max(entry.max_ttl, view.ttl)
            entry.hops, entry.rssi_dbm, entry.last_new_s = hops, rssi_dbm, now
            if entry.received == len(entry.pieces):
                self._complete(key, entry, now)
                return
        if entry.ack_due_s is None:
            entry.ack_due_s = now + self._config.ack_delay_s(entry.hops)

    def next_timer(self) -> float | None:
        """Earliest ack, incomplete or forget time in s, or None."""
        if not self._active and not self._completed:  # the common case, asked after every frame heard
            return None
        incomplete_s = self._config.incomplete_timeout_s
        times = [e.last_new_s + incomplete_s for e in self._active.values()]
        times += [e.ack_due_s for e in self._active.values() if e.ack_due_s is not None]
        if self._completed:
            times.append(next(iter(self._completed.values())).expires_s)
        return min(times, default=None)

    def handle_timer(self, now: float) -> None:
        """Send due acks, discard reassemblies past the incomplete timer, forget old completions."""
        incomplete_s = self._config.incomplete_timeout_s
        for key, entry in list(self._active.items()):
            if now >= entry.last_new_s + incomplete_s:
                self._close(key)
                self._stats.reassemblies_expired += 1
                if self._on_closed is not None:
                    self._on_closed(key[0], key[1], False)
            elif entry.ack_due_s is not None and entry.ack_due_s <= now:
                self._ack(key, entry, now)
        while self._completed and next(iter(self._completed.values())).expires_s <= now:
            self._completed.popitem(last=False)

    def forget_source(self, src: int) -> None:
        """`src` restarted (a new epoch): its reassemblies and completed frames belong to its old run."""
        for key in [k for k in self._active if k[0] == src]:
            self._close(key)
        for key in [k for k in self._completed if k[0] == src]:
            del self._completed[key]

    # internals

    def _open(
        self, key: tuple[int, int], data: bytes, segment: Segment, view: FrameView,
        hops: int, rssi_dbm: float | None, now: float,
    ) -> Reassembly | None:
        src = key[0]
        if (self._may_open is not None and not self._may_open(src, key[1])
                or len(self._active) >= self._config.max_reassemblies
                or self._per_source.get(src, 0) >= self._config.max_reassemblies_per_source):
            self._stats.reassemblies_rejected += 1
            return None
        entry = Reassembly(
            bytes(data[:6]), segment.seg_n, segment.msg_type, [None] * (segment.seg_n + 1),
            0, 0, view.ttl, hops, rssi_dbm, now,
        )
        self._active[key] = entry
        self._per_source[src] = self._per_source.get(src, 0) + 1
        return entry

    def _ack(self, key: tuple[int, int], entry: Reassembly, now: float) -> None:
        entry.ack_due_s = None
        entry.last_ack_s = now
        entry.base, bitmap = block_ack(entry.pieces, entry.base)
        self._send_ack(key[0], key[1], entry.base, bitmap, now)

    def _close(self, key: tuple[int, int]) -> None:
        del self._active[key]
        src = key[0]
        self._per_source[src] -= 1
        if not self._per_source[src]:
            del self._per_source[src]

    def _init_ttl(self, src: int) -> int:
        init_ttl = self._init_ttl_of(src)
        return self._config.initial_ttl if init_ttl is None else init_ttl

    def _complete(self, key: tuple[int, int], entry: Reassembly, now: float) -> None:
        self._close(key)
        body = b"".join(entry.pieces)  # type: ignore[arg-type]  (all pieces held)
        frame = rebuild_frame(entry.first, body, self._init_ttl(key[0]), entry.max_ttl)
        if frame is None:
            self._stats.reassemblies_corrupt += 1
            if self._on_closed is not None:
                self._on_closed(key[0], key[1], False)
            return
        self._stats.reassemblies_complete += 1
        self._completed[key] = Completed(
            entry.seg_n, frame, entry.pieces[-1], now + self._config.incomplete_timeout_s, now
        )
        self._completed.move_to_end(key)
        while len(self._completed) > self._config.completed_memory:
            self._completed.popitem(last=False)
        if self._on_closed is not None:
            self._on_closed(key[0], key[1], True)
        self._send_ack(key[0], key[1], entry.seg_n + 1, 0, now)
        self._deliver(frame, key[0], entry.hops, entry.rssi_dbm, now)

    @staticmethod
    def _is_same_message(done: Completed, segment: Segment) -> bool:
        """A segment of the completed frame, or of a resend of it. Its last segment, which every
        transfer sends first, tells a resend from another message reusing the seq."""
        if segment.seg_n != done.seg_n:
            return False
        if segment.seg_o != segment.seg_n or segment.data == done.last_piece:
            return True
        return is_resend_tail(done.frame, segment.data)

    def _late(
        self, key: tuple[int, int], done: Completed, segment: Segment, hops: int,
        rssi_dbm: float | None, now: float,
    ) -> None:
        """A segment of a frame already reassembled: the complete ack again (at most one per
        duplicate_ack_interval_s); a second delivery only for an endpoint resend, recognised by a
        last segment that differs (it ends with the frame's CRC-32, which the attempt bits change)
        yet fits the frame. The frame delivered again is the one first delivered: the endpoint
        matches a resend by source, seq and message, and answers it from its duplicate cache."""
        self._stats.segments_late += 1
        resend = segment.seg_o == segment.seg_n and segment.data != done.last_piece
        if resend:
            done.last_piece = segment.data
            self._stats.redeliveries += 1
            self._deliver(done.frame, key[0], hops, rssi_dbm, now)
        if resend or now - done.last_ack_s >= self._config.duplicate_ack_interval_s:
            done.last_ack_s = now
            self._send_ack(key[0], key[1], done.seg_n + 1, 0, now)
            if not resend and self._on_resent is not None:  # (a resend is delivered: answered above)
                self._on_resent(key[0], key[1], now)
