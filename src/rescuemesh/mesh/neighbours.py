"""Neighbours and liveness: who was heard, how many hops away, at what RSSI, and who is lost
(Bluetooth Mesh heartbeats; paper: "stop command execution in case of disconnecting and failing to
reconnect"). Owns the table and the lost/found rule; must not know frames, relays or segments.
"""

# Theory of operation
# ===================
#
# Every valid frame a source *originated* counts as hearing it: direct or relayed, for us or not,
# a Heartbeat or anything else. The node tells the table (address, received TTL, now, rssi and,
# for a Heartbeat, the init_ttl it carries); the table keeps one entry per source address (one
# byte, so at most 255 entries):
#
#     hops = init_ttl(src) - ttl + 1      (1 = heard directly), at least 1
#
# where init_ttl(src) is the one the source's latest Heartbeat announced, or the team-wide
# MeshConfig.initial_ttl before any Heartbeat. rssi_dbm is kept only when hops == 1: through a
# relay the radio measured the relay, not the source.
#
# Only a Heartbeat says with which TTL it was originated. A source may send other frames with
# less than its init_ttl (MeshConfig.unicast_ttl_from_hops: h + 1 to a robot h hops away), so for
# them the formula gives an upper bound; once a Heartbeat from the source has been heard, such a
# frame counts at most the hops that Heartbeat measured (Mesh Profile 1.0, 3.6.7: hops are
# counted from heartbeats):
#
#     hops = min(init_ttl(src) - ttl + 1, hops of src's latest Heartbeat)    (not a Heartbeat)
#
# A source that moved further away shows its new distance with its next Heartbeat (1 s).
#
# Liveness is a deadline per entry, lost_s = (lost_after_missed + 0.5) * heartbeat_period_s:
#
#     (unknown) --heard--------------------------> ALIVE  (NeighbourFound)
#     ALIVE     --heard--------------------------> ALIVE  (deadline moves; no event)
#     ALIVE     --now >= last_heard + lost_s------> LOST   (NeighbourLost, once)
#     LOST      --heard--------------------------> ALIVE  (NeighbourFound)
#     any       --now >= last_heard + expiry_s----> (forgotten; heard again = NeighbourFound)
#
# With a 1 s period and 3 missed heartbeats a peer last heard at t is lost at t + 3.5 s: the
# heartbeats due at t + 1, t + 2 and t + 3 all missed, with half a period of grace for jitter and
# relay delay on the last one. next_deadline() is the earliest of these times, so the node's timer
# fires exactly then; is_reachable(address, now) applies the same rule without waiting for it.
#
# The deadlines are kept in a heap of (deadline, address), pushed whenever an entry's deadline moves
# (heard, lost); an item that is no longer its entry's deadline is dropped when it reaches the top.
# A team of 30 hears a thousand frames a second and the node asks for its timer after each: a scan of
# every entry whenever the earliest one was heard again cost more than the rest of the table's work.

from __future__ import annotations

import heapq
from dataclasses import dataclass

from .config import MeshConfig
from .events import NeighbourFound, NeighbourLost


@dataclass(frozen=True, slots=True)
class NeighbourInfo:
    """One row of the neighbour table, for reports: hops from the latest reception, rssi_dbm of the
    latest reception if it came directly (None otherwise), last_heard_s in s, init_ttl from the
    latest Heartbeat (None before one)."""

    address: int
    hops: int
    rssi_dbm: float | None
    last_heard_s: float
    lost: bool
    init_ttl: int | None


@dataclass(slots=True)
class _Entry:
    hops: int
    rssi_dbm: float | None
    last_heard_s: float
    lost: bool
    init_ttl: int | None
    beat_hops: int | None = None  # hops of the latest Heartbeat heard from it


class NeighbourTable:
    """Sources heard, keyed by address, with the lost/found transitions of the module comment."""

    def __init__(self, config: MeshConfig) -> None:
        self._default_init_ttl = config.initial_ttl
        self._lost_s = config.lost_after_seconds
        self._expiry_s = config.neighbour_expiry_s
        self._entries: dict[int, _Entry] = {}
        self._deadlines: list[tuple[float, int]] = []  # (deadline, address), lazily cleaned (module comment)

    def __len__(self) -> int:
        return len(self._entries)

    def hops_for(self, address: int, ttl: int, init_ttl: int | None = None) -> int:
        """Hops a frame from `address` received with TTL `ttl` has travelled (at least 1)."""
        if init_ttl is None:
            entry = self._entries.get(address)
            init_ttl = entry.init_ttl if entry is not None and entry.init_ttl is not None else None
        if init_ttl is None:
            init_ttl = self._default_init_ttl
        return max(1, init_ttl - ttl + 1)

    def heard(
        self, address: int, ttl: int, now: float, rssi_dbm: float | None, init_ttl: int | None = None
    ) -> tuple[int, NeighbourFound | None]:
        """Record a frame originated by `address`, received with TTL `ttl` at `now` s. `init_ttl`:
        the value a Heartbeat carries (None for other frames). Returns the hops and, on a
        transition to ALIVE, the NeighbourFound event."""
        entry = self._entries.get(address)
        beat = init_ttl is not None
        if not beat and entry is not None:
            init_ttl = entry.init_ttl
        hops = self.hops_for(address, ttl, init_ttl)
        if not beat and entry is not None and entry.beat_hops is not None:
            hops = min(hops, entry.beat_hops)  # the frame may have left with less than init_ttl
        rssi = rssi_dbm if hops == 1 else None
        if entry is None:
            self._entries[address] = _Entry(hops, rssi, now, False, init_ttl, hops if beat else None)
            self._push(now + self._lost_s, address)
            return hops, NeighbourFound(address, hops, now)
        found = NeighbourFound(address, hops, now) if entry.lost else None
        entry.hops, entry.rssi_dbm, entry.last_heard_s, entry.lost = hops, rssi, now, False
        entry.init_ttl = init_ttl
        if beat:
            entry.beat_hops = hops
        self._push(now + self._lost_s, address)
        return hops, found

    def _push(self, deadline: float, address: int) -> None:
        """`address`'s entry (already updated) has a new deadline."""
        if len(self._deadlines) > 4 * len(self._entries) + 64:  # next_deadline() not asked for a while
            self._rebuild()
        heapq.heappush(self._deadlines, (deadline, address))

    def next_deadline(self) -> float | None:
        """Earliest time in s at which an entry is lost or forgotten, or None."""
        deadlines, entries = self._deadlines, self._entries
        while deadlines:
            deadline, address = deadlines[0]
            entry = entries.get(address)
            if entry is not None and deadline == entry.last_heard_s + (self._expiry_s if entry.lost else self._lost_s):
                return deadline
            heapq.heappop(deadlines)  # that entry was heard since, lost or forgotten
        return None

    def _rebuild(self) -> None:
        """The heap of deadlines with one item per entry."""
        lost_s, expiry_s = self._lost_s, self._expiry_s
        self._deadlines = [(e.last_heard_s + (expiry_s if e.lost else lost_s), a) for a, e in self._entries.items()]
        heapq.heapify(self._deadlines)

    def expire(self, now: float) -> list[NeighbourLost]:
        """Apply every deadline passed by `now`: mark lost (one event each) and forget expired."""
        deadline = self.next_deadline()
        if deadline is None or deadline > now:
            return []
        events = []
        for address in list(self._entries):
            entry = self._entries[address]
            if not entry.lost and now >= entry.last_heard_s + self._lost_s:
                entry.lost = True
                events.append(NeighbourLost(address, entry.last_heard_s, now))
                self._push(entry.last_heard_s + self._expiry_s, address)
            if now >= entry.last_heard_s + self._expiry_s:
                del self._entries[address]
        return events

    def hops_to(self, address: int) -> int | None:
        """Hops to `address` from its latest frame (kept while lost), None if unknown or forgotten."""
        entry = self._entries.get(address)
        return None if entry is None else entry.hops

    def reachable_count(self, now: float) -> int:
        """How many sources are reachable at `now` s (heard, not lost)."""
        lost_s = self._lost_s
        return sum(1 for e in self._entries.values() if not e.lost and now < e.last_heard_s + lost_s)

    def heartbeat_heard(self, address: int) -> bool:
        """Whether a Heartbeat from `address` was heard since it was last forgotten."""
        entry = self._entries.get(address)
        return entry is not None and entry.beat_hops is not None

    def init_ttl_of(self, address: int) -> int | None:
        entry = self._entries.get(address)
        return None if entry is None else entry.init_ttl

    def is_reachable(self, address: int, now: float) -> bool:
        """Heard, and not lost at `now` s (the lost rule applied now, timer or not)."""
        entry = self._entries.get(address)
        return entry is not None and not entry.lost and now < entry.last_heard_s + self._lost_s

    def snapshot(self) -> list[NeighbourInfo]:
        """Every entry, by address."""
        return [
            NeighbourInfo(a, e.hops, e.rssi_dbm, e.last_heard_s, e.lost, e.init_ttl)
            for a, e in sorted(self._entries.items())
        ]
