"""What a robot process copies to the world (data) and what it keeps and lends out by reference."""

from collections import Counter, deque

import numpy as np
import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.nav import Costmap, NavigateToPose
from rescuemesh.protocol import ResultCode
from rescuemesh.robot import BrainEvent
from rescuemesh.runtime.control import dumps, loads
from rescuemesh.runtime.robot_process import is_data


@pytest.mark.parametrize("value", [
    None, 3, 2.5, "robot_2", b"\x01", ResultCode.ACCEPTED, Pose2D(1.0, 2.0, 0.5),
    [BrainEvent(0.1, "robot_1", "confirm", "Follow by robot_2: ACCEPTED")], {1: Pose2D(0, 0, 0)},
    Counter({1: 3}), deque([1, 2]), np.zeros(360), (1, "a", None),
])
def test_plain_values_are_data_and_cross_the_control_plane(value):
    assert is_data(value)
    copy = loads(dumps(value))
    assert np.array_equal(copy, value) if isinstance(value, np.ndarray) else copy == value


def test_a_navigation_with_its_costmap_stays_in_the_robot():
    # this used to be pickled whole on every read of brain.running: a costmap per tick
    nav = NavigateToPose(Costmap(load_map(office_map_path()).grid))
    assert not is_data(nav)
    assert not is_data([1, nav])
    assert not is_data({"behaviour": nav})
    assert not is_data(lambda: 1)
    assert not is_data(np.zeros(1 << 20))  # too large to copy
    assert not is_data(np.array([object()]))
