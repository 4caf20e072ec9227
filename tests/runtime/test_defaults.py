"""One source for each default: a run's settings reach the layer that uses them (SimConfig -> the
assembled endpoint, mesh node and brain), and the run's defaults are the lower layers' own."""

from __future__ import annotations

from dataclasses import replace

import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.mesh import MeshConfig
from rescuemesh.protocol.codec import Header, decode_frame
from rescuemesh.protocol.endpoint import EndpointConfig
from rescuemesh.protocol.messages import Heartbeat
from rescuemesh.protocol.reliability import ReliabilityConfig
from rescuemesh.protocol.wire import DEFAULT_TTL
from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.onboard.linked_robot import build_robot

DT = 0.05


def assembled(config: SimConfig):
    _, brain, stack = build_robot("robot_1", Pose2D(0.0, 0.0), config, lambda: 0.0)
    return brain, stack


def heartbeats(config: SimConfig, seconds: float) -> list[tuple[float, Header]]:
    """(time, header) of each Heartbeat robot_1's brain sends alone for `seconds` (CRC frames, to read them)."""
    brain, stack = assembled(replace(config, secure=False))
    sent = []
    for i in range(round(seconds / DT)):
        now = round(i * DT, 9)
        brain.step(now)
        for frame in stack.frames_to_send(now):
            header, message = decode_frame(frame)
            if isinstance(message, Heartbeat):
                sent.append((now, header))
    return sent


def test_the_brain_sends_heartbeats_at_the_mesh_layers_period():
    # this used to be a second field (BrainConfig.heartbeat_period_s) that had to be kept equal by hand
    config = SimConfig(mesh=replace(SimConfig().mesh, heartbeat_period_s=2.0))
    times = [t for t, _ in heartbeats(config, 12.0)]
    gaps = [round(b - a, 6) for a, b in zip(times[1:], times[2:])]  # the first two: at once, then the phase
    assert len(gaps) >= 4
    assert gaps == [2.0] * len(gaps)
    default = [t for t, _ in heartbeats(SimConfig(), 6.0)]
    assert [round(b - a, 6) for a, b in zip(default[1:], default[2:])] == [1.0] * (len(default) - 2)


def test_the_endpoint_originates_with_the_mesh_configs_ttls():
    config = SimConfig(mesh=replace(SimConfig().mesh, initial_ttl=5, heartbeat_ttl=2))
    _, stack = assembled(config)
    assert (stack.endpoint.config.initial_ttl, stack.endpoint.config.heartbeat_ttl) == (5, 2)
    assert stack.node.config.initial_ttl == 5
    _, header = heartbeats(config, 0.1)[0]
    assert header.ttl == 2
    # a lone endpoint and a team's mesh node originate with one default TTL (the protocol's)
    assert MeshConfig().initial_ttl == EndpointConfig().initial_ttl == DEFAULT_TTL


def test_relay_set_on_the_run_reaches_the_mesh_nodes():
    assert SimConfig().relay is SimConfig().mesh.relay is MeshConfig().relay is True
    off = SimConfig(relay=False)
    assert off.mesh.relay is False
    assert assembled(off)[1].node.config.relay is False
    # the other mesh settings stay: only the relay switch is written in
    assert replace(off.mesh, relay=True) == SimConfig().mesh
    assert replace(SimConfig(), relay=False).mesh.relay is False
    assert replace(off, relay=True).mesh.relay is True
    with pytest.raises(ValueError, match="relay must be a bool"):
        SimConfig(relay="no")


def test_the_runs_retry_settings_are_the_protocols_unless_set():
    protocol = ReliabilityConfig()
    assert (SimConfig().ack_timeout_s, SimConfig().max_sends) == (protocol.ack_timeout_s, protocol.max_sends)
    _, stack = assembled(SimConfig(ack_timeout_s=0.4, max_sends=5, secure=False))
    reliability = stack.endpoint.config.reliability
    assert (reliability.ack_timeout_s, reliability.max_sends) == (0.4, 5)
    assert reliability.duplicate_window_s == protocol.duplicate_window_s  # the rest: the protocol's defaults


def test_the_team_mesh_differs_from_a_lone_node_only_in_relay_retransmit():
    """TEAM_RELAY_RETRANSMIT_COUNT (2) against MeshConfig's 0 is on purpose (docs/mesh.md); nothing
    else of a run's mesh is set apart from the mesh layer's defaults."""
    team = SimConfig().mesh
    assert team.relay_retransmit_count == 2 and MeshConfig().relay_retransmit_count == 0
    assert replace(team, relay_retransmit_count=0) == MeshConfig()
