"""A mesh node's outbox: what it will transmit, by due time; relayed copies paced, suppressed when
heard often enough, dropped when stale. Owns the queues and per-frame counters; must not know frame
bytes, radios or clocks (the node says which frame a copy is, its TTL, and when it heard it again).
"""

# Theory of operation (Ni, Tseng, Chen, Sheu, "The broadcast storm problem in a mobile ad hoc
# network", MobiCom 1999, section 3.2: the counter-based scheme)
# =============================================================================================
#
# Managed flooding makes every relay that hears a frame re-broadcast it, 1 + Relay Retransmit
# count times. In a dense team most of those copies reach no one new. A relayed copy is pushed
# with its frame's network-cache key and TTL; while any copy of that frame is still here (not yet
# handed out by pop_due), heard_again(key, ttl) counts the further copies the node hears that
# another relay sent at our level or beyond (TTL at most ours). Copies with a higher TTL are the
# Relay Retransmit copies of the node we heard the frame from: counting them would silence every
# relay of a chain whose relay delay exceeds the retransmit interval. A copy from further along
# is a passive acknowledgement. When the count reaches `suppress_after`, every copy of that frame
# still here is cancelled: its neighbourhood has heard it, one more re-broadcast adds little.
#
#     push(relayed copy, key, ttl)  -> WAITING (heard = 0)
#     WAITING --heard_again, ttl <= ours--> heard + 1; at suppress_after: cancelled (SUPPRESSED)
#     WAITING --last copy handed out by pop_due--> forgotten (later copies heard are not counted)
#
# Copies already handed out are the transport's: they go on the air. So relayed control copies
# are paced (at most one per relay_pace_s, and one pace after any frame we send): they wait here,
# where they can still be cancelled, instead of in the radio's queue, where they cannot. Under
# overload a copy still here relay_max_wait_s after its time is dropped (`expired`): its source
# has resent by then. suppress_after 0 or None turns suppression off. Ni's counter threshold C
# counts the first reception too: C = 1 + suppress_after.

from __future__ import annotations

import heapq
import itertools
import math
from dataclasses import dataclass
from collections.abc import Callable
from typing import Generic, TypeVar

T = TypeVar("T")


@dataclass(slots=True)
class _Waiting:
    ttl: int  # TTL our relayed copies carry
    heard: int  # copies heard since, relayed by others with at most that TTL
    orders: set[int]  # queue entries of its copies still here


class Outbox(Generic[T]):
    """Items by due time (s), oldest first at equal times; relayed copies can be suppressed."""

    def __init__(self, suppress_after: int | None, relay_pace_s: float = 0.0,
                 relay_max_wait_s: float = math.inf,
                 on_waiting: Callable[[bytes, bool], None] | None = None) -> None:
        """`on_waiting(key, True)` when copies of a frame start waiting here (suppressible), and
        `on_waiting(key, False)` when none waits any longer."""
        self._on_waiting = on_waiting
        self.suppress_after = suppress_after or 0
        self.relay_pace_s = relay_pace_s
        self.relay_max_wait_s = relay_max_wait_s
        self.expired = 0  # relayed copies dropped: still here relay_max_wait_s after they were due
        self._heap: list[tuple[float, int, T]] = []  # our own frames
        self._relays: list[tuple[float, int, T]] = []  # relayed copies, at most one per relay_pace_s
        self._next_relay_s = float("-inf")
        self._order = itertools.count()
        self._waiting: dict[bytes, _Waiting] = {}  # key of a relayed frame -> its copies here
        self._key_of: dict[int, bytes] = {}  # queue entry of a relayed copy -> its frame's key

    def __len__(self) -> int:
        return len(self._heap) + len(self._relays)

    def push(self, due: float, item: T, key: bytes | None = None, ttl: int = 0, paced: bool = True) -> None:
        """Queue `item` for `due` s. `key`: the cache key of a relayed frame (suppressible), whose
        copies carry TTL `ttl`; `paced` False lets it leave when due (a segment: its source paces)."""
        order = next(self._order)
        heapq.heappush(self._relays if key is not None and paced else self._heap, (due, order, item))
        if key is not None and self.suppress_after:
            self._key_of[order] = key
            waiting = self._waiting.get(key)
            if waiting is None:
                self._waiting[key] = _Waiting(ttl, 0, {order})
                if self._on_waiting is not None:
                    self._on_waiting(key, True)
            else:  # another copy of a frame already waiting (Relay Retransmit, or a late echo)
                waiting.orders.add(order)

    def holds_relays(self) -> bool:
        """Whether any suppressible relayed copy waits here."""
        return bool(self._waiting)

    def waiting(self, key: bytes) -> bool:
        """Whether relayed copies of the frame with `key` wait here (suppression on only)."""
        return key in self._waiting

    def heard_again(self, key: bytes, ttl: int) -> int:
        """A further copy of the frame with `key` was heard with TTL `ttl`: count it if another
        relay sent it at our level or beyond (TTL at most our copies'); returns the number of
        copies cancelled now (0 unless this made the count reach suppress_after)."""
        waiting = self._waiting.get(key)
        if waiting is None or ttl > waiting.ttl:  # the Relay Retransmit copies of whoever we heard
            return 0
        waiting.heard += 1
        if waiting.heard < self.suppress_after:
            return 0
        del self._waiting[key]
        if self._on_waiting is not None:
            self._on_waiting(key, False)
        orders = waiting.orders
        for order in orders:
            del self._key_of[order]
        self._relays = [entry for entry in self._relays if entry[1] not in orders]
        heapq.heapify(self._relays)
        if len(self._heap) and any(entry[1] in orders for entry in self._heap):
            self._heap = [entry for entry in self._heap if entry[1] not in orders]
            heapq.heapify(self._heap)
        return len(orders)

    def next_due(self) -> float | None:
        own = self._heap[0][0] if self._heap else None
        if not self._relays:
            return own
        relay = max(self._relays[0][0], self._next_relay_s)
        return relay if own is None or relay < own else own

    def pop_due(self, now: float) -> list[T]:
        """Every own item due by `now` s and the relayed copies due that the pace allows (one per
        relay_pace_s), oldest first; relayed copies handed out leave suppression behind."""
        heap, out = self._heap, []
        while heap and heap[0][0] <= now:
            entry = heapq.heappop(heap)
            self._leave(entry[1])
            out.append(entry)
        if out and self.relay_pace_s:  # our own frames go first; the next relay waits its turn
            self._next_relay_s = max(self._next_relay_s, now + self.relay_pace_s)
        relays = self._relays
        while relays and relays[0][0] <= now and now >= self._next_relay_s:
            entry = heapq.heappop(relays)
            self._leave(entry[1])
            if now > entry[0] + self.relay_max_wait_s:
                self.expired += 1
                continue
            if self.relay_pace_s:
                self._next_relay_s = now + self.relay_pace_s
            out.append(entry)
        if not out:  # the common case: asked after every frame accepted
            return []
        out.sort(key=lambda entry: entry[:2])
        return [entry[2] for entry in out]

    def _leave(self, order: int) -> None:
        """A relayed copy leaves the outbox: it can no longer be suppressed."""
        key = self._key_of.pop(order, None)
        if key is not None:
            waiting = self._waiting[key]
            waiting.orders.discard(order)
            if not waiting.orders:
                del self._waiting[key]
                if self._on_waiting is not None:
                    self._on_waiting(key, False)
