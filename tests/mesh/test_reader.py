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


def reader_knowing_source_1(sealer: FrameSealer | None = None, address: int = 9,
                            epoch: int = EPOCH) -> tuple[FrameReader, CountingSealer, MeshStats]:
    """A reader at `address` whose replay window knows source 1 in `epoch` (as after its Heartbeat)."""
    sealer = sealer if sealer is not None else CountingSealer(derive_frame_key(team_key_from_seed(1)))
    stats, replay = MeshStats(), ReplayWindow()
    replay.accept(1, epoch, 0, 0)
    return FrameReader(address, sealer, replay, stats), sealer, stats


def test_the_same_bytes_again_are_read_from_memory_with_the_same_result():
    reader, sealer, _ = reader_knowing_source_1()
    heard = sealer.seal(stop(1, 2, seq=7), EPOCH)
    first = reader.read(heard)
    again = reader.read(bytes(heard))  # an equal copy, not the same object
    assert first is not None and again == first and sealer.opens == 1
    data, view, key, epoch, _ = first
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


# --- a team's readers share what they read (FrameSealer(remember=...).reads) --------------------


def team_sealer(seed: int = 1) -> CountingSealer:
    return CountingSealer(derive_frame_key(team_key_from_seed(seed)), remember=64)


def test_readers_with_one_remembering_sealer_open_a_frame_once_and_get_the_same_read():
    sealer = team_sealer()
    heard = sealer.seal(stop(1, 2, seq=7), EPOCH)
    reads = [reader_knowing_source_1(sealer, address)[0].read(heard) for address in (3, 4, 5)]
    assert reads[0] is not None and reads[1] is reads[0] and reads[2] is reads[0]
    assert sealer.opens == 1
    data, view, key, epoch, _ = reads[0]
    assert (view.src, view.seq, epoch, data) == (1, 7, EPOCH, stop(1, 2, seq=7))


def test_a_forged_frame_is_never_served_from_the_shared_memory():
    sealer = team_sealer()
    genuine = sealer.seal(stop(1, 2, seq=7), EPOCH)
    forged = bytearray(genuine)
    forged[-1] ^= 0x01
    for address in (3, 4):
        reader, _, stats = reader_knowing_source_1(sealer, address)
        assert reader.read(genuine) is not None
        for _ in range(2):
            assert reader.read(bytes(forged)) is None
        assert stats.dropped_forged == 2
    assert sealer.opens == 1 + 2 * 2 * 2  # the genuine once; the forged each time, both epochs
    assert all(heard == genuine for heard, _ in sealer.reads)


def test_a_frame_read_under_one_key_is_not_read_by_a_team_with_another_key():
    ours, theirs = team_sealer(1), team_sealer(2)
    heard = ours.seal(stop(1, 2, seq=7), EPOCH)
    assert reader_knowing_source_1(ours, 3)[0].read(heard) is not None
    reader, _, stats = reader_knowing_source_1(theirs, 4)
    assert reader.read(heard) is None and stats.dropped_forged == 1 and not theirs.reads


def test_an_entry_answers_only_for_the_epoch_it_opened_under():
    sealer = team_sealer()
    heard = sealer.seal(stop(1, 2, seq=7), EPOCH)
    assert reader_knowing_source_1(sealer, 3)[0].read(heard) is not None  # in memory under EPOCH
    # a node that knows source 1 two epochs on (it restarted since): the frame is stale, not served
    reader, _, stats = reader_knowing_source_1(sealer, 4, epoch=EPOCH + 2)
    opens = sealer.opens
    assert reader.read(heard) is None and stats.dropped_forged == 1
    assert sealer.opens == opens + 2  # it tried EPOCH + 2 and + 3, as without the memory
    # a node one epoch behind tries its own epoch first, then finds the frame under the next
    reader, _, stats = reader_knowing_source_1(sealer, 5, epoch=EPOCH - 1)
    read = reader.read(heard)
    assert read is not None and read[3] == EPOCH and sealer.opens == opens + 3


def test_a_heartbeat_is_looked_up_under_the_epoch_it_announces():
    from rescuemesh.protocol import Endpoint
    sealer = team_sealer()
    endpoint = Endpoint(1, )
    endpoint.epoch = EPOCH
    endpoint.send_heartbeat(0.0)
    (frame, epoch), = endpoint.drain(0.0)
    heard = sealer.seal(frame, epoch)
    first = FrameReader(3, sealer, ReplayWindow(), MeshStats()).read(heard)  # epoch unknown: announced
    second = FrameReader(4, sealer, ReplayWindow(), MeshStats()).read(heard)
    assert first is not None and second is first and first[3] == epoch and sealer.opens == 1


def test_memory_shared_by_readers_is_bounded():
    sealer = team_sealer()
    reader = reader_knowing_source_1(sealer)[0]
    for k in range(100):
        reader.read(sealer.seal(stop(1, 2, seq=k), EPOCH))
    assert len(sealer.reads) == sealer.remember == 64
