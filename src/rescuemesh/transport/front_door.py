"""The mesh nodes' front door in the simulated medium: the copies of a frame that each receiver would
drop unopened or as already cached, recognised in one compiled call over the receivers' caches.

Owns: the cache buffers the medium lends the nodes (one row per radio) and the kernel that reads
them. Must not know: what a key is made of, relays, sealing; it reads what mesh/cache.py lays out.
"""

# A frame that reaches a receiver goes to its stack's receive() (mesh/node.py, steps 0-6) unless
# the kernel can tell that receive() would do nothing but count it, and does that itself:
#
#   - step 0: for another robot, TTL < 2, and no relayed copy waits in the node's outbox (WAITING
#     is 0): counted received and dropped_passing;
#   - step 3: its key (Transmission.key, the key the receiver files it under) is held in a slot that
#     is FILTERABLE (no source's epoch moved on since it was filed), not WAITS (no relayed copy of
#     it waits in the outbox: hearing it counts towards suppression) and not expired (heard less than
#     the cache lifetime ago): the slot is refreshed as check_and_add refreshes a duplicate (heard =
#     now, stamp = the next tick of the node's clock) and the copy counted received and
#     dropped_cached.
#
# Everything else (a new frame, an expired key, one whose relays wait, a stack without a node's
# cache, a frame without a key) is handed to receive(), as before. The counts land in the node's
# buffer and are folded into its MeshStats when they are read (MeshNode.stats). The oracle is the
# node itself: tests/oracles/test_front_door.py runs the same receptions through receive() alone.

from __future__ import annotations

import numpy as np

from rescuemesh.jit import compiled
from rescuemesh.mesh.cache import (
    CACHED,
    CLOCK,
    FILTERABLE,
    KEY_WORDS,
    MAX_KEY_BYTES,
    META,
    PASSING,
    RECEIVED,
    SIZE,
    WAITING,
    WAITS,
    storage_words,
)

_OK = 0  # medium_kernels.OK: a reception nothing spoiled


class FrontDoor:
    """The cache buffers of the radios whose stacks have a mesh node (rows by radio index)."""

    def __init__(self) -> None:
        self.caches: list = []  # by radio index: the node's NetworkCache, or None
        self.words = np.zeros((0, META), dtype=np.int64)
        self.heard = np.zeros((0, 1))
        self.lifetime = np.zeros(0)
        self.has = np.zeros(0, dtype=bool)
        self.hand = np.zeros(0, dtype=bool)

    def attach(self, stack) -> None:
        """Add a radio (the next index); lend its node's cache rows in new buffers (every node's
        moves: the buffers grow)."""
        cache = getattr(getattr(stack, "node", None), "cache", None)
        self.caches.append(cache if hasattr(cache, "use_storage") else None)
        held = [c for c in self.caches if c is not None]
        width = max([storage_words(c.size) for c in held], default=META)
        slots = max([c.size for c in held], default=1)
        n = len(self.caches)
        self.words = np.zeros((n, width), dtype=np.int64)
        self.heard = np.zeros((n, slots))
        self.lifetime = np.zeros(n)
        self.has = np.array([c is not None for c in self.caches], dtype=bool)
        self.hand = np.zeros(n, dtype=bool)
        for i, c in enumerate(self.caches):
            if c is not None:
                c.use_storage(memoryview(self.words[i, :storage_words(c.size)]), memoryview(self.heard[i, :c.size]))
                self.lifetime[i] = c.lifetime_s

    def sort(self, state: np.ndarray, addresses: np.ndarray, transmission, broadcast: int, now: float) -> np.ndarray:
        """The radios whose stack must receive this frame (state OK, not recognised here), by index;
        the copies recognised are counted in their nodes' buffers."""
        key = getattr(transmission, "key", b"")
        if not key or len(key) > MAX_KEY_BYTES:
            return np.flatnonzero(state == _OK)
        words = np.frombuffer(bytearray(key.ljust(MAX_KEY_BYTES, b"\0")), dtype="<i8")
        recognise(state, addresses, self.has, self.words, self.heard, self.lifetime, words, len(key),
                  transmission.dst, transmission.ttl, broadcast, now, self.hand)
        return np.flatnonzero(self.hand)


@compiled("i8(i1[::1], i8[::1], b1[::1], i8[:, ::1], f8[:, ::1], f8[::1], i8[::1], i8, i8, i8, i8, f8, b1[::1])")
def recognise(state, addresses, has, words, heard, lifetime, key, key_len, dst, ttl, broadcast, now, hand):
    """For each radio that received the frame (state OK): recognise the copy its node would only
    count (module comment) and count it there, or set `hand[r]`. Returns how many are handed on."""
    handed = 0
    for r in range(len(state)):
        hand[r] = False
        if state[r] != _OK:
            continue
        if not has[r]:
            hand[r] = True
            handed += 1
            continue
        w = words[r]
        if dst != addresses[r] and dst != broadcast and ttl < 2 and w[WAITING] == 0:  # step 0
            w[RECEIVED] += 1
            w[PASSING] += 1
            continue
        size = w[SIZE]
        length_at, stamp_at, flags_at, keys_at = META, META + size, META + 2 * size, META + 3 * size
        found = -1
        for s in range(size):
            if w[length_at + s] != key_len:
                continue
            at = keys_at + KEY_WORDS * s
            same = True
            for i in range(KEY_WORDS):
                if w[at + i] != key[i]:
                    same = False
                    break
            if same:
                found = s
                break
        if (found >= 0 and w[flags_at + found] & (FILTERABLE | WAITS) == FILTERABLE
                and heard[r, found] > now - lifetime[r]):
            clock = w[CLOCK] + 1
            w[CLOCK] = clock
            w[stamp_at + found] = clock
            heard[r, found] = now
            w[RECEIVED] += 1
            w[CACHED] += 1
            continue
        hand[r] = True
        handed += 1
    return handed
