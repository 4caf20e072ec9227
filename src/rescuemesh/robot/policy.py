"""Command priorities and resources as data: which resources each command needs, its default
priority, and the sender's rank (paper IV.A: "checks incoming messages for command with higher
priority"). Owns the tables and the decision; must not know behaviours, the wire, the clock.
"""

# Theory of operation
# ===================
#
# A robot's resources are its motion and each of its sensors. Every command type has a default
# priority level and the resources it needs (COMMAND_POLICY, a table keyed by message type).
# A command's priority is (sender's rank, level): an operator station outranks a team lead, who
# outranks a peer, whatever the level; within one rank the level decides. A robot's own mission
# (navigate_to) runs at the robot's own rank and the motion level.
#
# A new command that needs a resource held by a running command:
#
#   new priority <  running priority -> TEMPORARILY_REJECTED, with the resource that is held
#   new priority >= running priority -> it preempts: the running command ends CANCELLED
#                                       (reason REPLACED, reported to its own sender)
#
# Stop needs no priority: it always wins (paper IV.B: "stop running any command").

from __future__ import annotations

import enum
from dataclasses import dataclass

from rescuemesh.protocol import MessageType, Reason


class Resource(enum.Flag):
    NONE = 0
    MOTION = enum.auto()
    CAMERA = enum.auto()
    LASER = enum.auto()


class Rank(enum.IntEnum):
    """Who sends a command: set per robot address in a team file or a scenario."""

    PEER = 0
    TEAM_LEAD = 1
    OPERATOR = 2


@dataclass(frozen=True, slots=True)
class CommandPolicy:
    level: int  # priority within a rank, 0..9
    resources: Resource


#: Priority level of motion commands and of a robot's own missions.
MOTION_LEVEL = 5

COMMAND_POLICY: dict[MessageType, CommandPolicy] = {
    MessageType.FOLLOW: CommandPolicy(MOTION_LEVEL, Resource.MOTION),
    MessageType.GOTO: CommandPolicy(MOTION_LEVEL, Resource.MOTION),
    MessageType.RETURN: CommandPolicy(MOTION_LEVEL, Resource.MOTION),
    MessageType.MOVE_AROUND: CommandPolicy(MOTION_LEVEL, Resource.MOTION),
    MessageType.LAND_ON_TOP: CommandPolicy(MOTION_LEVEL, Resource.MOTION),
    MessageType.SHOW_SCAN: CommandPolicy(3, Resource.LASER),
    MessageType.SHOW_CAM: CommandPolicy(3, Resource.CAMERA),
    MessageType.STOP: CommandPolicy(9, Resource.NONE),
    MessageType.FORWARD_MSG: CommandPolicy(0, Resource.NONE),
}

#: The reason a TEMPORARILY_REJECTED answer gives, by the resource that is held.
HELD_REASON: dict[Resource, Reason] = {
    Resource.MOTION: Reason.MOTION_HELD,
    Resource.CAMERA: Reason.CAMERA_HELD,
    Resource.LASER: Reason.LASER_HELD,
}


@dataclass(frozen=True, slots=True)
class Priority:
    """Comparable: rank first, then level."""

    rank: Rank
    level: int

    def __lt__(self, other: Priority) -> bool:
        return (self.rank, self.level) < (other.rank, other.level)

    def __ge__(self, other: Priority) -> bool:
        return not self < other


def priority_of(msg_type: MessageType, rank: Rank) -> Priority:
    return Priority(rank, COMMAND_POLICY[msg_type].level)


def resources_of(msg_type: MessageType) -> Resource:
    return COMMAND_POLICY[msg_type].resources


def conflict(new_type: MessageType, new_rank: Rank, held: Resource, running: Priority,
             also_needs: Resource = Resource.NONE) -> Reason | None:
    """None when a command of `new_type` from a sender of `new_rank` may start now (it needs nothing
    that is held, or it outranks what holds it); otherwise the reason to answer TEMPORARILY_REJECTED.
    `also_needs`: resources beyond the table's (a ShowScan that must drive or turn needs motion)."""
    overlap = (resources_of(new_type) | also_needs) & held
    if not overlap or priority_of(new_type, new_rank) >= running:
        return None
    for resource, reason in HELD_REASON.items():
        if resource in overlap:
            return reason
    return None
