"""The neighbour table's heap of deadlines (mesh/neighbours.py) answers next_deadline() as the scan
of every entry it replaced (oracles/neighbours.py), whatever the order of hearing, losing and
forgetting, with time going forward or (in a test's hands) back."""

from __future__ import annotations

import random

import pytest

from oracles.neighbours import next_deadline as oracle_next_deadline
from rescuemesh.mesh import MeshConfig
from rescuemesh.mesh.neighbours import NeighbourTable


@pytest.mark.parametrize("seed", range(12))
def test_next_deadline_is_the_scan_of_every_entry(seed):
    rng = random.Random(seed)
    table = NeighbourTable(MeshConfig())
    now, asked = 0.0, 0
    monotonic = seed % 3 != 0
    for _ in range(600):
        step = rng.random()
        now = now + rng.choice((0.0, 0.01, 0.3, 1.0, 4.0)) if monotonic else rng.uniform(0.0, 60.0)
        if step < 0.7:
            table.heard(rng.randrange(1, 12), rng.randrange(0, 8), now, -60.0, rng.choice((None, 7)))
        elif step < 0.8:
            table.expire(now)
        if rng.random() < 0.5:  # sometimes not asked for a while: the heap grows, then is rebuilt
            asked += 1
            assert table.next_deadline() == oracle_next_deadline(table)
    assert asked > 100 and table.next_deadline() == oracle_next_deadline(table)
    assert len(table._deadlines) <= 4 * len(table) + 65  # bounded
