"""Assembling one robot's software from a run's settings: endpoint, mesh node, network stack,
navigation and brain on a given Body.

Owns: the one recipe every runtime uses (one process, a robot process, a ROS 1 robot), so that a
robot is the same software wherever it runs. Must not know: MuJoCo, Zenoh, rospy, the world.
"""

from __future__ import annotations

from dataclasses import replace

from rescuemesh.body import Body
from rescuemesh.geometry import Pose2D
from rescuemesh.mesh import MeshNode, NetworkStack
from rescuemesh.mesh.keys import team_key_from_seed
from rescuemesh.mesh.replay import DUPLICATE_MEMORY
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.nav import Costmap, NavigateToPose
from rescuemesh.protocol import Endpoint, EndpointConfig, ReliabilityConfig
from rescuemesh.robot import RobotBrain, robot_address
from rescuemesh.runtime.config import SimConfig


#: Seal and open results the team's shared sealer keeps: a frame's copies are all heard within
#: about 0.1 s, when a 30-robot team puts some 35 frames on the air.
TEAM_SEALER_MEMORY = 1024


def team_sealer(config: SimConfig) -> FrameSealer | None:
    """The team's frame sealer (None with `--insecure`); the key derives from the seed when none is given."""
    if not config.secure:
        return None
    key = config.team_key if config.team_key is not None else team_key_from_seed(config.seed)
    return FrameSealer.from_team_key(key, remember=TEAM_SEALER_MEMORY)


def reliability_for(config: SimConfig) -> ReliabilityConfig:
    reliability = ReliabilityConfig(ack_timeout_s=config.ack_timeout_s, max_sends=config.max_sends)
    if config.secure:
        # replay protection decides what is new; the duplicate cache must remember as many commands
        reliability = replace(reliability, duplicate_window_s=float("inf"), duplicate_cache_size=DUPLICATE_MEMORY)
    return reliability


def assemble_robot(name: str, body: Body, costmap: Costmap, config: SimConfig, sealer: FrameSealer | None,
                   start: Pose2D, *, epoch: int = 0) -> tuple[RobotBrain, NetworkStack]:
    """Robot `name`'s brain and network stack on `body`. `start` is where Return goes unless the
    brain config names a base; `epoch` is the endpoint's boot counter (a restarted robot counts up)."""
    address = robot_address(name)
    mesh = config.mesh  # carries config.relay (SimConfig writes it in)
    endpoint = Endpoint(address, EndpointConfig(reliability=reliability_for(config), initial_ttl=mesh.initial_ttl,
                                                heartbeat_ttl=mesh.heartbeat_ttl, initial_epoch=epoch,
                                                announce_epoch_on_resend=sealer is not None))
    stack = NetworkStack(endpoint, MeshNode(address, mesh, sealer))
    brain_config = config.brain if config.brain.base is not None else replace(config.brain, base=start)
    return RobotBrain(name, body, stack, NavigateToPose(costmap), costmap, brain_config), stack
