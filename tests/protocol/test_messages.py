"""The vocabulary: types, result codes, message dataclasses."""

from __future__ import annotations

import dataclasses

import pytest

from rescuemesh.protocol import (
    Follow, ForwardMsg, Goto, LandOnTop, MessageType, MoveAround, Pose, ResultCode, Return, ShowCam, ShowScan,
    Stop)
from rescuemesh.protocol.messages import (
    COMMAND_TYPES, CONFIRMABLE_TYPES, Confirm, Heartbeat, PoseUpdate, is_command)

P = Pose(0.0, 0.0, 0.0, 0.0)
COMMANDS = [Follow(P), ShowCam(P, 1.0, 1), ShowScan(P, 1.0, 0), LandOnTop(P), Goto(P), Stop(),
            ForwardMsg(3, b"\x06"), Return(), MoveAround(P, 1.0)]
OTHERS = [Confirm(1, MessageType.STOP, ResultCode.DONE), PoseUpdate(P), Heartbeat(0, 3)]


def test_result_codes_follow_mav_result_order():
    assert [(r.name, r.value) for r in ResultCode] == [
        ("ACCEPTED", 0), ("IN_PROGRESS", 1), ("DONE", 2), ("DENIED", 3),
        ("UNSUPPORTED", 4), ("FAILED", 5), ("CANCELLED", 6), ("TEMPORARILY_REJECTED", 7),
    ]


def test_message_types_fit_six_bits_and_zero_is_reserved():
    assert all(1 <= t <= 63 for t in MessageType)


def test_commands_are_the_nine_of_table_iii():
    assert {type(c).TYPE for c in COMMANDS} == COMMAND_TYPES
    assert len(COMMAND_TYPES) == 9
    assert CONFIRMABLE_TYPES == COMMAND_TYPES | {MessageType.POSE_UPDATE, MessageType.DATA}


@pytest.mark.parametrize("message", COMMANDS, ids=lambda m: type(m).__name__)
def test_is_command_true(message):
    assert is_command(message)


@pytest.mark.parametrize("message", [*OTHERS, None, "Stop", Stop], ids=repr)
def test_is_command_false(message):
    assert not is_command(message)


@pytest.mark.parametrize("message", COMMANDS + OTHERS + [P], ids=lambda m: type(m).__name__)
def test_messages_are_frozen_slotted_and_hashable(message):
    assert not hasattr(message, "__dict__")
    hash(message)
    fields = dataclasses.fields(message)
    if fields:
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(message, fields[0].name, 1)
