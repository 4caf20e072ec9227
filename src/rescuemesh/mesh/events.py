"""Events a MeshNode hands to the layer above, pulled with `MeshNode.next_event()` (None when empty).
Owns the event dataclasses only; must not know how they are produced or what the endpoint does.
Every event carries `now`, the time in s at which it was produced.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class MeshEvent:
    """Base class of every mesh event: consumers dispatch on `type(event)` through a table."""


@dataclass(frozen=True, slots=True)
class FrameDelivered(MeshEvent):
    """A logical frame for us (our address or broadcast): pass `data` to `Endpoint.receive()`.

    `hops` from `src` (1 = heard directly); `rssi_dbm` of the reception when it came directly,
    None when it came through a relay. A reassembled frame is the exact frame the source's
    endpoint encoded (docs/mesh.md, "Reassembly").
    """

    data: bytes
    src: int
    hops: int
    rssi_dbm: float | None
    now: float


@dataclass(frozen=True, slots=True)
class NeighbourFound(MeshEvent):
    """`address` heard for the first time, or again after it was lost or forgotten."""

    address: int
    hops: int
    now: float


@dataclass(frozen=True, slots=True)
class NeighbourLost(MeshEvent):
    """`address` missed `lost_after_missed` heartbeats (plus half a period): stop what depends on it."""

    address: int
    last_heard_s: float
    now: float


@dataclass(frozen=True, slots=True)
class TransferComplete(MeshEvent):
    """Every one of the `segments` segments of our frame `seq` to `dst` was acknowledged."""

    dst: int
    seq: int
    segments: int
    now: float


@dataclass(frozen=True, slots=True)
class TransferFailed(MeshEvent):
    """Segmented frame `seq` to `dst` given up: `acked` of `total` segments were acknowledged."""

    dst: int
    seq: int
    acked: int
    total: int
    now: float


@dataclass(frozen=True, slots=True)
class PeerRestarted(MeshEvent):
    """`address` is in a newer `epoch` (it rebooted, or its sequence wrapped): its old sequence
    numbers mean nothing now (the stack tells the endpoint to forget them)."""

    address: int
    epoch: int
    now: float


@dataclass(frozen=True, slots=True)
class SegmentsResent(MeshEvent):
    """`src` sent segments of its frame `seq` again after we had reassembled and acknowledged it: it
    lacks our SegmentAck and maybe our Confirm (the stack asks the endpoint to answer again)."""

    src: int
    seq: int
    now: float


# A frame for us is delivered as one FrameDelivered per robot that hears it (a thousand a second in a
# team of 30): built straight into its slots, as codec._make_header builds a Header, without the
# frozen dataclass's object.__setattr__ per field. The same object as FrameDelivered(...).
_new = object.__new__
_SET_DELIVERED = tuple(FrameDelivered.__dict__[name].__set__ for name in ("data", "src", "hops", "rssi_dbm", "now"))


def frame_delivered(data: bytes, src: int, hops: int, rssi_dbm: float | None, now: float) -> FrameDelivered:
    """FrameDelivered(data, src, hops, rssi_dbm, now), built faster."""
    event = _new(FrameDelivered)
    set_data, set_src, set_hops, set_rssi, set_now = _SET_DELIVERED
    set_data(event, data)
    set_src(event, src)
    set_hops(event, hops)
    set_rssi(event, rssi_dbm)
    set_now(event, now)
    return event
