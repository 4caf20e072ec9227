"""mesh/events.py: the fast FrameDelivered builder makes the object the dataclass makes."""

from __future__ import annotations

import dataclasses

import pytest

from rescuemesh.mesh.events import FrameDelivered, frame_delivered


@pytest.mark.parametrize("rssi", [-61.5, None])
def test_frame_delivered_is_the_dataclass_built_field_by_field(rssi):
    built, reference = frame_delivered(b"\x41\x01", 3, 2, rssi, 7.25), FrameDelivered(b"\x41\x01", 3, 2, rssi, 7.25)
    assert type(built) is FrameDelivered and built == reference and hash(built) == hash(reference)
    assert dataclasses.astuple(built) == (b"\x41\x01", 3, 2, rssi, 7.25)
    with pytest.raises(dataclasses.FrozenInstanceError):
        built.hops = 1
