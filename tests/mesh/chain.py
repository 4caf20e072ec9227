"""Test helper: sans-IO mesh nodes on an in-memory "air" with a fake clock, where each node hears
only the nodes it is linked to (a chain by default), with scripted or seeded loss.

Delivery is instant; a relay's delay is whatever `relay_delay` returns (the node holds the frame
until then). Every transmission is logged with the time it left its node.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from rescuemesh.mesh import MeshConfig, MeshEvent, MeshNode, Transmission

RSSI_DBM = -60.0


@dataclass
class Sent:
    now: float
    sender: int
    tx: Transmission


@dataclass
class Air:
    nodes: dict[int, MeshNode]
    links: set[frozenset[int]]
    #: (sender, receiver, transmission) -> True to lose that reception
    loss: Callable[[int, int, Transmission], bool] | None = None
    #: (receiver, data) -> relay delay in s handed to receive()
    relay_delay: Callable[[int, bytes], float] | None = None
    now: float = 0.0
    log: list[Sent] = field(default_factory=list)
    events: dict[int, list[MeshEvent]] = field(default_factory=dict)

    def hears(self, a: int, b: int) -> bool:
        return frozenset((a, b)) in self.links

    def send(self, address: int, frame: bytes) -> None:
        """Node `address`'s endpoint hands `frame` down; then everything due moves."""
        self.nodes[address].send(frame, self.now)
        self.pump()

    def inject(self, address: int, data: bytes, relay_delay_s: float = 0.0) -> None:
        """Node `address` hears `data` from outside the air (a test's own frame)."""
        self.nodes[address].receive(data, self.now, rssi_dbm=RSSI_DBM, relay_delay_s=relay_delay_s)
        self.pump()

    def pump(self) -> None:
        """Move every transmission due now until no node has one left."""
        moved = True
        while moved:
            moved = False
            for address, node in self.nodes.items():
                for tx in node.transmissions(self.now):
                    moved = True
                    self.log.append(Sent(self.now, address, tx))
                    self._broadcast(address, tx)
        self._collect()

    def _broadcast(self, sender: int, tx: Transmission) -> None:
        for address, node in self.nodes.items():
            if address == sender or not self.hears(sender, address):
                continue
            if self.loss is not None and self.loss(sender, address, tx):
                continue
            delay = self.relay_delay(address, tx.data) if self.relay_delay else 0.0
            node.receive(tx.data, self.now, rssi_dbm=RSSI_DBM, relay_delay_s=delay)

    def _collect(self) -> None:
        for address, node in self.nodes.items():
            while (event := node.next_event()) is not None:
                self.events.setdefault(address, []).append(event)

    def run_until(self, t: float, max_steps: int = 1_000_000) -> None:
        """Advance the fake clock to `t` s, firing every node timer due on the way."""
        for _ in range(max_steps):
            due = [d for d in (n.get_timer() for n in self.nodes.values()) if d is not None and d <= t]
            if not due:
                break
            self.now = max(self.now, min(due))
            for node in self.nodes.values():
                timer = node.get_timer()
                if timer is not None and timer <= self.now:
                    node.handle_timer(self.now)
            self.pump()
        else:
            raise AssertionError(f"timers still due after {max_steps} steps (a timer that never moves?)")
        self.now = max(self.now, t)
        self._collect()

    def of_type(self, address: int, cls: type) -> list:
        """Events of class `cls` node `address` produced so far."""
        return [e for e in self.events.get(address, []) if type(e) is cls]

    def sent_by(self, address: int) -> list[Transmission]:
        return [s.tx for s in self.log if s.sender == address]


def chain(n: int, config: MeshConfig | None = None, configs: dict[int, MeshConfig] | None = None,
          **kwargs) -> Air:
    """Nodes 1..n in a line: i hears only i - 1 and i + 1."""
    return mesh(range(1, n + 1), [(i, i + 1) for i in range(1, n)], config, configs, **kwargs)


def mesh(addresses: Iterable[int], links: Iterable[tuple[int, int]], config: MeshConfig | None = None,
         configs: dict[int, MeshConfig] | None = None, **kwargs) -> Air:
    """Nodes with explicit links (each pair hears each other)."""
    configs = configs or {}
    nodes = {a: MeshNode(a, configs.get(a, config)) for a in addresses}
    return Air(nodes, {frozenset(link) for link in links}, **kwargs)


def frame(src: int, dst: int, seq: int, payload: bytes, *, ttl: int = 7, msg_type: int = 36,
          attempt: int = 0, flags: int = 0) -> bytes:
    """Raw frame bytes (header + payload + CRC-32) without going through the codec, so tests can
    build frames the codec would refuse (unknown types, SEG flag, odd lengths)."""
    body = bytes(((1 << 6) | (flags << 4) | ttl, (attempt << 6) | msg_type, src, dst)) + seq.to_bytes(2, "big")
    body += payload
    return body + zlib.crc32(body).to_bytes(4, "big")
