"""The network message cache (Bluetooth Mesh Profile 1.0, 3.4.6.5): keys of recently accepted
frames, so a frame heard again through another relay is neither relayed nor delivered twice.
Owns the bounded, time-limited key set only; must not know what a key is made of or relays.
"""

# Storage: flat words, so that a transport can read them without a Python call per frame
# ================================================================================
#
# The keys live in fixed slots of two flat buffers (stdlib arrays by default, or buffers a
# transport lends with `use_storage`): `words` (int64) and `heard` (float64, the time each slot was
# last heard). A dict maps a key to its slot for this module; a transport that knows the key of a
# frame (the simulated medium: rescuemesh.transport.front_door) finds it by comparing the key words
# and may refresh a slot itself, exactly as check_and_add would for a duplicate (heard = now, stamp
# = the next tick of the clock). Layout of `words`:
#
#   [0, META)                 CLOCK (touches so far), WAITING (keys whose relayed copies wait in
#                             the node's outbox), SIZE, then counters a transport adds for the copies
#                             it recognised (RECEIVED, CACHED, PASSING), which the node folds into
#                             its statistics
#   LEN + slot                key length in bytes (0: a free slot)
#   STAMP + slot              the CLOCK value of its last touch: the least recently heard has the least
#   FLAGS + slot              FILTERABLE (a transport may recognise copies of it), WAITS (copies wait)
#   KEYS + KEY_WORDS * slot   the key, zero-padded to KEY_WORDS little-endian words
#
# Eviction order is the order of stamps, kept lazily in a heap of (stamp, slot): an entry whose slot
# was touched since it was pushed is pushed again with its new stamp when it reaches the top. This is
# the OrderedDict's order exactly (least recently heard first), refreshes made outside included.

from __future__ import annotations

import heapq
import struct
from array import array
from functools import lru_cache

#: Longest key the cache holds: a sealed team's epoch (4 bytes) and a 29-byte PDU less its
#: integrity field (4) and the TTL nibble it keeps (the byte stays): 29 bytes, in 4 words.
KEY_WORDS = 4
MAX_KEY_BYTES = 8 * KEY_WORDS
CLOCK, WAITING, SIZE, RECEIVED, CACHED, PASSING = range(6)
META = 8
#: Slot flags.
FILTERABLE = 1
WAITS = 2
_KEY = struct.Struct(f"<{KEY_WORDS}q")
_PAD = bytes(MAX_KEY_BYTES)
_heappush, _heappop, _heapreplace = heapq.heappush, heapq.heappop, heapq.heapreplace


def storage_words(size: int) -> int:
    """Length of the `words` buffer of a cache of `size` slots."""
    return META + (3 + KEY_WORDS) * size


def offsets(size: int) -> tuple[int, int, int, int]:
    """(LEN, STAMP, FLAGS, KEYS): where each per-slot field starts in `words` for `size` slots."""
    return META, META + size, META + 2 * size, META + 3 * size


@lru_cache(maxsize=1024)  # a team's nodes file one frame's key each: one object, unpacked once
def key_words(key: bytes) -> tuple[int, ...]:
    """`key` (at most MAX_KEY_BYTES bytes) as the KEY_WORDS int64 words a slot stores."""
    return _KEY.unpack((key + _PAD)[:MAX_KEY_BYTES])


class NetworkCache:
    """At most `size` frame keys, each valid for `lifetime_s` s after it was last heard.

    `check_and_add(key, now)` is the one question a receiver asks: True (and the key is
    remembered) for a frame not heard recently, False for a duplicate. A duplicate refreshes its
    key, so a frame that keeps echoing round a loop of relays stays cached while it echoes. The
    least recently heard key goes first when the cache is full or its lifetime has passed
    (docs/mesh.md, "The cache", says why both bounds).
    """

    def __init__(self, size: int, lifetime_s: float) -> None:
        if not (isinstance(size, int) and size >= 1):
            raise ValueError(f"cache size must be an int >= 1, got {size!r}")
        if not lifetime_s > 0.0:
            raise ValueError(f"cache lifetime must be > 0 s, got {lifetime_s!r}")
        self.size = size
        self.lifetime_s = lifetime_s
        self._len, self._stamp, self._flags, self._keys = offsets(size)
        self.words = array("q", bytes(8 * storage_words(size)))
        self.heard = array("d", bytes(8 * size))
        self.words[SIZE] = size
        self._slot: dict[bytes, int] = {}
        self._heap: list[tuple[int, int]] = []  # (stamp, slot) of every key held, lazily re-ordered
        self._free = list(range(size - 1, -1, -1))
        self._key_of: list[bytes | None] = [None] * size
        self._waiting: set[bytes] = set()

    def use_storage(self, words, heard) -> None:
        """Move the slots into buffers lent by a transport (int64 and float64 memoryviews or arrays
        of storage_words(size) and size items); what is held stays held."""
        if len(words) != len(self.words) or len(heard) != len(self.heard):
            raise ValueError(f"storage for {self.size} slots needs {len(self.words)} words and {self.size} times")
        for i, value in enumerate(self.words):
            words[i] = value
        for i, value in enumerate(self.heard):
            heard[i] = value
        self.words, self.heard = words, heard

    def __len__(self) -> int:
        return len(self._slot)

    def __contains__(self, key: bytes) -> bool:
        return key in self._slot

    def held(self, now: float) -> set[bytes]:
        """The keys that suppress a frame at `now` s (heard less than the lifetime ago). `len` and
        `in` also count keys expired but not yet dropped: they go at the next check_and_add."""
        oldest = now - self.lifetime_s
        return {key for key, slot in self._slot.items() if self.heard[slot] > oldest}

    def check_and_add(self, key: bytes, now: float) -> bool:
        """True if `key` is new at `now` s (now cached), False if cached (now most recent)."""
        words, heard, heap = self.words, self.heard, self._heap
        oldest = now - self.lifetime_s
        stamp_at = self._stamp
        while heap:
            stamp, slot = heap[0]
            current = words[stamp_at + slot]
            if current != stamp:  # refreshed since it was pushed
                _heapreplace(heap, (current, slot))
            elif heard[slot] <= oldest:
                _heappop(heap)
                self._free_slot(slot)
            else:
                break
        clock = words[CLOCK] + 1
        words[CLOCK] = clock
        slot = self._slot.get(key)
        if slot is not None:
            heard[slot] = now
            words[stamp_at + slot] = clock
            return False
        size = len(key)
        if size > MAX_KEY_BYTES:
            raise ValueError(f"a {size}-byte cache key, at most {MAX_KEY_BYTES}")
        if not self._free:  # full: the least recently heard goes
            while True:
                stamp, slot = heap[0]
                current = words[stamp_at + slot]
                if current == stamp:
                    break
                _heapreplace(heap, (current, slot))
            _heappop(heap)
            self._free_slot(slot)
        slot = self._free.pop()
        self._slot[key] = slot
        words[self._len + slot] = size
        words[stamp_at + slot] = clock
        words[self._flags + slot] = FILTERABLE | WAITS if key in self._waiting else FILTERABLE
        at = self._keys + KEY_WORDS * slot
        words[at], words[at + 1], words[at + 2], words[at + 3] = key_words(key)
        self._key_of[slot] = key
        heard[slot] = now
        _heappush(heap, (clock, slot))
        return True

    def set_waiting(self, key: bytes, waiting: bool) -> None:
        """Relayed copies of the frame with `key` wait in the node's outbox (True) or no longer do:
        a transport must leave such a frame's copies to the node (they count towards suppression)."""
        if waiting:
            self._waiting.add(key)
        else:
            self._waiting.discard(key)
        self.words[WAITING] = len(self._waiting)
        slot = self._slot.get(key)
        if slot is not None:
            at = self._flags + slot
            self.words[at] = (self.words[at] | WAITS) if waiting else (self.words[at] & ~WAITS)

    def hold_all(self) -> None:
        """No key held now may be recognised outside check_and_add (a source's epoch moved on: a
        copy from its old epoch no longer opens, and the node must see it)."""
        words, at = self.words, self._flags
        for slot in self._slot.values():
            words[at + slot] &= ~FILTERABLE

    def take_counts(self) -> tuple[int, int, int]:
        """(received, dropped as cached, dropped as passing) counted by a transport since the last
        call, and reset."""
        words = self.words
        counts = (words[RECEIVED], words[CACHED], words[PASSING])
        if any(counts):
            words[RECEIVED] = words[CACHED] = words[PASSING] = 0
        return counts

    def _free_slot(self, slot: int) -> None:
        del self._slot[self._key_of[slot]]
        self._key_of[slot] = None
        self.words[self._len + slot] = 0
        self._free.append(slot)
