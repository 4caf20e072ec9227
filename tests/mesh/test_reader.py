"""mesh/reader.py: a frame heard again as the same bytes is read from memory, not opened again;
what does not open is counted every time; the memory is bounded."""

from __future__ import annotations

import pytest

from rescuemesh.mesh.frames import read_on_air
from rescuemesh.mesh.keys import derive_frame_key, team_key_from_seed
from rescuemesh.mesh.reader import MAX_OPENED_FRAMES, FrameReader
from rescuemesh.mesh.replay import ReplayWindow
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.mesh.stats import MeshStats
from rescuemesh.protocol.errors import IntegrityError

from .frames import stop

EPOCH = 5


class CountingSealer(FrameSealer):
    """The team's sealer, counting the frames it opens."""

    opens = 0

    def open(self, frame: bytes, epoch: int) -> bytes:
        self.opens += 1
        return super().open(frame, epoch)


def reader_knowing_source_1() -> tuple[FrameReader, CountingSealer, MeshStats]:
    sealer, stats, replay = CountingSealer(derive_frame_key(team_key_from_seed(1))), MeshStats(), ReplayWindow()
    replay.accept(1, EPOCH, 0, 0)  # source 1's epoch is known (as after its Heartbeat)
    return FrameReader(9, sealer, replay, stats), sealer, stats


def test_the_same_bytes_again_are_read_from_memory_with_the_same_result():
    reader, sealer, _ = reader_knowing_source_1()
    heard = sealer.seal(stop(1, 2, seq=7), EPOCH)
    first = reader.read(heard)
    again = reader.read(bytes(heard))  # an equal copy, not the same object
    assert first is not None and again == first and sealer.opens == 1
    data, view, key, epoch = first
    assert (view.src, view.dst, view.seq, epoch) == (1, 2, 7, EPOCH) and data == stop(1, 2, seq=7)
    assert key.startswith(EPOCH.to_bytes(4, "big"))
    relayed = sealer.seal(stop(1, 2, seq=7, ttl=6), EPOCH)  # another TTL: other bytes, the same key
    assert reader.read(relayed)[2] == key and sealer.opens == 2


def test_a_forged_frame_is_opened_and_counted_every_time_it_is_heard():
    reader, sealer, stats = reader_knowing_source_1()
    forged = bytearray(sealer.seal(stop(1, 2, seq=7), EPOCH))
    forged[-1] ^= 0x01
    for _ in range(3):
        assert reader.read(bytes(forged)) is None
    assert stats.dropped_forged == 3 and sealer.opens == 3 * 2  # both epoch candidates, each time


def test_memory_is_bounded_and_forgets_the_oldest():
    reader, sealer, _ = reader_knowing_source_1()
    frames = [sealer.seal(stop(1, 2, seq=k), EPOCH) for k in range(MAX_OPENED_FRAMES + 10)]
    for frame in frames:
        reader.read(frame)
    opens = sealer.opens
    reader.read(frames[-1])
    assert sealer.opens == opens  # recent: remembered
    reader.read(frames[0])
    assert sealer.opens == opens + 1  # the oldest was forgotten
    assert len(reader._recent) == MAX_OPENED_FRAMES



def test_a_header_read_on_the_air_is_remembered_an_error_is_not():
    frame = stop(1, 2, seq=7)
    assert read_on_air(bytearray(frame)) == read_on_air(frame)  # any bytes-like, one answer
    assert read_on_air(bytes(frame)) is read_on_air(frame)  # the second read is remembered
    broken = frame[:-1] + bytes((frame[-1] ^ 1,))
    for _ in range(2):  # raised every time, never remembered as a header
        with pytest.raises(IntegrityError):
            read_on_air(broken)
