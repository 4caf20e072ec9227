"""The simulated radio medium: BLE advertising airtime, one transmit queue per radio, collisions at
each receiver, and a discrete-event pump around the robots' sans-IO network stacks.

Owns: when each frame is on the air, who hears it, collisions, the extra `--loss`, per-pair random
streams, the one timer heap, statistics and records. Must not know: frame contents (it reads the
metadata the mesh layer attaches to each Transmission, never the bytes), robots, physics.
"""

# Theory of operation
# ===================
#
# Everything happens at event times on one heap, so a frame's fate never depends on the 50 ms
# control tick. Three kinds of event:
#
#   TX_START  a radio starts its next queued frame. The frame occupies the air for the channel's
#             airtime (a legacy advertisement on the three advertising channels, about 1.1 ms).
#             For every other radio that can hear it at all (channel.audible), a reception is
#             opened over [start, end] with the channel's verdict for that frame (fading, PER):
#             together they are the frame's "burst".
#             Receptions that overlap at one receiver collide: each is lost unless it is stronger
#             than the other by the co-channel rejection ratio (capture). Every advertiser sends
#             its three PDUs on channels 37, 38, 39 in that order and a scanner listens on one
#             channel, so two events collide only when their starts are closer than one PDU (a
#             third of the event); events further apart meet on different channels. A radio that
#             transmits cannot receive at all during its event (half duplex).
#   ARRIVAL   a burst ends: at each radio where nothing spoiled it and the extra --loss draw
#             passes, the stack gets the bytes (with the RSSI and a random relay delay drawn here,
#             since the sans-IO mesh layer draws no random numbers), in the order radios attached.
#             One heap event per frame, not one per reception: a team of 30 hears 29 of each.
#   TIMER     a stack's timer is due (resends, segments, relays, neighbour expiry).
#
# After any call into a stack, its new transmissions are queued on its radio and its timer is
# re-read and pushed on the heap if it changed: no scan of every stack per event. A stack whose
# receive() says False dropped the frame (most frames a team of 30 hears are copies) and is not
# asked: its timer can only have moved later, so a heap entry that comes due early re-reads the
# timer and pushes the new one. A radio starts a frame at max(now, previous start + advertising
# interval) + advDelay, as a BLE advertiser does (Core Vol 6 Part B 4.4.2.2.1).
#
# Randomness: advDelay and relay delays come from a stream per radio; fading and PER draws from a
# stream per ordered pair (sender, receiver), and the extra --loss from another: adding a robot
# that no one hears changes nothing for the others. Same seed, same run. Every stream is a
# UniformStream (radio/streams.py): the generator's numbers in its order, drawn 128 at a time.

from __future__ import annotations

import heapq
import itertools
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Protocol

import numpy as np

from rescuemesh.protocol import BROADCAST
from rescuemesh.radio import ChannelModel, LossCause, UniformStream
from rescuemesh.radio.channel import ADV_CHANNELS

#: At most this many events in one pump: a runaway guard.
MAX_EVENTS_PER_PUMP = 1_000_000


@dataclass(frozen=True)
class AirTiming:
    """Advertiser timing, in s.

    adv_interval_s: least time between the starts of two frames from one radio: 20 ms, the minimum
        advertising interval of non-connectable advertising since Bluetooth 5.0 (Core Vol 6 Part B
        4.4.2.2.1) and Mesh 1.1's segment interval.
    adv_delay_max_s: advDelay, a pseudo-random 0..10 ms added before every advertising event (same
        section), so that two advertisers do not collide forever.
    relay_delay_max_s: a relay re-broadcasts after a random 0..10 ms (Mesh Profile 3.4.6.3, "a small
        random delay"), drawn here and handed to the mesh layer.
    capture_db: a reception survives an overlapping one if it is at least this much stronger: 21 dB,
        the co-channel rejection a BLE receiver must meet (Core Vol 6 Part A 4.2, C/I co-channel).
    """

    adv_interval_s: float = 0.020
    adv_delay_max_s: float = 0.010
    relay_delay_max_s: float = 0.010
    capture_db: float = 21.0

    def __post_init__(self) -> None:
        for name in ("adv_interval_s", "adv_delay_max_s", "relay_delay_max_s", "capture_db"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")


class NetworkStack(Protocol):
    """What the medium needs of a robot's stack (rescuemesh.mesh.NetworkStack has it)."""

    def receive(self, data: bytes, now: float, *, rssi_dbm: float | None = None,
                relay_delay_s: float = 0.0) -> bool | None: ...  # False: nothing new to send, no earlier timer
    def transmissions(self, now: float) -> list: ...  # rescuemesh.mesh.Transmission
    def get_timer(self) -> float | None: ...
    def handle_timer(self, now: float) -> None: ...


@dataclass
class MediumStats:
    """Counts over the whole run. A transmission is one frame put on the air by one radio (an
    original, a relay or a segment); a reception is one transmission at one other radio that could
    hear it, or at its intended receiver (the destination, or every radio for a broadcast) even
    when that one could not (counted lost out of range or radio off). `unicast_*` and
    `broadcast_*` count the source's own transmissions (first sends and resends) at their intended
    receivers; `relayed_*` the relays' copies at theirs (a relayed copy is not a unicast delivery)."""

    transmissions: int = 0
    relayed_transmissions: int = 0
    segment_transmissions: int = 0
    bytes_on_air: int = 0
    max_frame_bytes: int = 0
    airtime_s: float = 0.0
    dropped_radio_off: int = 0  # frames a silent radio did not send
    receptions_delivered: int = 0
    receptions_lost: dict[str, int] = field(default_factory=lambda: {cause.value: 0 for cause in LossCause})
    unicast_delivered: int = 0
    unicast_lost: int = 0
    broadcast_delivered: int = 0
    broadcast_lost: int = 0
    relayed_delivered: int = 0
    relayed_lost: int = 0

    @property
    def collisions(self) -> int:
        return self.receptions_lost[LossCause.COLLISION.value]

    def as_dict(self) -> dict:
        return {
            "transmissions": self.transmissions,
            "relayed_transmissions": self.relayed_transmissions,
            "segment_transmissions": self.segment_transmissions,
            "bytes_on_air": self.bytes_on_air,
            "max_frame_bytes": self.max_frame_bytes,
            "airtime_s": round(self.airtime_s, 4),
            "dropped_radio_off": self.dropped_radio_off,
            "receptions_delivered": self.receptions_delivered,
            "receptions_lost": dict(self.receptions_lost),
            "collisions": self.collisions,
            "unicast_delivered": self.unicast_delivered,
            "unicast_lost": self.unicast_lost,
            "broadcast_delivered": self.broadcast_delivered,
            "broadcast_lost": self.broadcast_lost,
            "relayed_delivered": self.relayed_delivered,
            "relayed_lost": self.relayed_lost,
        }


@dataclass(slots=True)
class AirRecord:
    """One transmission, for timelines: on the air over [start_s, end_s] from `transmitter`.
    `dst_heard`: whether the destination received this very transmission (None for a broadcast);
    `heard_by`: how many radios received it; `collided`: whether a collision spoiled any reception;
    `seq`: the source's sequence number of the message (its sends, relays and segments share it)."""

    start_s: float
    end_s: float
    transmitter: int
    src: int
    dst: int
    msg_type: int
    relayed: bool
    segment: int | None
    frame: bytes
    dst_heard: bool | None = None
    heard_by: int = 0
    collided: bool = False
    seq: int = -1


class _Event(IntEnum):
    """Event kinds; at equal times a reception ends before a timer fires before a frame starts
    (intervals are half-open: a frame that ends at t does not collide with one that starts at t)."""

    ARRIVAL = 0
    TIMER = 1
    TX_START = 2


@dataclass(slots=True)
class _Radio:
    address: int
    stack: NetworkStack
    position: Callable[[], tuple[float, float]]
    rng: UniformStream
    enabled: bool = True
    #: This radio's streams as a sender, by receiver address: fading and PER, and the extra loss.
    fading: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    queue: deque = field(default_factory=deque)
    tx_scheduled: bool = False
    next_allowed_s: float = float("-inf")
    on_air_until: float = float("-inf")


@dataclass(slots=True)
class _Burst:
    """One frame on the air and its receptions: `receivers` (in attach order) could hear it, each
    with the channel's `verdicts[k]` and what the medium has since spoiled it with, `lost[k]`;
    `slot` maps a receiver's address to k."""

    transmission: object  # rescuemesh.mesh.Transmission
    sender: _Radio
    start: float
    end: float
    record: AirRecord | None
    receivers: list = field(default_factory=list)
    verdicts: list = field(default_factory=list)
    lost: list = field(default_factory=list)
    slot: dict = field(default_factory=dict)


class SimMedium:
    """Moves frames between attached stacks in simulated time, through a channel model.

    `flush(now)` queues what the stacks have to send (call it after the brains ran); `pump(now)`
    processes, in time order, every frame start, reception and stack timer due by `now`.
    """

    def __init__(self, channel: ChannelModel, seed: int, *, extra_loss: float = 0.0,
                 timing: AirTiming | None = None, record: bool = False) -> None:
        if not 0.0 <= extra_loss < 1.0:
            raise ValueError(f"extra loss must be in [0, 1), got {extra_loss!r}")
        self.channel = channel
        self.timing = timing or AirTiming()
        self.extra_loss = extra_loss
        self.stats = MediumStats()
        self.records: list[AirRecord] | None = [] if record else None
        self._seed = int(seed)
        self._radios: dict[int, _Radio] = {}
        self._heap: list = []
        self._order = itertools.count()
        self._timer_at: dict[int, float] = {}
        self._bursts: list[_Burst] = []  # frames on the air or not yet arrived, in start order
        self._now = 0.0
        #: Radio positions read once per pump or flush (the world does not move inside one): a team
        #: of 30 asked each body for its pose 29 times per frame on the air.
        self._xy: dict[int, tuple[float, float]] = {}
        #: Optional observer of every delivery (a test harness, the spoof scenario): called as
        #: observe(transmitter, receiver, data, now, deliver) and must call deliver() itself.
        self.observe: Callable[[int, int, bytes, float, Callable[[], None]], None] | None = None

    # --- set-up ------------------------------------------------------------------------------

    def attach(self, address: int, stack: NetworkStack, position: Callable[[], tuple[float, float]]) -> None:
        if address in self._radios:
            raise ValueError(f"address {address} is already attached")
        self._radios[address] = _Radio(address, stack, position, self._stream(1, address))

    def set_radio_enabled(self, address: int, enabled: bool, now: float) -> None:
        """Switch a radio off (it neither sends nor hears; its queued frames are dropped) or on."""
        radio = self._radio(address)
        radio.enabled = bool(enabled)
        if not enabled:
            self.stats.dropped_radio_off += len(radio.queue)
            radio.queue.clear()
            for burst in self._bursts:
                k = burst.slot.get(address)
                if k is not None and burst.end > now:
                    burst.lost[k] = burst.lost[k] or LossCause.RADIO_OFF

    def radio_enabled(self, address: int) -> bool:
        return self._radio(address).enabled

    # --- the pump ------------------------------------------------------------------------------

    def flush(self, now: float) -> None:
        """Queue, stamped `now`, every frame the stacks have to send (call it after the brains ran
        at `now`, the time the medium was last pumped to)."""
        self._now = max(self._now, now)
        self._xy.clear()
        for radio in self._radios.values():
            self._collect(radio, self._now)

    def pump(self, now: float) -> None:
        """Advance the medium to `now`: every event due by then, in time order. Frames the stacks
        queued since the last pump or flush leave at that earlier time."""
        self.flush(self._now)  # also forgets the positions read before the world moved
        heap = self._heap
        for _ in range(MAX_EVENTS_PER_PUMP):
            if not heap or heap[0][0] > now:
                self._now = max(self._now, now)
                return
            at, kind, _, payload = heapq.heappop(heap)
            self._now = at
            if kind is _Event.ARRIVAL:
                self._arrive(payload, at)
            elif kind is _Event.TIMER:
                self._fire_timer(payload, at)
            else:
                self._start_transmission(payload, at)
        raise RuntimeError(f"radio medium: more than {MAX_EVENTS_PER_PUMP} events in one pump (runaway timers?)")

    # --- internals -----------------------------------------------------------------------------

    def _radio(self, address: int) -> _Radio:
        try:
            return self._radios[address]
        except KeyError:
            raise ValueError(f"no radio with address {address}") from None

    def _position(self, radio: _Radio) -> tuple[float, float]:
        xy = self._xy.get(radio.address)
        if xy is None:
            xy = self._xy[radio.address] = radio.position()
        return xy

    def _stream(self, *key: int) -> UniformStream:
        return UniformStream(np.random.default_rng(np.random.SeedSequence(self._seed, spawn_key=key)))

    def _pair_stream(self, streams: dict, purpose: int, sender: int, receiver: int) -> UniformStream:
        """The stream (purpose, sender, receiver), made the first time it is needed, from `streams`:
        the sender's dict of that purpose by receiver."""
        stream = streams.get(receiver)
        if stream is None:
            stream = streams[receiver] = self._stream(purpose, sender, receiver)
        return stream

    def _push(self, at: float, kind: _Event, payload) -> None:
        heapq.heappush(self._heap, (at, kind, next(self._order), payload))

    def _collect(self, radio: _Radio, now: float) -> None:
        """Queue the stack's new transmissions on its radio and re-arm its timer."""
        transmissions = radio.stack.transmissions(now)
        if transmissions:
            if not radio.enabled:
                self.stats.dropped_radio_off += len(transmissions)
            else:
                radio.queue.extend(transmissions)
                if not radio.tx_scheduled:
                    self._schedule_start(radio, now)
        self._arm_timer(radio, radio.stack.get_timer())

    def _arm_timer(self, radio: _Radio, timer: float | None) -> None:
        if timer is not None and self._timer_at.get(radio.address) != timer:
            self._timer_at[radio.address] = timer
            self._push(max(timer, self._now), _Event.TIMER, radio)

    def _schedule_start(self, radio: _Radio, now: float) -> None:
        timing = self.timing
        delay = radio.rng.random() * timing.adv_delay_max_s if timing.adv_delay_max_s else 0.0
        start = max(now, radio.next_allowed_s, radio.on_air_until) + delay
        radio.tx_scheduled = True
        self._push(start, _Event.TX_START, radio)

    def _fire_timer(self, radio: _Radio, at: float) -> None:
        timer = radio.stack.get_timer()
        if timer is None or timer > at:  # stale: the stack's timer moved (later) since this was pushed
            if self._timer_at.get(radio.address) == at:
                del self._timer_at[radio.address]
            self._arm_timer(radio, timer)  # a stack that dropped a frame was not asked: ask now
            return
        self._timer_at.pop(radio.address, None)
        radio.stack.handle_timer(at)
        self._collect(radio, at)

    def _start_transmission(self, radio: _Radio, start: float) -> None:
        radio.tx_scheduled = False
        if not radio.queue or not radio.enabled:
            return
        transmission = radio.queue.popleft()
        size = len(transmission.data)
        end = start + self.channel.airtime_s(size)
        radio.next_allowed_s = start + self.timing.adv_interval_s
        radio.on_air_until = end
        self._bursts = on_air = [burst for burst in self._bursts if burst.end > start]
        for burst in on_air:  # half duplex: what it was hearing is lost
            k = burst.slot.get(radio.address)
            if k is not None:
                burst.lost[k] = burst.lost[k] or LossCause.HALF_DUPLEX
        self._count_transmission(transmission, size, end - start)
        record = None
        if self.records is not None:
            record = AirRecord(start, end, radio.address, transmission.src, transmission.dst,
                               transmission.msg_type, transmission.relayed, transmission.segment,
                               transmission.data, None if transmission.dst == BROADCAST else False,
                               seq=transmission.seq)
            self.records.append(record)
        burst = _Burst(transmission, radio, start, end, record)
        sender_xy = self._position(radio)
        dst = transmission.dst
        # the loop runs once per frame per other radio: what it needs, read once
        reception, fading = self.channel.reception, radio.fading
        slot, receivers, verdicts, lost = burst.slot, burst.receivers, burst.verdicts, burst.lost
        for receiver in self._radios.values():
            if receiver is radio:
                continue
            address = receiver.address
            verdict = None
            if receiver.enabled:  # OUT_OF_RANGE exactly when not audible, nothing drawn (ChannelModel)
                verdict = reception(sender_xy, self._position(receiver), size,
                                    self._pair_stream(fading, 2, radio.address, address))
            if verdict is None or verdict.cause is LossCause.OUT_OF_RANGE:
                if dst == BROADCAST or dst == address:  # only intended ones count
                    cause = LossCause.RADIO_OFF if not receiver.enabled else LossCause.OUT_OF_RANGE
                    self._count_reception(transmission, receiver, cause)
                continue
            slot[address] = len(receivers)
            receivers.append(receiver)
            verdicts.append(verdict)
            lost.append(LossCause.HALF_DUPLEX if receiver.on_air_until > start else None)
        if burst.receivers:
            for other in on_air:
                self._collide(burst, other)
            on_air.append(burst)
            self._push(end, _Event.ARRIVAL, burst)
        if radio.queue:
            self._schedule_start(radio, end)

    def _collide(self, burst: _Burst, other: _Burst) -> None:
        """Collide `burst` with `other`, still on the air, at every radio that hears both, if their
        PDUs share a channel in time (starts closer than one PDU), unless one captures the radio."""
        start = burst.start
        if start - other.start >= max((burst.end - start) / ADV_CHANNELS, (other.end - other.start) / ADV_CHANNELS):
            return  # their PDUs are on different channels at any instant
        capture = self.timing.capture_db
        slot, lost, verdicts = other.slot, other.lost, other.verdicts
        for k, receiver in enumerate(burst.receivers):
            j = slot.get(receiver.address)
            if j is None:
                continue
            margin = burst.verdicts[k].rssi_dbm - verdicts[j].rssi_dbm
            if margin < capture:
                burst.lost[k] = burst.lost[k] or LossCause.COLLISION
            if -margin < capture:
                lost[j] = lost[j] or LossCause.COLLISION

    def _arrive(self, burst: _Burst, at: float) -> None:
        transmission, sender, record = burst.transmission, burst.sender, burst.record
        data = transmission.data
        relay_delay_max_s, extra_loss, observe = self.timing.relay_delay_max_s, self.extra_loss, self.observe
        for receiver, lost, verdict in zip(burst.receivers, burst.lost, burst.verdicts):
            if lost is None and not receiver.enabled:
                lost = LossCause.RADIO_OFF
            if lost is None and not verdict.delivered:
                lost = verdict.cause or LossCause.BIT_ERRORS
            if lost is None and extra_loss > 0.0:
                stream = self._pair_stream(sender.extra, 3, sender.address, receiver.address)
                if stream.random() < extra_loss:
                    lost = LossCause.EXTRA_LOSS
            self._count_reception(transmission, receiver, lost)
            if record is not None:
                if lost is LossCause.COLLISION:
                    record.collided = True
                if lost is None:
                    record.heard_by += 1
                    if transmission.dst == receiver.address:
                        record.dst_heard = True
            if lost is not None:
                continue
            relay_delay = receiver.rng.random() * relay_delay_max_s if relay_delay_max_s else 0.0
            if observe is None:
                if receiver.stack.receive(data, at, rssi_dbm=verdict.rssi_dbm, relay_delay_s=relay_delay) is False:
                    continue  # dropped: nothing new to send, no earlier timer
            else:
                observe(sender.address, receiver.address, data, at,
                        _delivery(receiver.stack, data, at, verdict.rssi_dbm, relay_delay))
            self._collect(receiver, at)

    def _count_transmission(self, transmission, size: int, airtime_s: float) -> None:
        stats = self.stats
        stats.transmissions += 1
        stats.bytes_on_air += size
        stats.airtime_s += airtime_s
        if size > stats.max_frame_bytes:
            stats.max_frame_bytes = size
        if transmission.relayed:
            stats.relayed_transmissions += 1
        if transmission.segment is not None:
            stats.segment_transmissions += 1

    def _count_reception(self, transmission, receiver: _Radio, lost: LossCause | None) -> None:
        stats = self.stats
        if lost is None:
            stats.receptions_delivered += 1
        else:
            stats.receptions_lost[lost.value] += 1
        if transmission.dst != BROADCAST and transmission.dst != receiver.address:
            return
        if transmission.relayed:
            if lost is None:
                stats.relayed_delivered += 1
            else:
                stats.relayed_lost += 1
        elif transmission.dst == BROADCAST:
            if lost is None:
                stats.broadcast_delivered += 1
            else:
                stats.broadcast_lost += 1
        else:
            if lost is None:
                stats.unicast_delivered += 1
            else:
                stats.unicast_lost += 1


def _delivery(stack: NetworkStack, data: bytes, at: float, rssi: float, relay_delay: float) -> Callable[[], None]:
    def deliver() -> None:
        stack.receive(data, at, rssi_dbm=rssi, relay_delay_s=relay_delay)

    return deliver
