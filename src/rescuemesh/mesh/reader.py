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
#
# With a sealer that remembers (FrameSealer(remember=N), one per simulated team), the results live
# in the sealer's `reads` instead, by (bytes heard, epoch), and serve every node with that sealer:
# of the 29 robots that hear a frame in a convoy of 30, the first opens and parses it, the others
# find it there. The epoch a node asks for is its own (the announced one for a Heartbeat, else the
# source's epoch in its replay window, then the next), asked in the same order as it would open
# them, so each node reaches the result it would have computed: an entry exists only for bytes that
# opened under that key and that epoch, and a node that knows another epoch looks up another entry.

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

#: What a frame read gives: its CRC frame, header, network cache key, the epoch it opened under, and
#: a one-item list the node may fill with something it derives from those alone (the copy a relay
#: sends: the same for every node that reads the frame, so one node computes it for the team).
Read = tuple[bytes, FrameView, bytes, int, list]


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
        sealer = self.sealer
        if sealer is not None and sealer.reads is not None:
            return self._read_shared(heard, sealer.reads)
        known = self._recent.get(heard)
        if known is not None:
            return known
        data, epoch = heard, 0
        if self.sealer is not None:
            opened = self._open(heard)
            if opened is None:
                return None
            data, epoch = opened
        read = self._parse(data, epoch, self.sealer is not None)
        if read is None:
            return None
        self._recent[heard] = read
        if len(self._recent) > MAX_OPENED_FRAMES:
            del self._recent[next(iter(self._recent))]
        return read

    def _read_shared(self, heard: bytes, reads: dict) -> Read | None:
        """read() through the sealer's shared results (module comment): the same checks, counters
        and result as _open and _parse, a frame opened and parsed once per team. Each candidate
        epoch that opened before is found in `reads`, in the order _open would try it."""
        candidates = self._candidates(heard)
        if candidates is None:
            return None
        sealer = self.sealer
        for epoch in candidates:
            read = reads.get((heard, epoch))
            if read is not None:
                return read
            try:
                data = sealer.open(heard, epoch)
            except FrameError:
                continue
            read = self._parse(data, epoch, True)
            if read is not None:
                reads[(heard, epoch)] = read
                if len(reads) > sealer.remember:
                    del reads[next(iter(reads))]
            return read
        self.stats.dropped_forged += 1
        return None

    def _parse(self, data: bytes, epoch: int, sealed: bool) -> Read | None:
        """The Read of CRC frame `data` opened under `epoch`, or None (counted) for a malformed frame
        or our own. The cache key starts with the epoch when `sealed`."""
        stats = self.stats
        try:
            view = read_on_air(data)
        except FrameError as exc:
            name = _DROP_COUNTER.get(type(exc), "dropped_malformed")
            setattr(stats, name, getattr(stats, name) + 1)
            return None
        if view.src == self.address:  # sealed: unreachable, the source is in the clear and checked first
            stats.dropped_own += 1
            return None
        return data, view, cache_key(data, epoch if sealed else None), epoch, [None]

    def forget(self) -> None:
        """Forget the frames read so far: a source's epoch moved on, and a frame of its old epoch
        must be opened again (it no longer opens)."""
        self._recent.clear()

    def _open(self, data: bytes) -> tuple[bytes, int] | None:
        """The CRC frame inside an authenticated one and its epoch, or None (counted)."""
        candidates = self._candidates(data)
        if candidates is None:
            return None
        for epoch in candidates:
            try:
                return self.sealer.open(data, epoch), epoch
            except FrameError:
                continue
        self.stats.dropped_forged += 1
        return None

    def _candidates(self, data: bytes) -> tuple[int, ...] | None:
        """The epochs an authenticated frame may open under, in the order to try them, or None
        (counted) for one not authenticated, our own, or from a source whose epoch is not known."""
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
            return (announced,)
        known = self._replay.epoch_of(src)
        if known is None:
            stats.dropped_unknown_epoch += 1
            return None
        return known, (known + 1) & MAX_EPOCH  # the source may have wrapped since
