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
# Receptions are computed by compiled kernels over arrays indexed by radio (medium_kernels.py): one
# call opens a frame's receptions at every radio, one collides two overlapping frames, one settles
# a frame's receptions when it ends; Python is left with a call per stack that gets the frame. The
# channel's mean power per pair of radios is kept in a matrix and asked of the channel again only for
# pairs of which a radio moved to another cell of the channel's quantum (ChannelModel.mean_rx_power_dbm,
# itself cached by cell pair).
#
# Randomness: advDelay comes from a stream per radio (a UniformStream, radio/streams.py); every draw
# per reception (fading and PER, the extra --loss, the relay delay handed to the stack) is a
# counter-based uniform keyed by (seed, purpose, the two radios, the sender's transmission number):
# adding a robot that no one hears changes nothing for the others, and no draw depends on the order
# receivers are visited in. Same seed, same run (docs/radio.md, "Draws per reception").

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
from rescuemesh.radio.per import crc_covered_bits
from rescuemesh.radio.streams import SEED_MASK
from rescuemesh.transport import medium_kernels as k
from rescuemesh.transport.front_door import FrontDoor

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
    response_delay_s: what a stack answers as it receives a frame (a Confirm re-sent for a
        duplicate: any frame it hands back that it did not relay) leaves a random 20-50 ms later
        (Mesh Profile 1.0, 3.7.3.1, for a response to a unicast message), drawn here. Answered at
        once, a Confirm met the relays of the command it answered: in a room of 30 robots that
        relay a resent Follow, robot_12's Confirms were lost three sends in a row.
    """

    adv_interval_s: float = 0.020
    adv_delay_max_s: float = 0.010
    relay_delay_max_s: float = 0.010
    capture_db: float = 21.0
    response_delay_s: tuple[float, float] = (0.020, 0.050)

    def __post_init__(self) -> None:
        for name in ("adv_interval_s", "adv_delay_max_s", "relay_delay_max_s", "capture_db"):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        low, high = self.response_delay_s
        if not 0.0 <= low <= high:
            raise ValueError(f"response_delay_s must be (low, high) with 0 <= low <= high, got {self.response_delay_s!r}")


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
    receivers; `relayed_*` the relays' copies at theirs (a relayed copy is not a unicast delivery).
    The reception counts live in `counts` (indices in medium_kernels), where the compiled kernels
    count them."""

    transmissions: int = 0
    relayed_transmissions: int = 0
    segment_transmissions: int = 0
    bytes_on_air: int = 0
    max_frame_bytes: int = 0
    airtime_s: float = 0.0
    dropped_radio_off: int = 0  # frames a silent radio did not send
    counts: np.ndarray = field(default_factory=lambda: np.zeros(k.N_COUNTS, dtype=np.int64))

    @property
    def receptions_delivered(self) -> int:
        return int(self.counts[k.DELIVERED])

    @property
    def receptions_lost(self) -> dict[str, int]:
        return {cause.value: int(self.counts[k.CODE[cause]]) for cause in LossCause}

    @property
    def unicast_delivered(self) -> int:
        return int(self.counts[k.UNICAST_DELIVERED])

    @property
    def unicast_lost(self) -> int:
        return int(self.counts[k.UNICAST_LOST])

    @property
    def broadcast_delivered(self) -> int:
        return int(self.counts[k.BROADCAST_DELIVERED])

    @property
    def broadcast_lost(self) -> int:
        return int(self.counts[k.BROADCAST_LOST])

    @property
    def relayed_delivered(self) -> int:
        return int(self.counts[k.RELAYED_DELIVERED])

    @property
    def relayed_lost(self) -> int:
        return int(self.counts[k.RELAYED_LOST])

    @property
    def collisions(self) -> int:
        return int(self.counts[k.COLLISION])

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
            "receptions_lost": self.receptions_lost,
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
    index: int  # in attach order: its place in the medium's arrays
    stack: NetworkStack
    position: Callable[[], tuple[float, float]]
    rng: UniformStream
    enabled: bool = True
    loop_phase_s: float = 0.0  # what flush() collects leaves this much later (set_loop_phase)
    transmissions: int = 0  # started so far: the counter of its draws
    queue: deque = field(default_factory=deque)
    tx_scheduled: bool = False
    next_allowed_s: float = float("-inf")
    on_air_until: float = float("-inf")


@dataclass(slots=True)
class _Burst:
    """One frame on the air and its receptions, as arrays over the radios (medium_kernels): `state`
    (NOT_RECEIVER, OK or what spoiled it), the channel's `rssi` and `ok` per receiver; `counter`: the
    sender's transmission number, which keys its draws."""

    transmission: object  # rescuemesh.mesh.Transmission
    sender: _Radio
    start: float
    end: float
    record: AirRecord | None
    counter: int
    state: np.ndarray
    rssi: np.ndarray
    ok: np.ndarray


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
        self.law = k.reception_law(channel)  # TypeError for a model the kernels cannot run
        self.timing = timing or AirTiming()
        self.extra_loss = extra_loss
        self.stats = MediumStats()
        self.records: list[AirRecord] | None = [] if record else None
        self._seed = int(seed)
        self._key = np.uint64(self._seed & SEED_MASK)  # the draws' seed word
        self._radios: dict[int, _Radio] = {}
        self._order_of: list[_Radio] = []  # by index
        self._heap: list = []
        self._order = itertools.count()
        self._timer_at: dict[int, float] = {}
        self._bursts: list[_Burst] = []  # frames on the air or not yet arrived, in start order
        self._now = 0.0
        self._bits: dict[int, int] = {}
        # arrays over the radios, by index (grown by attach)
        self._addresses = np.zeros(0, dtype=np.int64)
        self._enabled = np.zeros(0, dtype=bool)
        self._on_air_until = np.zeros(0)
        #: Radio positions, read once per pump or flush when a frame needs them (the world does not
        #: move inside one), the channel's cell of each, and the mean power between every two radios
        #: with whether it is still valid (both radios in the cells it was computed for).
        self._xy = np.zeros((0, 2))
        self._cells = np.zeros((0, 2))
        self._positions_fresh = False
        self._mean = np.zeros((0, 0))
        self._mean_valid = np.zeros((0, 0), dtype=bool)
        self._relay_delay = np.zeros(0)
        self._response_delay = np.zeros(0)
        #: The nodes' front door (front_door.py): copies a receiver would only count are counted
        #: there, without a call to its stack. False: every copy goes to receive() (the oracle).
        self.front_door = True
        self._door = FrontDoor()
        #: Optional observer of every delivery (a test harness, the spoof scenario): called as
        #: observe(transmitter, receiver, data, now, deliver) and must call deliver() itself.
        self.observe: Callable[[int, int, bytes, float, Callable[[], None]], None] | None = None

    # --- set-up ------------------------------------------------------------------------------

    def attach(self, address: int, stack: NetworkStack, position: Callable[[], tuple[float, float]]) -> None:
        if address in self._radios:
            raise ValueError(f"address {address} is already attached")
        if self._bursts:
            raise ValueError("attach radios before frames are on the air")
        index = len(self._order_of)
        radio = self._radios[address] = _Radio(address, index, stack, position, self._stream(1, address))
        self._order_of.append(radio)
        n = index + 1
        self._addresses = np.append(self._addresses, np.int64(address))
        self._enabled = np.append(self._enabled, True)
        self._on_air_until = np.append(self._on_air_until, -np.inf)
        self._xy = np.zeros((n, 2))
        self._cells = np.full((n, 2), np.nan)  # no cell yet: every pair is computed when first needed
        self._positions_fresh = False
        self._mean = np.full((n, n), -np.inf)
        self._mean_valid = np.eye(n, dtype=bool)  # a radio never hears itself
        self._relay_delay = np.zeros(n)
        self._response_delay = np.zeros(n)
        self._door.attach(stack)

    def set_radio_enabled(self, address: int, enabled: bool, now: float) -> None:
        """Switch a radio off (it neither sends nor hears; its queued frames are dropped) or on."""
        radio = self._radio(address)
        radio.enabled = bool(enabled)
        self._enabled[radio.index] = radio.enabled
        if not enabled:
            self.stats.dropped_radio_off += len(radio.queue)
            radio.queue.clear()
            for burst in self._bursts:
                if burst.end > now and burst.state[radio.index] == k.OK:
                    burst.state[radio.index] = k.RADIO_OFF

    def set_loop_phase(self, address: int, phase_s: float) -> None:
        """The robot's control loop runs `phase_s` after the ticks at which flush() is called: what
        its stack hands down then leaves that much later (robots switched on at different times
        do not run their loops in step; a team whose loops did put most of its frames on the air in
        the 10 ms after each tick)."""
        if not phase_s >= 0.0:
            raise ValueError(f"loop phase must be >= 0 s, got {phase_s!r}")
        self._radio(address).loop_phase_s = float(phase_s)

    def radio_enabled(self, address: int) -> bool:
        return self._radio(address).enabled

    # --- the pump ------------------------------------------------------------------------------

    def flush(self, now: float) -> None:
        """Queue, stamped `now`, every frame the stacks have to send (call it after the brains ran
        at `now`, the time the medium was last pumped to)."""
        self._now = max(self._now, now)
        self._positions_fresh = False
        for radio in self._order_of:
            self._collect(radio, self._now, radio.loop_phase_s)

    def pump(self, now: float, collect: bool = True) -> None:
        """Advance the medium to `now`: every event due by then, in time order. Frames the stacks
        queued since the last pump or flush leave at that earlier time (`collect` False: the caller
        flushed after the last thing that could queue one, and the stacks are not asked again)."""
        if collect:
            self.flush(self._now)
        self._positions_fresh = False  # the world may have moved since
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

    def _read_positions(self) -> None:
        """Read every radio's position (once per pump or flush) and forget the mean powers of the
        pairs of which a radio moved to another cell."""
        self._xy[:] = [radio.position() for radio in self._order_of]
        law = self.law
        k.move_radios(self._xy, law.quantum_m, law.origin[0], law.origin[1], self._cells, self._mean_valid)
        self._positions_fresh = True

    def _mean_row(self, radio: _Radio) -> np.ndarray:
        """The channel's mean power from `radio` to every radio (dBm), computing only the pairs not
        known for the radios' present cells (and only towards radios that are on)."""
        if not self._positions_fresh:
            self._read_positions()
        s = radio.index
        valid = self._mean_valid[s]
        if not valid.all():
            missing = np.flatnonzero(~valid & self._enabled)
            if len(missing):
                values = self.channel.mean_rx_power_row(tuple(self._xy[s].tolist()), self._xy[missing])
                self._mean[s, missing] = values
                valid[missing] = True
                if self.law.symmetric:
                    self._mean[missing, s] = values
                    self._mean_valid[missing, s] = True
        return self._mean[s]

    def _stream(self, *key: int) -> UniformStream:
        return UniformStream(np.random.default_rng(np.random.SeedSequence(self._seed, spawn_key=key)))

    def _push(self, at: float, kind: _Event, payload) -> None:
        heapq.heappush(self._heap, (at, kind, next(self._order), payload))

    def _collect(self, radio: _Radio, now: float, phase_s: float = 0.0, respond_s: float = 0.0) -> None:
        """Queue the stack's new transmissions on its radio and re-arm its timer. They leave
        `phase_s` later (the robot's loop phase), or `respond_s` later when the stack answers a frame
        it just received with one it did not relay (AirTiming.response_delay_s)."""
        transmissions = radio.stack.transmissions(now)
        if transmissions:
            if not radio.enabled:
                self.stats.dropped_radio_off += len(transmissions)
            else:
                radio.queue.extend(transmissions)
                if not radio.tx_scheduled:
                    if respond_s and not all(t.relayed for t in transmissions):
                        phase_s = respond_s
                    self._schedule_start(radio, now + phase_s)
        self._arm_timer(radio, radio.stack.get_timer())

    def _arm_timer(self, radio: _Radio, timer: float | None) -> None:
        """Push the stack's timer on the heap unless that very entry is pending. `_timer_at` holds,
        per radio, the time of the one entry that counts (the latest pushed); any other entry of that
        radio on the heap is superseded (_fire_timer)."""
        if timer is not None:
            at = max(timer, self._now)
            if self._timer_at.get(radio.address) != at:
                self._timer_at[radio.address] = at
                self._push(at, _Event.TIMER, radio)

    def _schedule_start(self, radio: _Radio, now: float) -> None:
        timing = self.timing
        delay = radio.rng.random() * timing.adv_delay_max_s if timing.adv_delay_max_s else 0.0
        start = max(now, radio.next_allowed_s, radio.on_air_until) + delay
        radio.tx_scheduled = True
        self._push(start, _Event.TX_START, radio)

    def _fire_timer(self, radio: _Radio, at: float) -> None:
        if self._timer_at.get(radio.address) != at:
            # superseded: this radio's entry that counts is a later one, or none is armed. The
            # stack's timer is never earlier than the medium last read it (it moves earlier only in
            # calls after which the medium collects it), so it is not due now: no need to ask. In the
            # convoy of 30, three timer entries in four are superseded (relays scheduled, then
            # suppressed or sent; resends confirmed), and each was a get_timer() call before.
            return
        del self._timer_at[radio.address]
        timer = radio.stack.get_timer()
        if timer is None or timer > at:  # stale: the stack's timer moved (later) since this was pushed
            self._arm_timer(radio, timer)  # a stack that dropped a frame was not asked: ask now
            return
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
        s = radio.index
        self._on_air_until[s] = end
        self._bursts = on_air = [burst for burst in self._bursts if burst.end > start]
        for burst in on_air:  # half duplex: what it was hearing is lost
            if burst.state[s] == k.OK:
                burst.state[s] = k.HALF_DUPLEX
        self._count_transmission(transmission, size, end - start)
        record = None
        if self.records is not None:
            record = AirRecord(start, end, radio.address, transmission.src, transmission.dst,
                               transmission.msg_type, transmission.relayed, transmission.segment,
                               transmission.data, None if transmission.dst == BROADCAST else False,
                               seq=transmission.seq)
            self.records.append(record)
        bits = self._bits.get(size)
        if bits is None:
            bits = self._bits[size] = crc_covered_bits(size)
        n = len(self._order_of)
        burst = _Burst(transmission, radio, start, end, record, radio.transmissions,
                       np.empty(n, dtype=np.int8), np.empty(n), np.empty(n, dtype=np.int8))
        radio.transmissions += 1
        law = self.law
        heard = k.open_receptions(s, self._addresses, self._enabled, self._on_air_until, self._mean_row(radio),
                                  start, transmission.dst, BROADCAST, bits, law.floor_dbm, law.fading,
                                  law.rician_k, law.packet_errors, law.sensitivity_dbm, self._key, burst.counter,
                                  transmission.relayed, burst.state, burst.rssi, burst.ok, self.stats.counts)
        if heard:
            third = (end - start) / ADV_CHANNELS
            capture = self.timing.capture_db
            for other in on_air:
                # their PDUs share a channel in time only if their starts are closer than one PDU
                if start - other.start < max(third, (other.end - other.start) / ADV_CHANNELS):
                    k.collide(burst.state, burst.rssi, other.state, other.rssi, capture)
            on_air.append(burst)
            self._push(end, _Event.ARRIVAL, burst)
        if radio.queue:
            self._schedule_start(radio, end)

    def _arrive(self, burst: _Burst, at: float) -> None:
        transmission, sender, record = burst.transmission, burst.sender, burst.record
        delays = self._relay_delay
        delivered, collided, dst_heard = k.close_receptions(
            sender.index, self._addresses, self._enabled, burst.state, burst.ok, transmission.dst, BROADCAST,
            self.extra_loss, self.timing.relay_delay_max_s, self._key, burst.counter, transmission.relayed, delays,
            self.stats.counts)
        if record is not None:
            record.collided = bool(collided)
            record.heard_by = delivered
            if dst_heard:
                record.dst_heard = True
        if not delivered:
            return
        data, observe, radios, rssi = transmission.data, self.observe, self._order_of, burst.rssi
        if observe is None and self.front_door:
            receivers = self._door.sort(burst.state, self._addresses, transmission, BROADCAST, at)
        else:
            receivers = np.flatnonzero(burst.state == k.OK)
        low, high = self.timing.response_delay_s
        responses = self._response_delay
        if high > 0.0:
            k.response_delays(receivers, self._addresses, sender.index, self._key, burst.counter, low, high, responses)
        for r in receivers.tolist():
            receiver = radios[r]
            if observe is None:
                if receiver.stack.receive(data, at, rssi_dbm=float(rssi[r]), relay_delay_s=float(delays[r])) is False:
                    continue  # dropped: nothing new to send, no earlier timer
            else:
                observe(sender.address, receiver.address, data, at,
                        _delivery(receiver.stack, data, at, float(rssi[r]), float(delays[r])))
            self._collect(receiver, at, respond_s=float(responses[r]) if high > 0.0 else 0.0)

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


def _delivery(stack: NetworkStack, data: bytes, at: float, rssi: float, relay_delay: float) -> Callable[[], None]:
    def deliver() -> None:
        stack.receive(data, at, rssi_dbm=rssi, relay_delay_s=relay_delay)

    return deliver
