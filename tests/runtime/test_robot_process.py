"""What a robot process sends the world: typed values only; its navigation and costmap stay in it."""

from collections import Counter, deque

import numpy as np
import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import load_map, office_map_path
from rescuemesh.nav import Costmap, NavigateToPose
from rescuemesh.protocol import DataKind, ResultCode
from rescuemesh.protocol import MessageType, Reason
from rescuemesh.robot.events import Confirm
from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.processes.control_codec import CodecError, decode, encode


@pytest.mark.parametrize("value", [
    None, 3, 2.5, "robot_2", b"\x01", ResultCode.ACCEPTED, Pose2D(1.0, 2.0, 0.5),
    [Confirm(0.1, "robot_1", MessageType.FOLLOW, 2, 1, ResultCode.ACCEPTED, Reason.NONE, 255, 1)], {1: Pose2D(0, 0, 0)},
    np.zeros(360), (1, "a", None), (0.5, 2, DataKind.LASER_SCAN, 7, b"\x00\x01", 1),
])
def test_plain_values_and_registered_types_cross_the_control_plane(value):
    copy = decode(encode(value))
    assert np.array_equal(copy, value) if isinstance(value, np.ndarray) else copy == value


def test_counters_and_deques_cross_as_their_plain_forms():
    assert decode(encode(Counter({1: 3}))) == {1: 3}
    assert decode(encode(deque([1, 2]))) == [1, 2]


def test_a_navigation_with_its_costmap_stays_in_the_robot():
    # this used to be pickled whole on every read of brain.running: a costmap per tick
    nav = NavigateToPose(Costmap(load_map(office_map_path()).grid))
    for value in (nav, [1, nav], {"behaviour": nav}, lambda: 1, np.array([object()])):
        with pytest.raises(CodecError):
            encode(value)
    with pytest.raises(CodecError):
        encode(np.zeros(1 << 22))  # 32 MB: over the array limit


def test_every_request_has_its_reply_type():
    assert set(msg.ANSWERS) == set(msg.REQUESTS)
    assert set(msg.ANSWERS.values()) | {msg.ErrorReply} == set(msg.REPLIES)


def test_a_transmission_with_its_message_type_crosses():
    # this used to be refused: Transmission.msg_type is annotated int and holds a MessageType (show-scan died)
    from rescuemesh.mesh.node import Transmission
    from rescuemesh.protocol import MessageType

    sent = Transmission(b"\x01", 1, 2, MessageType.SHOW_SCAN, 5, 4, False, None, None)
    assert decode(encode(msg.StackReply([sent], None))).transmissions == [sent]
