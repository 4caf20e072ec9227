"""Command priorities and resources: a robot's resources, the sender's rank, priorities, and the
decision whether a new command may preempt a running one (paper IV.A: "checks incoming messages
for command with higher priority"). Each command type's level and resources are in
robot/commands.py. Owns the decision; must not know behaviours, the wire, the clock.
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

from rescuemesh.protocol import Reason


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


#: Priority level of motion commands and of a robot's own missions.
MOTION_LEVEL = 5

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


def conflict(new: Priority, needs: Resource, held: Resource, running: Priority) -> Reason | None:
    """None when a command of priority `new` that needs `needs` (robot/commands.py's resources of its
    type, and any more it needs: a ShowScan that must drive or turn needs motion) may start now (it
    needs nothing that is held, or it outranks what holds it); otherwise the reason to answer
    TEMPORARILY_REJECTED."""
    overlap = needs & held
    if not overlap or new >= running:
        return None
    for resource, reason in HELD_REASON.items():
        if resource in overlap:
            return reason
    return None
