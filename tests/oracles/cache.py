"""Oracle of the mesh node's network message cache (mesh/cache.py): the OrderedDict it was before
its keys moved into flat slots that the simulated medium's front door reads."""

from __future__ import annotations

from collections import OrderedDict


class NetworkCache:
    """At most `size` keys, each valid for `lifetime_s` s after it was last heard; a duplicate
    refreshes its key; the least recently heard goes first."""

    def __init__(self, size: int, lifetime_s: float) -> None:
        self.size = size
        self.lifetime_s = lifetime_s
        self._keys: OrderedDict[bytes, float] = OrderedDict()  # key -> last heard, in s; oldest first

    def __len__(self) -> int:
        return len(self._keys)

    def __contains__(self, key: bytes) -> bool:
        return key in self._keys

    def check_and_add(self, key: bytes, now: float) -> bool:
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

    def keys(self) -> list[bytes]:
        return list(self._keys)
