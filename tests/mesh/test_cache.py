"""The network message cache and its key (docs/mesh.md section 4)."""

from __future__ import annotations

import pytest

from rescuemesh.mesh.cache import NetworkCache
from rescuemesh.mesh.frames import cache_key, with_ttl
from rescuemesh.mesh.segments import make_segment

from .frames import data, stop


def test_the_same_frame_under_another_ttl_has_the_same_key():
    frame = stop(1, 2, seq=3)
    assert cache_key(with_ttl(frame, 2)) == cache_key(frame)


@pytest.mark.parametrize(
    "other",
    [
        stop(1, 2, seq=3, attempt=1),  # a resend
        stop(1, 2, seq=4),  # another seq
        stop(2, 1, seq=3),  # another source
    ],
)
def test_resends_and_other_frames_have_other_keys(other):
    assert cache_key(other) != cache_key(stop(1, 2, seq=3))


def test_segments_differ_by_index_and_round():
    frame = data(1, 2, seq=3, size=60)
    keys = {cache_key(make_segment(frame, i, r)) for i in range(4) for r in range(4)}
    assert len(keys) == 16


def test_check_and_add():
    cache = NetworkCache(size=2, lifetime_s=1.0)
    assert cache.check_and_add(b"a", 0.0) and not cache.check_and_add(b"a", 0.1)
    assert cache.check_and_add(b"b", 0.2) and cache.check_and_add(b"c", 0.3)
    assert b"a" not in cache and len(cache) == 2  # least recently heard evicted


def test_a_duplicate_refreshes_its_key():
    cache = NetworkCache(size=2, lifetime_s=1.0)
    cache.check_and_add(b"a", 0.0)
    cache.check_and_add(b"b", 0.1)
    cache.check_and_add(b"a", 0.2)  # heard again: now the most recent
    cache.check_and_add(b"c", 0.3)
    assert b"a" in cache and b"b" not in cache


def test_an_entry_older_than_the_lifetime_no_longer_suppresses():
    cache = NetworkCache(size=128, lifetime_s=0.75)
    cache.check_and_add(b"a", 0.0)
    assert not cache.check_and_add(b"a", 0.5)  # refreshed at 0.5
    assert not cache.check_and_add(b"a", 1.2)
    assert cache.check_and_add(b"a", 1.95)  # 0.75 s after it was last heard


@pytest.mark.parametrize("size, lifetime", [(0, 1.0), (1.5, 1.0), (1, 0.0)])
def test_bad_parameters(size, lifetime):
    with pytest.raises(ValueError):
        NetworkCache(size, lifetime)
