"""The in-process simulation loop: MuJoCo world, simulated radio link and robot brains.

Owns: the clock (simulated seconds), the control step, assembling a team from a map and start
poses, and the trajectory record. Must not know: scenarios' scripts and success criteria.
Each control tick at time t: the world steps to t, the link delivers what is due by t, every
brain steps at t. The control step is a whole multiple of the physics step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel
from rescuemesh.nav import Costmap, NavigateToPose
from rescuemesh.protocol import Endpoint, EndpointConfig, ReliabilityConfig
from rescuemesh.radio import RangeLossChannel
from rescuemesh.robot import BrainConfig, RobotBrain, robot_address
from rescuemesh.sim import World
from rescuemesh.transport import SimRadioLink


@dataclass(frozen=True)
class SimConfig:
    """How to run: timing in s, the radio channel, and the protocol's retry settings."""

    seed: int = 0
    physics_dt: float = 0.005
    control_dt: float = 0.05
    loss: float = 0.0
    latency_s: float = 0.01
    range_m: float = 10.0
    ack_timeout_s: float = 0.15
    max_sends: int = 3
    brain: BrainConfig = field(default_factory=BrainConfig)

    def __post_init__(self) -> None:
        ratio = self.control_dt / self.physics_dt
        if self.physics_dt <= 0 or self.physics_dt > 0.005:
            raise ValueError(f"physics step must be in (0, 0.005] s, got {self.physics_dt}")
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"control step {self.control_dt} s is not a whole multiple of the physics step")


@dataclass(frozen=True, slots=True)
class TrajectorySample:
    time_s: float
    pose: Pose2D
    speed: float  # |v| in m/s from odometry


class SimRuntime:
    """A team of simulated robots on one map, stepped in simulated time."""

    def __init__(self, map_model: MapModel, starts: dict[str, Pose2D], config: SimConfig | None = None) -> None:
        self.config = config or SimConfig()
        self.map = map_model
        rng = np.random.default_rng(self.config.seed)
        radio_rng, world_seed = rng.spawn(1)[0], int(rng.integers(2**31))
        self.world = World(map_model, starts, physics_dt=self.config.physics_dt, seed=world_seed)
        channel = RangeLossChannel(loss=self.config.loss, latency_s=self.config.latency_s, range_m=self.config.range_m)
        self.link = SimRadioLink(channel, radio_rng, record=True)
        reliability = ReliabilityConfig(ack_timeout_s=self.config.ack_timeout_s, max_sends=self.config.max_sends)
        self.costmap = Costmap(map_model.grid)
        self.brains: dict[str, RobotBrain] = {}
        for name in starts:
            body = self.world.bodies[name]
            endpoint = Endpoint(robot_address(name), EndpointConfig(reliability=reliability))
            nav = NavigateToPose(self.costmap)
            self.brains[name] = RobotBrain(name, body, endpoint, nav, self.costmap, self.config.brain)
            self.link.attach(endpoint.address, endpoint, _position_of(body))
        self.time = 0.0
        self.ticks = 0
        self.trajectories: dict[str, list[TrajectorySample]] = {name: [] for name in starts}
        self._record()

    def brain(self, name: str) -> RobotBrain:
        try:
            return self.brains[name]
        except KeyError:
            raise ValueError(f"unknown robot {name!r}; this team has {', '.join(self.brains)}") from None

    def step(self, script: Callable[["SimRuntime"], None] | None = None) -> None:
        """One control step: physics, radio, brains, then `script` (a mission), then transmit."""
        self.ticks += 1
        now = round(self.ticks * self.config.control_dt, 9)  # no 0.30000000000000004 in the logs
        self.world.step_to(now)
        self.time = now
        self.link.pump(now)
        for brain in self.brains.values():
            brain.step(now)
        if script is not None:
            script(self)
        self.link.flush(now)  # what the brains sent leaves now, not at the next tick
        self._record()

    def _record(self) -> None:
        for name, body in self.world.bodies.items():
            _, v, _ = body.odometry()
            self.trajectories[name].append(TrajectorySample(self.time, body.pose(), abs(v)))


def _position_of(body):
    def position() -> tuple[float, float]:
        pose = body.pose()
        return (pose.x, pose.y)

    return position
