"""The network message cache (Bluetooth Mesh Profile 1.0, 3.4.6.5): keys of recently accepted
frames, so a frame heard again through another relay is neither relayed nor delivered twice.
Owns the bounded, time-limited key set only; must not know what a key is made of or relays.
"""

from __future__ import annotations

from collections import OrderedDict


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
        self._keys: OrderedDict[bytes, float] = OrderedDict()  # key -> last heard, in s; oldest first

    def __len__(self) -> int:
        return len(self._keys)

    def __contains__(self, key: bytes) -> bool:
        return key in self._keys

    def check_and_add(self, key: bytes, now: float) -> bool:
        """True if `key` is new at `now` s (now cached), False if cached (now most recent)."""
        keys = self._keys
        oldest = now - self.lifetime_s
        while keys and next(iter(keys.values())) <= oldest:
            keys.popitem(last=False)
        new = key not in keys
        keys[key] = now
        keys.move_to_end(key)
        if len(keys) > self.size:
            keys.popitem(last=False)
        return new
