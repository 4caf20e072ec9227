"""The in-process radio link: a discrete-event pump between sans-IO endpoints over a channel model.

Owns: in-flight frames, their arrival times, link statistics and an optional per-frame trace.
Must not know: what the frames mean (it reads only the destination byte), robots, the physics.
Every radio in range hears every frame (the medium is broadcast); endpoints drop what is not theirs.
Statistics count only the intended receptions: the destination, or every other radio for broadcast.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Protocol

import numpy as np

from rescuemesh.protocol import BROADCAST
from rescuemesh.radio.channel import ChannelModel

#: The destination address is byte 3 of every frame's header (docs/protocol.md).
DESTINATION_BYTE = 3
#: At most this many network events (deliveries and timer firings) per pump: a runaway guard.
MAX_EVENTS_PER_PUMP = 100_000


class FrameEndpoint(Protocol):
    """What the link needs of an endpoint (rescuemesh.protocol.Endpoint has it)."""

    def receive(self, data: bytes, now: float) -> None: ...
    def frames_to_send(self, now: float) -> list[bytes]: ...
    def get_timer(self) -> float | None: ...
    def handle_timer(self, now: float) -> None: ...


@dataclass
class LinkStats:
    """Counts over the whole run. A reception is one frame at one intended receiver."""

    frames_sent: int = 0  # transmissions
    bytes_sent: int = 0
    max_frame_bytes: int = 0
    frames_delivered: int = 0  # intended receptions that arrived
    frames_lost: int = 0  # intended receptions dropped by the channel (loss or range)
    frames_out_of_range: int = 0  # of frames_lost, those beyond range

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


@dataclass(frozen=True, slots=True)
class RadioRecord:
    """One intended reception, for timelines: sent at `sent_s`, arrived at `arrived_s` (None: lost)."""

    sent_s: float
    src: int
    dst: int
    frame: bytes
    arrived_s: float | None


@dataclass
class _Radio:
    address: int
    endpoint: FrameEndpoint
    position: Callable[[], tuple[float, float]]


class SimRadioLink:
    """Moves frames between attached endpoints, in simulated time, through a channel model.

    `pump(now)` processes, in time order, every arrival and every endpoint timer due by `now`;
    frames an endpoint emits while handling one are sent at that event's time, so a reply can
    arrive within the same pump. Positions are read at send time.
    """

    def __init__(self, channel: ChannelModel, rng: np.random.Generator, *, record: bool = False) -> None:
        self.channel = channel
        self.stats = LinkStats()
        self.records: list[RadioRecord] | None = [] if record else None
        self._rng = rng
        self._radios: dict[int, _Radio] = {}
        self._in_flight: list[tuple[float, int, int, bytes]] = []  # (arrival, order, receiver, frame)
        self._order = itertools.count()

    def attach(self, address: int, endpoint: FrameEndpoint, position: Callable[[], tuple[float, float]]) -> None:
        if address in self._radios:
            raise ValueError(f"address {address} is already attached")
        self._radios[address] = _Radio(address, endpoint, position)

    def flush(self, now: float) -> None:
        """Transmit, stamped `now`, every frame the endpoints have queued (call after the brains ran)."""
        for radio in self._radios.values():
            self._send_queued(radio, now)

    def pump(self, now: float) -> None:
        """Advance the network to `now`: send what endpoints queued, deliver and fire what is due."""
        self.flush(now)
        for _ in range(MAX_EVENTS_PER_PUMP):
            arrival = self._in_flight[0][0] if self._in_flight else None
            timer_radio, timer_at = self._earliest_timer()
            if timer_at is not None and timer_at <= now and (arrival is None or timer_at < arrival):
                timer_radio.endpoint.handle_timer(timer_at)
                self._send_queued(timer_radio, timer_at)
            elif arrival is not None and arrival <= now:
                arrival, _, receiver, frame = heapq.heappop(self._in_flight)
                radio = self._radios[receiver]
                radio.endpoint.receive(frame, arrival)
                self._send_queued(radio, arrival)
            else:
                return
        raise RuntimeError(f"radio link: more than {MAX_EVENTS_PER_PUMP} events in one pump (runaway timers?)")

    def _earliest_timer(self) -> tuple[_Radio | None, float | None]:
        best: tuple[_Radio | None, float | None] = (None, None)
        for radio in self._radios.values():
            at = radio.endpoint.get_timer()
            if at is not None and (best[1] is None or at < best[1]):
                best = (radio, at)
        return best

    def _send_queued(self, sender: _Radio, now: float) -> None:
        frames = sender.endpoint.frames_to_send(now)
        if not frames:
            return
        sender_xy = sender.position()
        for frame in frames:
            self._transmit(sender, sender_xy, frame, now)

    def _transmit(self, sender: _Radio, sender_xy: tuple[float, float], frame: bytes, now: float) -> None:
        size = len(frame)
        self.stats.frames_sent += 1
        self.stats.bytes_sent += size
        self.stats.max_frame_bytes = max(self.stats.max_frame_bytes, size)
        dst = frame[DESTINATION_BYTE] if len(frame) > DESTINATION_BYTE else BROADCAST
        for radio in self._radios.values():
            if radio is sender:
                continue
            receiver_xy = radio.position()
            delay = self.channel.transmit(sender_xy, receiver_xy, size, self._rng)
            intended = dst == BROADCAST or dst == radio.address
            if delay is not None:
                heapq.heappush(self._in_flight, (now + delay, next(self._order), radio.address, frame))
            if intended:
                self._count(sender.address, radio.address, frame, now, delay, sender_xy, receiver_xy)

    def _count(self, src, dst, frame, now, delay, sender_xy, receiver_xy) -> None:
        if delay is None:
            self.stats.frames_lost += 1
            if not self.channel.in_range(sender_xy, receiver_xy):
                self.stats.frames_out_of_range += 1
        else:
            self.stats.frames_delivered += 1
        if self.records is not None:
            self.records.append(RadioRecord(now, src, dst, frame, None if delay is None else now + delay))
