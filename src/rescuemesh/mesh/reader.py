"""Steps 1-2 of a mesh node's receive path: open an authenticated frame, check and read its header,
drop our own; and remember what it read, by the bytes heard. Must not know relays, the cache's
policy, replay decisions, radios or clocks (the node owns those).
"""

# A copy of a frame heard again as the same bytes (a relay's Relay Retransmit copies, two relays
# re-sealing one frame identically, a source's resends once their attempt bits saturate) is read
# from the last MAX_OPENED_FRAMES results instead of being opened again: in a team of 30 most frames
# heard are such copies, and AES-CCM and parsing were a third of the receive path. Zephyr's mesh
# stack likewise checks its message cache before it decrypts a network PDU. Only frames that opened
# and parsed are remembered, so a bad frame is counted every time it is heard.

from __future__ import annotations

from rescuemesh.protocol import FrameError
from rescuemesh.protocol.codec import FRAME_OVERHEAD_BYTES, MAX_EPOCH
from rescuemesh.protocol.errors import IntegrityError

from .frames import AUTH_BIT, FrameView, cache_key, read_on_air
from .stats import MeshStats

#: Frames read recently whose results are kept, by the bytes heard.
MAX_OPENED_FRAMES = 256
#: FrameError subclass -> the counter it increments (any other: dropped_malformed).
_DROP_COUNTER: dict[type, str] = {IntegrityError: "dropped_corrupt"}

#: What a frame read gives: its CRC frame, header, network cache key and the epoch it opened under.
Read = tuple[bytes, FrameView, bytes, int]


class FrameReader:
    """Reads frames heard by the node at `address`; counts what it drops in `stats`. `sealer`: the
    team's FrameSealer (None: CRC frames); `replay`: the node's ReplayWindow (its sources' epochs)."""

    def __init__(self, address: int, sealer, replay, stats: MeshStats) -> None:
        self.address = address
        self.sealer = sealer
        self._replay = replay
        self.stats = stats
        self._recent: dict[bytes, Read] = {}

    def read(self, heard: bytes) -> Read | None:
        """(CRC frame, header, cache key, epoch) of `heard`, or None (counted) for a frame that does
        not open, is malformed or is our own. The cache key starts with the epoch when sealed."""
        known = self._recent.get(heard)
        if known is not None:
            return known
        data, epoch = heard, 0
        if self.sealer is not None:
            opened = self._open(heard)
            if opened is None:
                return None
            data, epoch = opened
        stats = self.stats
        try:
            view = read_on_air(data)
        except FrameError as exc:
            name = _DROP_COUNTER.get(type(exc), "dropped_malformed")
            setattr(stats, name, getattr(stats, name) + 1)
            return None
        if view.src == self.address:
            stats.dropped_own += 1
            return None
        key = cache_key(data, None if self.sealer is None else epoch)
        read = self._recent[heard] = (data, view, key, epoch)
        if len(self._recent) > MAX_OPENED_FRAMES:
            del self._recent[next(iter(self._recent))]
        return read

    def forget(self) -> None:
        """Forget the frames read so far: a source's epoch moved on, and a frame of its old epoch
        must be opened again (it no longer opens)."""
        self._recent.clear()

    def _open(self, data: bytes) -> tuple[bytes, int] | None:
        """The CRC frame inside an authenticated one and its epoch, or None (counted)."""
        stats = self.stats
        if len(data) < FRAME_OVERHEAD_BYTES or not data[0] & AUTH_BIT:
            stats.dropped_unauthenticated += 1
            return None
        src = data[2]
        if src == self.address:
            stats.dropped_own += 1
            return None
        announced = self.sealer.heartbeat_epoch(data)
        if announced is not None:
            candidates = (announced,)
        else:
            known = self._replay.epoch_of(src)
            if known is None:
                stats.dropped_unknown_epoch += 1
                return None
            candidates = (known, (known + 1) & MAX_EPOCH)  # the source may have wrapped since
        for epoch in candidates:
            try:
                return self.sealer.open(data, epoch), epoch
            except FrameError:
                continue
        stats.dropped_forged += 1
        return None
