"""The priority table: rank first, then the command's level; held resources; Stop needs nothing."""

import pytest

from rescuemesh.protocol.messages import COMMAND_TYPES
from rescuemesh.protocol import MessageType as T
from rescuemesh.protocol import Reason
from rescuemesh.robot.commands import COMMANDS, priority_of, resources_of
from rescuemesh.robot.policy import Priority, Rank, Resource, conflict

FOLLOW_BY_LEAD = priority_of(T.FOLLOW, Rank.TEAM_LEAD)


def _conflict(new: T, rank: Rank, held: Resource, running: Priority) -> Reason | None:
    return conflict(priority_of(new, rank), resources_of(new), held, running)


@pytest.mark.parametrize("new, rank, expected", [
    (T.GOTO, Rank.PEER, Reason.MOTION_HELD),  # a peer may not take the wheel from a team lead
    (T.GOTO, Rank.TEAM_LEAD, None),  # equal priority preempts
    (T.GOTO, Rank.OPERATOR, None),  # higher rank preempts
    (T.MOVE_AROUND, Rank.PEER, Reason.MOTION_HELD),
    (T.SHOW_SCAN, Rank.PEER, None),  # needs the laser, not the wheels
    (T.STOP, Rank.PEER, None),  # Stop always wins: it needs nothing
])
def test_conflicts_with_a_team_leads_follow(new, rank, expected):
    assert _conflict(new, rank, Resource.MOTION, FOLLOW_BY_LEAD) is expected


def test_rank_outweighs_level():
    assert priority_of(T.SHOW_SCAN, Rank.OPERATOR) >= priority_of(T.GOTO, Rank.TEAM_LEAD)
    assert priority_of(T.GOTO, Rank.PEER) < Priority(Rank.PEER, 9)


def test_every_command_has_a_row():
    commands = {T.FOLLOW, T.SHOW_CAM, T.SHOW_SCAN, T.LAND_ON_TOP, T.GOTO, T.STOP, T.FORWARD_MSG, T.RETURN,
                T.MOVE_AROUND}
    assert set(COMMANDS) == commands == COMMAND_TYPES


def test_a_held_sensor_is_named_in_the_reason():
    assert _conflict(T.SHOW_CAM, Rank.PEER, Resource.CAMERA, Priority(Rank.OPERATOR, 3)) is Reason.CAMERA_HELD


def test_a_scan_that_must_drive_needs_the_wheels_too():
    held = _conflict(T.SHOW_SCAN, Rank.PEER, Resource.MOTION, FOLLOW_BY_LEAD)
    assert held is None  # the laser alone is free
    needs = resources_of(T.SHOW_SCAN) | Resource.MOTION
    assert conflict(priority_of(T.SHOW_SCAN, Rank.PEER), needs, Resource.MOTION, FOLLOW_BY_LEAD) is Reason.MOTION_HELD
