"""The in-process simulation loop: MuJoCo world, simulated radio medium and robot brains.

Owns: the clock (simulated seconds), the control step, assembling a team (body, endpoint, mesh
node, brain per robot) from a map and start poses, and the trajectory record. Must not know:
scenarios' scripts and success criteria. Each control tick at time t: the world steps to t, the
medium delivers what is due by t, every brain steps at t. The control step is a whole multiple
of the physics step.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel
from rescuemesh.mesh import NetworkStack
from rescuemesh.nav import Costmap
from rescuemesh.radio import make_channel
from rescuemesh.robot import RobotBrain, robot_address
from rescuemesh.robot.records import power_on_s
from rescuemesh.runtime.assembly import assemble_robot, team_sealer
from rescuemesh.runtime.config import RadioKind, SimConfig  # noqa: F401  (RadioKind: re-exported)
from rescuemesh.sim import World
from rescuemesh.transport.sim_medium import SimMedium


@dataclass(frozen=True, slots=True)
class TrajectorySample:
    time_s: float
    pose: Pose2D
    speed: float  # |v| in m/s from odometry


class SimRuntime:
    """A team of simulated robots on one map, stepped in simulated time."""

    #: The radio medium's class (a world with robot processes delivers each frame to all at once).
    medium_class = SimMedium

    def __init__(self, map_model: MapModel, starts: dict[str, Pose2D], config: SimConfig | None = None) -> None:
        self.config = config or SimConfig()
        self.map = map_model
        config = self.config
        rng = np.random.default_rng(config.seed)
        radio_seed, world_seed = int(rng.integers(2**63)), int(rng.integers(2**31))
        self.world = World(map_model, starts, physics_dt=config.physics_dt, seed=world_seed, kinds=config.kinds)
        self.channel = make_channel(config.radio.value, grid=map_model.grid, seed=radio_seed, **config.radio_params)
        self.medium = self.medium_class(self.channel, radio_seed, extra_loss=config.loss, record=True)
        self.brains: dict[str, RobotBrain] = {}
        self.stacks: dict[str, NetworkStack] = {}
        self._make_team(starts)
        #: Robots not switched on yet (BrainConfig.power_on_spread_s): address -> power-on time, s.
        #: Their radios stay off until then (their brains do nothing until then either).
        self._powering_on = {}
        for name in starts:
            at = power_on_s(robot_address(name), config.brain.power_on_spread_s)
            # switched on at `at`, its control loop ticks at `at` + k * control_dt, not on the world's
            self.medium.set_loop_phase(robot_address(name), at % config.control_dt)
            if at > 0.0:
                self._powering_on[robot_address(name)] = at
                self.medium.set_radio_enabled(robot_address(name), False, 0.0)
        #: Wall time in s spent in the world (physics and sensors), the medium, and the robots
        #: (brains, or the round trips to robot processes), over the run's steps.
        self.wall_s = {"world": 0.0, "medium": 0.0, "robots": 0.0}
        self.time = 0.0
        self.ticks = 0
        self.trajectories: dict[str, list[TrajectorySample]] = {name: [] for name in starts}
        self._record()

    def _make_team(self, starts: dict[str, Pose2D]) -> None:
        """Each robot's brain and stack, here in this process, its radio on the medium."""
        self.sealer = team_sealer(self.config)
        self.costmap = Costmap(self.map.grid)
        for name in starts:
            body = self.world.bodies[name]
            base = self.map.bases.get(name, starts[name])  # where Return goes: the map's base, else the start
            self.brains[name], stack = assemble_robot(name, body, self.costmap, self.config, self.sealer, base)
            self.stacks[name] = stack
            self.medium.attach(robot_address(name), stack, _position_of(body))

    def _step_robots(self, now: float) -> None:
        for brain in self.brains.values():
            brain.step(now)

    def _collect_robots(self, now: float) -> None:
        """Before the medium takes what the stacks send: nothing to do when the robots are here."""

    def brain(self, name: str) -> RobotBrain:
        try:
            return self.brains[name]
        except KeyError:
            raise ValueError(f"unknown robot {name!r}; this team has {', '.join(self.brains)}") from None

    def set_radio(self, name: str, enabled: bool) -> None:
        """Switch robot `name`'s radio off (it neither sends nor hears) or back on, now."""
        self.brain(name)  # an unknown name: ValueError naming the team
        self.medium.set_radio_enabled(robot_address(name), enabled, self.time)

    def step(self, script: Callable[["SimRuntime"], None] | None = None) -> None:
        """One control step: physics, radio, brains, then `script` (a mission), then transmit."""
        self.ticks += 1
        now = round(self.ticks * self.config.control_dt, 9)  # no 0.30000000000000004 in the logs
        wall = self.wall_s
        t0 = time.perf_counter()
        self.world.step_to(now)
        t1 = time.perf_counter()
        self.time = now
        if self._powering_on:
            self._power_on(now)
        self.medium.pump(now, collect=False)  # the last step flushed after its brains and script
        t2 = time.perf_counter()
        self._step_robots(now)
        t3 = time.perf_counter()
        if script is not None:
            script(self)
        self._collect_robots(now)
        t4 = time.perf_counter()
        self.medium.flush(now)  # what the brains sent leaves now, not at the next tick
        t5 = time.perf_counter()
        self._record()
        wall["world"] += t1 - t0
        wall["medium"] += t2 - t1 + t5 - t4
        wall["robots"] += t3 - t2

    def powered_on(self, name: str) -> bool:
        """Whether robot `name` has been switched on (BrainConfig.power_on_spread_s)."""
        return robot_address(name) not in self._powering_on

    def _power_on(self, now: float) -> None:
        for address, at in list(self._powering_on.items()):
            if now >= at:
                del self._powering_on[address]
                self.medium.set_radio_enabled(address, True, now)

    def _record(self) -> None:
        for name, body in self.world.bodies.items():
            _, v, _ = body.odometry()
            self.trajectories[name].append(TrajectorySample(self.time, body.pose(), abs(v)))


def _position_of(body):
    def position() -> tuple[float, float]:
        pose = body.pose()
        return (pose.x, pose.y)

    return position
