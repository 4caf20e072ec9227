"""A tiny two-or-three robot team for brain tests: unicycle bodies, real nav and protocol, no MuJoCo."""

from __future__ import annotations

import math

import numpy as np

from rescuemesh.body import Body
from rescuemesh.geometry import Pose2D, wrap_angle
from rescuemesh.maps import OccupancyGrid
from rescuemesh.nav import Costmap, NavigateToPose
from rescuemesh.mesh import MeshNode, NetworkStack
from rescuemesh.protocol import Endpoint
from rescuemesh.radio import DiscChannel
from rescuemesh.robot import RobotBrain, robot_address
from rescuemesh.transport.sim_medium import SimMedium

DT = 0.05


class UnicycleBody(Body):
    """Integrates (v, omega) exactly as commanded; can be teleported to test the radio range."""

    max_linear_speed, max_angular_speed, radius = 0.7, math.pi, 0.177

    def __init__(self, name: str, pose: Pose2D) -> None:
        self.name, self._pose, self.command = name, pose, (0.0, 0.0)

    def pose(self):
        return self._pose

    def odometry(self):
        return self._pose, self.command[0], self.command[1]

    def scan(self):
        return None

    def set_velocity(self, linear, angular):
        self.command = (max(-0.7, min(0.7, linear)), max(-math.pi, min(math.pi, angular)))

    def advance(self, dt: float) -> None:
        v, w = self.command
        p = self._pose
        self._pose = Pose2D(p.x + v * math.cos(p.yaw) * dt, p.y + v * math.sin(p.yaw) * dt, wrap_angle(p.yaw + w * dt))

    def teleport(self, pose: Pose2D) -> None:
        self._pose = pose


def open_room(size_m: float = 12.0, resolution: float = 0.05) -> OccupancyGrid:
    cells = int(size_m / resolution)
    occupied = np.zeros((cells, cells), dtype=bool)
    occupied[0, :] = occupied[-1, :] = occupied[:, 0] = occupied[:, -1] = True
    return OccupancyGrid(occupied, resolution, 0.0, 0.0)


class Team:
    """Robots with the real endpoint, mesh node and brain over the simulated medium (disc radio,
    10 m: teleport a body away to cut it off)."""

    def __init__(self, starts: dict[str, Pose2D], loss: float = 0.0, seed: int = 0) -> None:
        self.costmap = Costmap(open_room())
        self.link = SimMedium(DiscChannel(), seed, extra_loss=loss, record=True)
        self.bodies, self.brains, self.time = {}, {}, 0.0
        for name, pose in starts.items():
            body = UnicycleBody(name, pose)
            address = robot_address(name)
            stack = NetworkStack(Endpoint(address), MeshNode(address))
            self.bodies[name] = body
            self.brains[name] = RobotBrain(name, body, stack, NavigateToPose(self.costmap), self.costmap)
            self.link.attach(address, stack, lambda b=body: (b.pose().x, b.pose().y))

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds / DT)):
            self.time = round(self.time + DT, 9)
            for body in self.bodies.values():
                body.advance(DT)
            self.link.pump(self.time)
            for brain in self.brains.values():
                brain.step(self.time)
            self.link.flush(self.time)

    def kinds(self, name: str) -> list[type]:
        """The types of the events in `name`'s log (robot/events.py), in order."""
        return [type(e) for e in self.brains[name].log]
