"""scenarios/base.py `settled`: still for SETTLE_S s, judged on the recent samples only."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.runtime.inprocess.sim_loop import TrajectorySample
from rescuemesh.scenarios.base import SETTLE_S, SETTLED_SPEED, settled

DT = 0.05


def runtime_with(speeds: list[float]) -> SimpleNamespace:
    samples = [TrajectorySample(round(k * DT, 9), Pose2D(0.0, 0.0, 0.0), v) for k, v in enumerate(speeds)]
    return SimpleNamespace(time=samples[-1].time_s, trajectories={"robot_1": samples})


@pytest.mark.parametrize("moving_until_s, expected", [
    (None, True),  # never moved
    (5.0, True),  # moved long ago, still since
    (9.0 - SETTLE_S + 2 * DT, False),  # moved within the last SETTLE_S s
    (9.0, False),  # moving now
])
def test_settled_looks_at_the_last_settle_time_only(moving_until_s, expected):
    speeds = [0.5 if moving_until_s is not None and k * DT <= moving_until_s else 0.0 for k in range(181)]
    assert settled(runtime_with(speeds), "robot_1", since_s=0.0) is expected


def test_not_settled_before_settle_time_since_the_start():
    rt = runtime_with([0.0] * 181)
    assert settled(rt, "robot_1", since_s=rt.time - SETTLE_S / 2) is False
    assert settled(rt, "robot_1", since_s=rt.time - SETTLE_S) is True


def test_a_speed_just_below_the_threshold_counts_as_still():
    assert settled(runtime_with([SETTLED_SPEED * 0.99] * 100), "robot_1", since_s=0.0) is True
    assert settled(runtime_with([SETTLED_SPEED] * 100), "robot_1", since_s=0.0) is False
