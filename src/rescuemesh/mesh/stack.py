"""A robot's network stack: its endpoint on its mesh node, with the aioquic API a transport pumps.
Owns the glue only: frames down, delivered frames and hop counts up, transfers ended once the endpoint
stops awaiting their Confirm, network events out. Must not know radios or clocks.
"""

from __future__ import annotations

from collections import Counter, deque

from rescuemesh.protocol import Endpoint

from .events import (
    FrameDelivered,
    MeshEvent,
    NeighbourFound,
    NeighbourLost,
    PeerRestarted,
    SegmentsResent,
    TransferComplete,
    TransferFailed,
)
from .node import MeshNode, Transmission


class NetworkStack:
    """Endpoint over MeshNode. A transport calls `receive`, `transmissions` (or `frames_to_send`),
    `get_timer` and `handle_timer`; the robot reads `endpoint.next_event()` for protocol events and
    `next_event()` here for network events (NeighbourFound, NeighbourLost, TransferComplete,
    TransferFailed)."""

    def __init__(self, endpoint: Endpoint, node: MeshNode) -> None:
        if endpoint.address != node.address:
            raise ValueError(f"endpoint {endpoint.address} and mesh node {node.address} differ")
        self.endpoint = endpoint
        self.node = node
        self.hops_histogram: Counter[int] = Counter()  # frames delivered to us, by hops crossed
        self._events: deque[MeshEvent] = deque()
        self._path_hops: dict[int, int] = {}
        node.number = self._number  # one sequence per robot: the node's SegmentAcks use the endpoint's
        self._on_event = {
            PeerRestarted: self._restarted,
            FrameDelivered: self._deliver,
            NeighbourFound: self._found,
            NeighbourLost: self._events.append,
            TransferComplete: self._events.append,
            TransferFailed: self._events.append,
            SegmentsResent: self._resent,
        }

    @property
    def address(self) -> int:
        return self.endpoint.address

    @property
    def heartbeat_period_s(self) -> float:
        """How often the robot above sends a Heartbeat, in s: the node's MeshConfig.heartbeat_period_s,
        the period its neighbour table counts missed Heartbeats in (the one source of it)."""
        return self.node.config.heartbeat_period_s

    # --- the transport's side ------------------------------------------------------------------

    def receive(self, data: bytes, now: float, *, rssi_dbm: float | None = None, relay_delay_s: float = 0.0) -> bool:
        """A frame heard on the air (never raises for any bytes). False when the mesh node dropped
        it: then there is nothing new to send and no earlier timer (see MeshNode.receive)."""
        accepted = self.node.receive(data, now, rssi_dbm=rssi_dbm, relay_delay_s=relay_delay_s)
        if accepted:
            self._drain()
        return accepted

    def transmissions(self, now: float) -> list[Transmission]:
        """What to put on the air now: the endpoint's new frames (segmented as needed), relays."""
        node = self.node
        node.abandon_transfers(self.endpoint.awaits, now)  # first: a new frame to that robot need not queue
        for frame, epoch in self.endpoint.drain(now):
            node.send(frame, now, epoch)
        return node.transmissions(now)

    def frames_to_send(self, now: float) -> list[bytes]:
        """The same as bytes only, for transports that need no metadata (BLE, Zenoh)."""
        return [t.data for t in self.transmissions(now)]

    def get_timer(self) -> float | None:
        a, b = self.endpoint.get_timer(), self.node.get_timer()
        return b if a is None else a if b is None or a < b else b

    def handle_timer(self, now: float) -> None:
        timer = self.endpoint.get_timer()
        if timer is not None and timer <= now:
            self.endpoint.handle_timer(now)
            self.node.abandon_transfers(self.endpoint.awaits, now)  # a frame given up: no further round
        timer = self.node.get_timer()
        if timer is not None and timer <= now:
            self.node.handle_timer(now)
            self._drain()

    # --- the robot's side ----------------------------------------------------------------------

    def next_event(self) -> MeshEvent | None:
        """The oldest network event not yet pulled (frames for us go to the endpoint instead)."""
        return self._events.popleft() if self._events else None

    def is_reachable(self, address: int, now: float) -> bool:
        return self.node.is_reachable(address, now)

    def hops_to(self, address: int) -> int | None:
        return self.node.hops_to(address)

    # --- internals -----------------------------------------------------------------------------

    def _drain(self) -> None:
        next_event, on_event = self.node.next_event, self._on_event
        while (event := next_event()) is not None:
            on_event[type(event)](event)

    def _deliver(self, event: FrameDelivered) -> None:
        hops = event.hops
        self.hops_histogram[hops] += 1
        if self._path_hops.get(event.src) != hops:  # _note_hops, inline: a frame per robot heard
            self._note_hops(event.src, hops)
        self.endpoint.receive(event.data, event.now, hops)

    def _number(self) -> tuple[int, int]:
        seq = self.endpoint.allocate_seq()
        return seq, self.endpoint.epoch

    def _restarted(self, event: PeerRestarted) -> None:
        self.endpoint.forget_peer(event.address)
        self._events.append(event)

    def _resent(self, event: SegmentsResent) -> None:
        self.endpoint.answer_resend(event.src, event.seq, event.now)

    def _found(self, event: NeighbourFound) -> None:
        self._note_hops(event.address, event.hops)
        self._events.append(event)

    def _note_hops(self, address: int, hops: int) -> None:
        if self._path_hops.get(address) != hops:
            self._path_hops[address] = hops
            self.endpoint.set_path_hops(address, hops)
