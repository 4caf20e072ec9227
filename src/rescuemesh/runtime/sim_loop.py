"""The in-process simulation loop: MuJoCo world, simulated radio medium and robot brains.

Owns: the clock (simulated seconds), the control step, assembling a team (body, endpoint, mesh
node, brain per robot) from a map and start poses, and the trajectory record. Must not know:
scenarios' scripts and success criteria. Each control tick at time t: the world steps to t, the
medium delivers what is due by t, every brain steps at t. The control step is a whole multiple
of the physics step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel
from rescuemesh.mesh import TEAM_RELAY_RETRANSMIT_COUNT, MeshConfig, MeshNode, NetworkStack
from rescuemesh.mesh.keys import team_key_from_seed
from rescuemesh.mesh.replay import DUPLICATE_MEMORY
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.nav import Costmap, NavigateToPose
from rescuemesh.protocol import Endpoint, EndpointConfig, ReliabilityConfig
from rescuemesh.radio import make_channel
from rescuemesh.robot import BrainConfig, RobotBrain, robot_address
from rescuemesh.sim import World
from rescuemesh.transport import SimMedium


class RadioKind(Enum):
    """The channel model a run uses (`--radio`)."""

    BLE = "ble"  # path loss, walls, shadowing, fading on the map (docs/radio.md)
    DISC = "disc"  # the paper's 10 m disc, no walls


@dataclass(frozen=True)
class SimConfig:
    """How to run: timing in s, the radio, the mesh, and the protocol's retry settings.

    `loss`: extra independent per-reception loss on top of the channel. `relay`: every robot has
    the relay feature (False: `--no-relay`). `radio_params`: channel settings overriding defaults.
    `secure`: authenticated, encrypted frames (False: `--insecure`, CRC frames); `team_key`: the
    team key (None: derived from the seed, for simulation only).
    """

    seed: int = 0
    physics_dt: float = 0.005
    control_dt: float = 0.05
    loss: float = 0.0
    radio: RadioKind = RadioKind.BLE
    radio_params: dict = field(default_factory=dict)
    relay: bool = True
    secure: bool = True
    team_key: bytes | None = None
    ack_timeout_s: float = 0.15
    max_sends: int = 3
    brain: BrainConfig = field(default_factory=BrainConfig)
    kinds: dict = field(default_factory=dict)  # robot name -> RobotKind (default: ground)
    mesh: MeshConfig = field(default_factory=lambda: MeshConfig(relay_retransmit_count=TEAM_RELAY_RETRANSMIT_COUNT))

    def __post_init__(self) -> None:
        ratio = self.control_dt / self.physics_dt
        if self.physics_dt <= 0 or self.physics_dt > 0.005:
            raise ValueError(f"physics step must be in (0, 0.005] s, got {self.physics_dt}")
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"control step {self.control_dt} s is not a whole multiple of the physics step")
        if self.brain.heartbeat_period_s != self.mesh.heartbeat_period_s:
            raise ValueError("the brain's and the mesh layer's heartbeat periods differ")


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
        config = self.config
        rng = np.random.default_rng(config.seed)
        radio_seed, world_seed = int(rng.integers(2**63)), int(rng.integers(2**31))
        self.world = World(map_model, starts, physics_dt=config.physics_dt, seed=world_seed, kinds=config.kinds)
        self.channel = make_channel(config.radio.value, grid=map_model.grid, seed=radio_seed, **config.radio_params)
        self.medium = SimMedium(self.channel, radio_seed, extra_loss=config.loss, record=True)
        reliability = ReliabilityConfig(ack_timeout_s=config.ack_timeout_s, max_sends=config.max_sends)
        self.sealer = None
        if config.secure:
            key = config.team_key if config.team_key is not None else team_key_from_seed(config.seed)
            self.sealer = FrameSealer.from_team_key(key)
            # replay protection decides what is new; the duplicate cache must remember as many commands
            reliability = replace(reliability, duplicate_window_s=float("inf"), duplicate_cache_size=DUPLICATE_MEMORY)
        mesh = replace(config.mesh, relay=config.relay)
        self.costmap = Costmap(map_model.grid)
        self.brains: dict[str, RobotBrain] = {}
        self.stacks: dict[str, NetworkStack] = {}
        for name in starts:
            body = self.world.bodies[name]
            address = robot_address(name)
            endpoint = Endpoint(address, EndpointConfig(reliability=reliability, initial_ttl=mesh.initial_ttl,
                                                        heartbeat_ttl=mesh.heartbeat_ttl))
            stack = self.stacks[name] = NetworkStack(endpoint, MeshNode(address, mesh, self.sealer))
            nav = NavigateToPose(self.costmap)
            brain_config = config.brain if config.brain.base is not None else replace(config.brain, base=starts[name])
            self.brains[name] = RobotBrain(name, body, stack, nav, self.costmap, brain_config)
            self.medium.attach(address, stack, _position_of(body))
        self.time = 0.0
        self.ticks = 0
        self.trajectories: dict[str, list[TrajectorySample]] = {name: [] for name in starts}
        self._record()

    def brain(self, name: str) -> RobotBrain:
        try:
            return self.brains[name]
        except KeyError:
            raise ValueError(f"unknown robot {name!r}; this team has {', '.join(self.brains)}") from None

    def set_radio(self, name: str, enabled: bool) -> None:
        """Switch robot `name`'s radio off (it neither sends nor hears) or back on, now."""
        self.medium.set_radio_enabled(robot_address(self.brain(name).name), enabled, self.time)

    def step(self, script: Callable[["SimRuntime"], None] | None = None) -> None:
        """One control step: physics, radio, brains, then `script` (a mission), then transmit."""
        self.ticks += 1
        now = round(self.ticks * self.config.control_dt, 9)  # no 0.30000000000000004 in the logs
        self.world.step_to(now)
        self.time = now
        self.medium.pump(now)
        for brain in self.brains.values():
            brain.step(now)
        if script is not None:
            script(self)
        self.medium.flush(now)  # what the brains sent leaves now, not at the next tick
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
