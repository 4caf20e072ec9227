"""Test helper: endpoints over an in-memory link with a fake clock and scripted loss.

Delivery is instant; `drop` holds the indices (0-based, in the order frames are put on the link,
both directions together) of the frames the link loses. Every frame put on the link is logged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rescuemesh.protocol import Endpoint


@dataclass
class Sent:
    index: int
    src: int
    data: bytes
    dropped: bool
    now: float


@dataclass
class Link:
    endpoints: list[Endpoint]
    drop: set[int] | None = None  # None: lose nothing; use drop_all_from for a dead direction
    drop_all_from: set[int] = field(default_factory=set)
    now: float = 0.0
    log: list[Sent] = field(default_factory=list)

    def pump(self) -> None:
        """Move frames until no endpoint has anything left to send."""
        moved = True
        while moved:
            moved = False
            for ep in self.endpoints:
                for data in ep.frames_to_send(self.now):
                    moved = True
                    self._put(ep, data)

    def _put(self, sender: Endpoint, data: bytes) -> None:
        index = len(self.log)
        dropped = index in (self.drop or ()) or sender.address in self.drop_all_from
        self.log.append(Sent(index, sender.address, data, dropped, self.now))
        if dropped:
            return
        for ep in self.endpoints:  # a radio: everyone in range hears every frame, and filters
            if ep is not sender:
                ep.receive(data, self.now)

    def run_until(self, t: float) -> None:
        """Advance the fake clock to `t` s, firing every endpoint timer due on the way."""
        while True:
            due = [ep.get_timer() for ep in self.endpoints]
            due = [d for d in due if d is not None and d <= t]
            if not due:
                break
            self.now = max(self.now, min(due))
            for ep in self.endpoints:
                timer = ep.get_timer()
                if timer is not None and timer <= self.now:
                    ep.handle_timer(self.now)
            self.pump()
        self.now = t

    def sent_by(self, address: int) -> list[Sent]:
        return [s for s in self.log if s.src == address]


def drain(ep: Endpoint) -> list:
    """All pending events of `ep`, oldest first."""
    events = []
    while (event := ep.next_event()) is not None:
        events.append(event)
    return events
