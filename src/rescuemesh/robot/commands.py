"""What each command type obliges, in one table: its priority level, the resources it needs,
whether its sender streams PoseUpdates to the receiver, whether the receiver reports IN_PROGRESS,
whether it moves the receiver, and the brain's handler for it.

Owns: the table (COMMANDS, keyed by MessageType) and the lookups on it. Must not know: how the
brain runs a command (robot/brain.py), how a conflict is decided (robot/policy.py), the wire.
"""

from __future__ import annotations

from dataclasses import dataclass

from rescuemesh.protocol import MessageType
from rescuemesh.robot.policy import MOTION_LEVEL, Priority, Rank, Resource


@dataclass(frozen=True, slots=True)
class CommandTraits:
    """One command type's row. `level`: priority within a rank (0..9); `streamed`: the sender
    streams its pose (PoseUpdates) to the receiver until it ends; `reports_progress`: the receiver
    reports IN_PROGRESS with a percentage while it runs it (and a forwarder waits for its final
    result); `motion`: it moves the receiver (when it is given up unconfirmed, the sender sends Stop
    in case it runs); `handler`: the name of the RobotBrain method that answers it."""

    level: int
    resources: Resource
    handler: str
    streamed: bool = False
    reports_progress: bool = False
    motion: bool = False


_MOTION = dict(level=MOTION_LEVEL, resources=Resource.MOTION, motion=True)

#: Every command of paper Table III.
COMMANDS: dict[MessageType, CommandTraits] = {
    MessageType.FOLLOW: CommandTraits(**_MOTION, handler="_on_follow", streamed=True),
    MessageType.GOTO: CommandTraits(**_MOTION, handler="_on_goto", reports_progress=True),
    MessageType.RETURN: CommandTraits(**_MOTION, handler="_on_return", reports_progress=True),
    MessageType.MOVE_AROUND: CommandTraits(**_MOTION, handler="_on_move_around", reports_progress=True),
    MessageType.LAND_ON_TOP: CommandTraits(**_MOTION, handler="_on_land_on_top", streamed=True,
                                           reports_progress=True),
    MessageType.SHOW_SCAN: CommandTraits(3, Resource.LASER, "_on_show", reports_progress=True),
    MessageType.SHOW_CAM: CommandTraits(3, Resource.CAMERA, "_on_show", reports_progress=True),
    MessageType.STOP: CommandTraits(9, Resource.NONE, "_on_stop"),
    MessageType.FORWARD_MSG: CommandTraits(0, Resource.NONE, "_on_forward"),
}

_NONE = CommandTraits(0, Resource.NONE, "_on_unsupported")


def traits(msg_type: MessageType | None) -> CommandTraits:
    """The row of `msg_type`; for anything that is not a command (None, PoseUpdate, Data): a row
    that obliges nothing."""
    return COMMANDS.get(msg_type, _NONE)


def priority_of(msg_type: MessageType, rank: Rank) -> Priority:
    return Priority(rank, COMMANDS[msg_type].level)


def resources_of(msg_type: MessageType) -> Resource:
    return COMMANDS[msg_type].resources
