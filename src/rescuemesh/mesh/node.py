"""The sans-IO mesh node, one per robot, between its endpoint and its transport (aioquic shape):
logical frames and heard frames in; transmissions, a timer and events out. Owns the receive path,
the relay decision and the outbox; must not know radios, clocks, random numbers or payloads.
"""

# Theory of operation (relaying: Bluetooth Mesh Profile 1.0, 3.4.6; docs/mesh.md)
# ================================================================================
#
# Every frame heard goes through these steps; the first that fails drops and counts it. Step 0: a
# frame for another robot with TTL < 2 ends here, dropped unopened (dropped_passing) unless copies
# of ours wait that it could cancel (30 robots hear a thousand frames a second, most passing by).
#   1. check: length (10..20 bytes, up to 29 for a segment frame), version, AUTH, CRC-32, source
#      (frames.read_on_air)                                -> dropped_corrupt / dropped_malformed
#   2. our own frame heard back (src == our address)      -> dropped_own
#   3. the network message cache (key: the frame without TTL nibble and CRC) -> dropped_cached
#   4. the neighbour table hears its source (hops, rssi, a Heartbeat's init_ttl; may emit
#      NeighbourFound)
#   5. for us (our address or broadcast): by kind, PLAIN -> FrameDelivered, SEGMENT ->
#      reassembly, SEGMENT_ACK -> the SAR sender
#   6. not for our address only (unicast to another robot, or broadcast), relay feature on:
#      TTL >= 2 -> the same bytes with TTL - 1 and a new CRC, due at now + relay_delay_s, and
#      again relay_retransmit_count times, relay_retransmit_interval_s apart (Relay Retransmit,
#      Mesh Profile 4.2.20: a receiver's cache drops the copies it already has);
#      TTL < 2 -> dropped_ttl.
#
# Steps 1-2 (reader.py) remember the frames read recently by the bytes heard (per team where the
# sealer remembers), so a copy that is the same bytes skips AES-CCM; the relayed copy is built once.
#
# Relay suppression (counter-based, Ni et al. 1999; outbox.py): step-3 hits on a frame whose copies
# wait in the outbox are counted; at relay_suppress_after they are cancelled (not those handed out).
#
# TTL on send: a unicast control frame to a destination whose Heartbeat we heard and that the
# neighbour table hears at h hops (not lost) goes out with TTL min(initial_ttl, h + attempt bits),
# one hop more in a sparse team: its path, not the whole team (a PoseUpdate's resends do not add
# their attempt bits: the next update supersedes them). A broadcast, a segmented frame, or
# a destination unknown, lost or never heard in a Heartbeat keeps the endpoint's TTL (Mesh Profile
# 1.0, 3.6.7: heartbeat hop counts "may be used to determine the TTL"). docs/mesh.md 12.
#
# A relay reads the header only (and a segment's SegO/SegN): it relays types it does not know.
#
# With a frame sealer (authenticated frames, docs/protocol.md section 12), step 1 opens the frame
# first: a frame without the AUTH flag, from a source whose epoch is unknown (no Heartbeat heard
# yet), or whose MIC does not verify is dropped (dropped_unauthenticated, dropped_unknown_epoch,
# dropped_forged) and goes no further, not even to a relay; after the cache, the replay window
# (replay.py) drops a frame already accepted or too old (dropped_replay), a segment frame by its own
# (seq, SegO, round) identity, so a replayed segment refreshes no liveness, opens no reassembly and
# is not relayed; a transfer whose reassembly completed or expired here opens none again. A frame
# that opens under a newer epoch of its source emits PeerRestarted (its old reassemblies are
# dropped). We seal under our endpoint's epoch and re-seal relays with TTL - 1 under the source's.
# The caller draws relay_delay_s (Bluetooth Mesh relays wait a random 0..~20 ms so that neighbours
# do not all transmit at once); the node draws nothing.

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from rescuemesh.protocol import BROADCAST, FrameError, MessageType, decode_frame, encode_frame
from rescuemesh.protocol.codec import (
    MAX_CONTROL_FRAME_BYTES, MAX_SEQ, MAX_TTL, MAX_UNICAST_ADDRESS, PROTOCOL_VERSION, FrameFlags, Header)
from rescuemesh.protocol.messages import SegmentAck

from .cache import NetworkCache
from .config import MeshConfig
from .events import MeshEvent, PeerRestarted, SegmentsResent, frame_delivered
from .frames import ATTEMPT_SHIFT, TTL_MASK, FrameKind, FrameView, cache_key, read_logical, with_ttl
from .neighbours import NeighbourInfo, NeighbourTable
from .outbox import Outbox
from .reader import FrameReader
from .reassembly import SarReceiver
from .replay import ReplayVerdict, ReplayWindow, SegmentState
from .sar import SarSender
from .segments import read_segment_header
from .stats import MeshStats

#: Types whose resends keep the first send's TTL: a PoseUpdate is superseded by the next within
#: 0.5 s, and its resends flooding two or three hops were a third of a 30-robot convoy's airtime.
_SUPERSEDED_TYPES = frozenset({MessageType.POSE_UPDATE})
_MAX_TX_EPOCHS = 64  # segmented frames whose epoch the node remembers (a transfer is numbered in one epoch)
_HEARTBEAT_BYTES = 17  # 6 header + active_command + init_ttl + epoch (4) + capabilities + 4 CRC
_HEARTBEAT_INIT_TTL_BYTE = 7
_SEGMENT_DATA_AT = 9  # header 6 + SegO|SegN 3
_HEARTBEAT = int(MessageType.HEARTBEAT)
_PLAIN, _SEGMENT = FrameKind.PLAIN, FrameKind.SEGMENT
_ACCEPTED, _NEW_EPOCH = ReplayVerdict.ACCEPTED, ReplayVerdict.NEW_EPOCH


@dataclass(frozen=True, slots=True)
class Transmission:
    """One frame to put on the air, with what a transport or a trace needs to know about it:
    `ttl` as sent, `relayed` True for a frame we re-broadcast, `segment` its SegO and `segments`
    SegN + 1 for a segment frame (None otherwise); `key`: the network cache key every receiver that
    opens it files it under (b"" when unknown), so that a transport can recognise the copies a
    receiver has cached without asking it (the simulated medium's front door)."""

    data: bytes
    src: int
    dst: int
    msg_type: int
    seq: int
    ttl: int
    relayed: bool
    segment: int | None
    segments: int | None
    key: bytes = field(default=b"", compare=False, repr=False)


class MeshNode:
    """One robot's network layer. Drive it with:

    - send(frame, now) for every frame its endpoint produces;
    - receive(data, now, rssi_dbm=..., relay_delay_s=...) for every frame its radio hears;
    - transmissions(now) after any of those, and when get_timer() comes, to get what to put on air;
    - get_timer() / handle_timer(now) for relay delays, segment pacing, SAR and liveness timers;
    - next_event() until None: FrameDelivered goes to Endpoint.receive(data, now, hops).
    """

    def __init__(self, address: int, config: MeshConfig | None = None, sealer=None) -> None:
        """`sealer`: a rescuemesh.mesh.security.FrameSealer for authenticated frames, None for the
        CRC frames of an insecure team."""
        if not (isinstance(address, int) and 0 <= address <= MAX_UNICAST_ADDRESS):
            raise ValueError(f"address must be 0..{MAX_UNICAST_ADDRESS}, got {address!r}")
        self.address = address
        self.config = config if config is not None else MeshConfig()
        self.sealer = sealer
        self._replay = ReplayWindow() if sealer is not None else None
        self._tx_epoch: dict[tuple[int, int], int] = {}  # (dst, seq) of segmented frames -> epoch
        self._rx_epoch = 0  # epoch the frame being handled opened under
        #: Numbers for frames the node originates (SegmentAcks): the endpoint's counter, so that
        #: one robot has one sequence. NetworkStack sets it; (seq, epoch) per call.
        self.number = self._own_number
        self._stats = MeshStats()
        #: The network message cache; a transport's front door may read it (docs/mesh.md, "The front door").
        self.cache = NetworkCache(self.config.cache_size, self.config.cache_lifetime_s)
        self._reader = FrameReader(address, sealer, self._replay, self._stats)
        self._neighbours = NeighbourTable(self.config)
        self._events: deque[MeshEvent] = deque()
        self._outbox: Outbox[Transmission] = Outbox(self.config.relay_suppress_after, self.config.relay_pace_s,
                                                     self.config.relay_max_wait_s, self.cache.set_waiting)
        self._ack_seq = 0  # seq of the SegmentAcks this node originates (docs/mesh.md)
        self._sender = SarSender(
            self.config, self._stats, self._neighbours.hops_to, self._queue_segment, self._events.append
        )
        self._receiver = SarReceiver(
            self.config, self._stats, self._send_ack, self._deliver, self._neighbours.init_ttl_of,
            self._replay.may_open if self._replay is not None else None,
            self._reassembly_closed if self._replay is not None else None,
            lambda src, seq, now: self._events.append(SegmentsResent(src, seq, now)))
        # what a frame for us becomes, by kind (a PLAIN one: delivered, in receive)
        self._local = {FrameKind.SEGMENT: self._on_segment, FrameKind.SEGMENT_ACK: self._on_segment_ack}

    @property
    def stats(self) -> MeshStats:
        """What the node saw and did, the copies a transport recognised at its front door included."""
        stats, (received, cached, passing) = self._stats, self.cache.take_counts()
        if received:
            stats.received, stats.dropped_cached = stats.received + received, stats.dropped_cached + cached
            stats.dropped_passing += passing
        return stats

    # --- from the endpoint -----------------------------------------------------------------------

    def send(self, frame: bytes, now: float, epoch: int = 0) -> None:
        """Queue a logical frame our endpoint encoded: as it is up to 20 bytes, otherwise as segment
        frames paced by the timer. Raises ValueError for bytes that are not a valid frame (length
        10..8192, version, CRC, no SEG/AUTH flag), a frame from another source, or a segmented one
        to the broadcast address."""
        try:
            view = read_logical(bytes(frame))
        except FrameError as exc:
            raise ValueError(f"cannot send: {exc}") from exc
        if view.src != self.address:
            raise ValueError(f"frame from {view.src} handed to the mesh node of {self.address}")
        frame = bytes(frame)
        if len(frame) <= MAX_CONTROL_FRAME_BYTES:
            self._stats.sent += 1
            ttl = self._unicast_ttl(frame, view, now)
            if ttl != view.ttl:
                frame = with_ttl(frame, ttl)
                self._stats.sent_short_ttl += 1
            self._outbox.push(now, Transmission(self._seal(frame, epoch), view.src, view.dst, view.msg_type,
                                                view.seq, ttl, False, None, None, self._key(frame, epoch)))
        elif view.dst == BROADCAST:
            raise ValueError("a frame longer than 20 bytes is segmented and needs a unicast destination")
        else:
            self._stats.sent += 1
            self._tx_epoch[(view.dst, view.seq)] = epoch
            while len(self._tx_epoch) > _MAX_TX_EPOCHS:
                del self._tx_epoch[next(iter(self._tx_epoch))]
            self._sender.start(view, frame, now)

    # --- from the radio --------------------------------------------------------------------------

    def receive(
        self, data: bytes, now: float, *, rssi_dbm: float | None = None, relay_delay_s: float = 0.0
    ) -> bool:
        """Handle a frame heard on the air (steps in the module comment). True when it was accepted;
        False when it was dropped, and then the node has nothing new to send and no earlier timer
        (a transport may skip asking). Never raises for any bytes; ValueError only for a
        relay_delay_s that is negative or not finite."""
        if not 0.0 <= relay_delay_s < math.inf:  # NaN compares False
            raise ValueError(f"relay_delay_s must be finite and >= 0, got {relay_delay_s!r}")
        stats = self._stats
        stats.received += 1
        data = bytes(data)
        address = self.address
        if len(data) > 3 and data[3] != address and data[3] != BROADCAST and data[0] & TTL_MASK < 2 \
                and not self._outbox.holds_relays():  # step 0
            stats.dropped_passing += 1
            return False
        read = self._reader.read(data)
        if read is None:
            return False
        data, view, key, epoch, derived = read
        self._rx_epoch = epoch
        # a frame whose relayed copies still wait here is a duplicate even if its cache entry expired
        if not self.cache.check_and_add(key, now) or self._outbox.waiting(key):
            stats.dropped_cached += 1
            cancelled = self._outbox.heard_again(key, view.ttl)
            if cancelled:
                stats.relays_suppressed += 1
                stats.relay_copies_suppressed += cancelled
            return False
        replay = self._replay
        if replay is not None:
            if view.kind is _SEGMENT:
                seg_o, seg_n = read_segment_header(data)
                variant = data[_SEGMENT_DATA_AT:-4] if seg_o == seg_n else b""
                verdict = replay.accept_segment(view.src, epoch, view.seq, seg_o, data[1] >> ATTEMPT_SHIFT, variant)
            else:
                verdict = replay.accept(view.src, epoch, view.seq, data[1] >> ATTEMPT_SHIFT)
            if verdict is not _ACCEPTED:
                if verdict is not _NEW_EPOCH:
                    stats.dropped_replay += 1
                    return False
                # its old epoch's frames no longer open here: none is recognised unopened any more
                self.cache.hold_all()
                self._reader.forget()
                self._receiver.forget_source(view.src)
                self._events.append(PeerRestarted(view.src, self._rx_epoch, now))
        stats.accepted += 1
        beat = view.msg_type == _HEARTBEAT
        hops, found = self._neighbours.heard(view.src, view.ttl, now, rssi_dbm,
                                             _announced_init_ttl(data, view) if beat else None)
        if found is not None:
            self._events.append(found)
        dst = view.dst
        if dst == address or dst == BROADCAST:
            kind = view.kind
            if kind is _PLAIN:  # most frames for us: _deliver, inline
                stats.delivered += 1
                self._events.append(frame_delivered(data, view.src, hops, rssi_dbm if hops == 1 else None, now))
            else:
                try:
                    self._local[kind](data, view, hops, rssi_dbm if hops == 1 else None, now)
                except FrameError:
                    stats.dropped_malformed += 1
        if dst != address and self.config.relay:
            # a Heartbeat is in no hurry: wait longer, hear others relay it
            self._relay(data, view, now + relay_delay_s * (self.config.heartbeat_relay_delay_scale if beat else 1), key,
                        derived)
        return True

    # --- the aioquic loop ------------------------------------------------------------------------

    def transmissions(self, now: float) -> list[Transmission]:
        """Everything due by `now` s (relays whose delay has passed included), oldest first."""
        out = self._outbox.pop_due(now)
        stats = self._stats
        stats.relays_expired = self._outbox.expired
        for item in out:
            stats.transmitted += 1
            stats.bytes_transmitted += len(item.data)
        return out

    def get_timer(self) -> float | None:
        """Earliest time in s at which handle_timer() or transmissions() has work, or None."""
        best = self._outbox.next_due()
        for t in (self._sender.next_timer(), self._receiver.next_timer(), self._neighbours.next_deadline()):
            if t is not None and (best is None or t < best):
                best = t
        return best

    def abandon_transfers(self, awaited, now: float) -> None:
        """End the transfers whose frame `awaited(dst, seq)` says nobody waits for (sar.py, abandon)."""
        self._sender.abandon(awaited, now)

    def handle_timer(self, now: float) -> None:
        """Neighbours lost or forgotten, SAR deadlines and acks, the next paced segment."""
        self._events.extend(self._neighbours.expire(now))
        self._receiver.handle_timer(now)
        self._sender.handle_timer(now)

    def next_event(self) -> MeshEvent | None:
        """The oldest event not yet pulled, or None."""
        return self._events.popleft() if self._events else None

    # --- neighbours ------------------------------------------------------------------------------

    def hops_to(self, address: int) -> int | None:
        """Hops to `address` from its latest frame, None if never heard (or forgotten)."""
        return self._neighbours.hops_to(address)

    def is_reachable(self, address: int, now: float) -> bool:
        """Heard and not lost at `now` s (docs/mesh.md, "Liveness")."""
        return self._neighbours.is_reachable(address, now)

    def neighbours(self) -> list[NeighbourInfo]:
        """A snapshot of the neighbour table, by address."""
        return self._neighbours.snapshot()

    # --- internals -------------------------------------------------------------------------------

    def _unicast_ttl(self, frame: bytes, view: FrameView, now: float) -> int:
        """TTL for a control frame we originate (module comment, "TTL on send")."""
        table = self._neighbours
        if (not self.config.unicast_ttl_from_hops or view.dst == BROADCAST
                or not table.is_reachable(view.dst, now) or not table.heartbeat_heard(view.dst)):
            return view.ttl
        sparse = table.reachable_count(now) <= self.config.sparse_neighbours  # airtime to spare
        resend = 0 if view.msg_type in _SUPERSEDED_TYPES else frame[1] >> ATTEMPT_SHIFT
        slack = self.config.unicast_ttl_slack + resend + sparse
        return min(view.ttl, table.hops_to(view.dst) + slack)

    def _relay(self, data: bytes, view: FrameView, due: float, key: bytes, derived: list) -> None:
        """`derived`: the Read's cell; it keeps the relayed copy (one per frame read, for all readers)."""
        if view.ttl < 2:
            self._stats.dropped_ttl += 1
            return
        relayed = derived[0]
        if relayed is None:
            segment = segments = None
            if view.kind is _SEGMENT:
                segment, last = read_segment_header(data)
                segments = last + 1
            ttl = view.ttl - 1
            relayed = derived[0] = Transmission(self._seal(with_ttl(data, ttl), self._rx_epoch), view.src, view.dst,
                                                view.msg_type, view.seq, ttl, True, segment, segments, key)
        self._stats.relayed += 1
        interval = self.config.relay_retransmit_interval_s
        # Mesh Profile 4.2.20 Relay Retransmit, for control frames. A segment is relayed once (block acks
        # repair it; 3 copies cut 2-hop bulk fivefold), a Heartbeat too (the next comes a period later).
        unsegmented = relayed.segment is None
        once = not unsegmented or view.msg_type == _HEARTBEAT
        copies = 1 if once else 1 + self.config.relay_retransmit_count
        for k in range(copies):
            self._outbox.push(due + k * interval, relayed, key, relayed.ttl, paced=unsegmented)

    def _deliver(self, frame: bytes, src: int, hops: int, rssi_dbm: float | None, now: float) -> None:
        self._stats.delivered += 1
        self._events.append(frame_delivered(frame, src, hops, rssi_dbm, now))

    def _on_segment(self, data: bytes, view: FrameView, hops: int, rssi: float | None, now: float) -> None:
        self._receiver.on_segment(data, view, hops, rssi, now)

    def _on_segment_ack(self, data: bytes, view: FrameView, hops: int, rssi: float | None, now: float) -> None:
        ack = decode_frame(data)[1]  # raises FrameError (counted) for a bad payload
        self._sender.on_ack(view.src, ack.ref_seq, ack.base, ack.bitmap, now)

    def _queue_segment(self, view: FrameView, data: bytes, index: int, total: int, round_: int,
                       now: float) -> None:
        epoch = self._tx_epoch.get((view.dst, view.seq), 0)
        self._outbox.push(now, Transmission(self._seal(data, epoch), view.src, view.dst, view.msg_type, view.seq,
                                            view.ttl, False, index, total, self._key(data, epoch)))

    def _send_ack(self, dst: int, ref_seq: int, base: int, bitmap: int, now: float) -> None:
        ttl = self.config.initial_ttl
        seq, epoch = self.number()
        header = Header(PROTOCOL_VERSION, FrameFlags.NONE, ttl, 0, MessageType.SEGMENT_ACK, self.address, dst, seq)
        data = encode_frame(header, SegmentAck(ref_seq, base, bitmap))
        self._outbox.push(now, Transmission(self._seal(data, epoch), self.address, dst, MessageType.SEGMENT_ACK,
                                            seq, ttl, False, None, None, self._key(data, epoch)))
        self._stats.acks_sent += 1

    def _reassembly_closed(self, src: int, seq: int, complete: bool) -> None:
        self._replay.mark(src, seq, SegmentState.COMPLETE if complete else SegmentState.EXPIRED)

    def _own_number(self) -> tuple[int, int]:
        """(seq, epoch) for a SegmentAck when no endpoint lends its counter (a bare node in tests)."""
        seq = self._ack_seq
        self._ack_seq = (self._ack_seq + 1) & MAX_SEQ
        return seq, 0

    # --- authenticated frames ----------------------------------------------------------------------

    def _seal(self, frame: bytes, epoch: int) -> bytes:
        return frame if self.sealer is None else self.sealer.seal(frame, epoch)

    def _key(self, frame: bytes, epoch: int) -> bytes:  # what FrameReader.read files it under
        return cache_key(frame, None if self.sealer is None else epoch)


def _announced_init_ttl(data: bytes, view: FrameView) -> int | None:
    """The init_ttl a Heartbeat carries (payload byte 1, frame byte 7), None for other frames."""
    if (view.kind is FrameKind.PLAIN and view.msg_type == MessageType.HEARTBEAT
            and len(data) == _HEARTBEAT_BYTES and data[_HEARTBEAT_INIT_TTL_BYTE] <= MAX_TTL):
        return data[_HEARTBEAT_INIT_TTL_BYTE]
    return None
