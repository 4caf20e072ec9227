"""The robot's brain: a command handler that turns protocol events into behaviours.

Owns: RobotBrain and its records, behaviours (follow, move-around, navigate), robot naming. Must not know: the
simulator (it talks to a `rescuemesh.body.Body`), the transport, the clock (it is handed `now`).
"""

from rescuemesh.robot.brain import RobotBrain
from rescuemesh.robot.events import BrainEvent, BrainEventKind
from rescuemesh.robot.records import BrainConfig, FinishedBehaviour
from rescuemesh.robot.naming import robot_address, robot_name

__all__ = ["BrainConfig", "BrainEvent", "BrainEventKind", "FinishedBehaviour", "RobotBrain", "robot_address",
           "robot_name"]
