"""Navigation: costmap, global planners, regulated pure pursuit and the NavigateToPose action.

Owns: everything between (occupancy grid, pose, scan, goal) and a velocity command (v m/s, omega rad/s).
Must not know: MuJoCo, rescuemesh.sim, rescuemesh.robot, rescuemesh.protocol, or the wall clock.
"""

from rescuemesh.nav.controller import ControllerParams, compute_velocity, limit_acceleration, rotate_toward
from rescuemesh.nav.costmap import LETHAL, Costmap
from rescuemesh.nav.navigate import GoalStatus, NavFeedback, NavigateToPose, NavParams, NavReason, NavResult
from rescuemesh.nav.path import Path
from rescuemesh.nav.planner import PLANNERS, MCPPlanner, Planner, StraightLinePlanner, make_planner, register_planner

__all__ = [
    "LETHAL",
    "PLANNERS",
    "ControllerParams",
    "Costmap",
    "GoalStatus",
    "MCPPlanner",
    "NavFeedback",
    "NavParams",
    "NavReason",
    "NavResult",
    "NavigateToPose",
    "Path",
    "Planner",
    "StraightLinePlanner",
    "compute_velocity",
    "limit_acceleration",
    "make_planner",
    "register_planner",
    "rotate_toward",
]
