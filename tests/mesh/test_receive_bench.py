"""checks/receive_bench.py measures what it says: every robot accepts every other robot's Heartbeat,
timed per frame accepted (behaviour, not speed: no figure is a goal here)."""

from __future__ import annotations

import math

from rescuemesh.checks.receive_bench import receive_cost


def test_every_robot_accepts_every_heartbeat_and_each_acceptance_is_timed():
    ticks = iter(range(10**9))
    us, accepted = receive_cost(robots=4, periods=3, clock=lambda: next(ticks) * 1e-6)  # 1 us a tick
    # 4 robots x 3 others x 3 periods Heartbeats at least, plus the PoseUpdates their paths let through
    assert 4 * 3 * 3 <= accepted <= 2 * 4 * 3 * 3
    assert math.isclose(us, 1.0)  # one clock tick between a receive()'s start and end


def test_a_team_without_the_shared_memory_accepts_the_same_frames():
    assert receive_cost(robots=4, periods=3, remember=0)[1] == receive_cost(robots=4, periods=3)[1]
