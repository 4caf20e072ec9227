"""What a run is configured with: the channel kind, timing, the mesh, the protocol's retries.

Owns: SimConfig and RadioKind, plain data a world process and a robot process both read. Must not
know: MuJoCo, Zenoh, how a team is assembled or stepped.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

from rescuemesh.mesh import TEAM_RELAY_RETRANSMIT_COUNT, MeshConfig
from rescuemesh.protocol.reliability import ReliabilityConfig
from rescuemesh.robot import BrainConfig
from rescuemesh.sim.mjcf import MAX_PHYSICS_DT, PHYSICS_DT  # numbers only: mjcf does not import mujoco


class RadioKind(Enum):
    """The channel model a run uses (`--radio`)."""

    BLE = "ble"  # path loss, walls, shadowing, fading on the map (docs/radio.md)
    DISC = "disc"  # the paper's 10 m disc, no walls


#: The defaults of the layers below, which SimConfig's own fields take theirs from (one source each).
_RELIABILITY = ReliabilityConfig()
_TEAM_MESH = MeshConfig(relay_retransmit_count=TEAM_RELAY_RETRANSMIT_COUNT)


@dataclass(frozen=True)
class SimConfig:
    """How to run: timing in s, the radio, the mesh, and the protocol's retry settings.

    `loss`: extra independent per-reception loss on top of the channel. `relay`: every robot has
    the relay feature (False: `--no-relay`); it is written into `mesh.relay`, which a run's mesh
    nodes read (set relay here, not in `mesh`). `radio_params`: channel settings overriding defaults.
    `secure`: authenticated, encrypted frames (False: `--insecure`, CRC frames); `team_key`: the
    team key (None: derived from the seed, for simulation only).

    Each default lives in the layer that uses it: `ack_timeout_s` and `max_sends` are
    ReliabilityConfig's, `relay` is MeshConfig's, the heartbeat period is `mesh.heartbeat_period_s`
    only (the brain reads it from its mesh node), TTLs are `mesh.initial_ttl` and
    `mesh.heartbeat_ttl` (the endpoint is built with them). `mesh` is the team's: MeshConfig with
    Relay Retransmit count TEAM_RELAY_RETRANSMIT_COUNT (2) where a lone node has 0.
    """

    seed: int = 0
    physics_dt: float = PHYSICS_DT
    control_dt: float = 0.05
    loss: float = 0.0
    radio: RadioKind = RadioKind.BLE
    radio_params: dict = field(default_factory=dict)
    relay: bool = _TEAM_MESH.relay
    secure: bool = True
    team_key: bytes | None = None
    ack_timeout_s: float = _RELIABILITY.ack_timeout_s
    max_sends: int = _RELIABILITY.max_sends
    brain: BrainConfig = field(default_factory=BrainConfig)
    kinds: dict = field(default_factory=dict)  # robot name -> RobotKind (default: ground)
    mesh: MeshConfig = _TEAM_MESH

    def __post_init__(self) -> None:
        ratio = self.control_dt / self.physics_dt
        if not 0.0 < self.physics_dt <= MAX_PHYSICS_DT:
            raise ValueError(f"physics step must be in (0, {MAX_PHYSICS_DT}] s, got {self.physics_dt}")
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ValueError(f"control step {self.control_dt} s is not a whole multiple of the physics step")
        if not isinstance(self.relay, bool):
            raise ValueError(f"relay must be a bool, got {self.relay!r}")
        if self.mesh.relay != self.relay:  # one value a run reads: the mesh nodes take it from mesh
            object.__setattr__(self, "mesh", replace(self.mesh, relay=self.relay))
