"""Network benchmarks in simulated time: confirm latency over a chain of relays, and command
delivery ratio on a lossy link with and without relays (`rescuemesh bench`).

Owns: the bench harnesses (real endpoints, mesh nodes and the simulated medium; no robots, no
physics). Must not know: scenarios, plots. Receivers confirm a command the moment it arrives, so
the figures measure the protocol, the mesh and the air, not a robot's 50 ms control tick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rescuemesh.mesh import TEAM_RELAY_RETRANSMIT_COUNT, MeshConfig, MeshNode, NetworkStack
from rescuemesh.mesh.keys import team_key_from_seed
from rescuemesh.mesh.security import FrameSealer
from rescuemesh.protocol import CommandReceived, ConfirmReceived, Endpoint, EndpointConfig, ResultCode, Stop
from rescuemesh.radio import DiscChannel
from rescuemesh.transport.sim_medium import SimMedium

#: Harness step in s: receivers answer within this of a command's arrival.
STEP_S = 0.001
#: Chain spacing in m with the 10 m disc: each node hears only its two neighbours.
CHAIN_SPACING_M = 8.0


@dataclass(frozen=True)
class LatencyFigures:
    hops: int
    trials: int
    confirmed: int
    p50_ms: float
    p95_ms: float
    mean_ms: float


def _team(positions: list[tuple[float, float]], seed: int, *, extra_loss: float = 0.0, relay: bool = True):
    """Robots on a 10 m disc, with authenticated frames as the simulated team has them."""
    medium = SimMedium(DiscChannel(), seed, extra_loss=extra_loss)
    sealer = FrameSealer.from_team_key(team_key_from_seed(seed))
    stacks = []
    for address, xy in enumerate(positions, start=1):
        config = MeshConfig(relay=relay, relay_retransmit_count=TEAM_RELAY_RETRANSMIT_COUNT)
        endpoint = Endpoint(address, EndpointConfig(initial_ttl=config.initial_ttl))
        stack = NetworkStack(endpoint, MeshNode(address, config, sealer))
        medium.attach(address, stack, lambda xy=xy: xy)
        stacks.append(stack)
    return medium, stacks


def _exchange(medium: SimMedium, stacks: list[NetworkStack], t0: float, limit_s: float) -> float | None:
    """robot 1 sends Stop to the last robot at t0; returns the time of the solicited Confirm, or None."""
    sender, receiver = stacks[0].endpoint, stacks[-1].endpoint
    seq = sender.send_command(receiver.address, Stop(), t0)
    medium.flush(t0)
    t = t0
    while t < t0 + limit_s:
        t = round(t + STEP_S, 9)
        medium.pump(t)
        while (event := receiver.next_event()) is not None:
            if isinstance(event, CommandReceived):
                receiver.confirm(event.src, event.seq, event.command.TYPE, ResultCode.DONE, t)
        answered = None
        while (event := sender.next_event()) is not None:
            if isinstance(event, ConfirmReceived) and event.ref_seq == seq and event.solicited:
                answered = event.now
        for stack in stacks[1:-1]:
            while stack.endpoint.next_event() is not None:
                pass
        medium.flush(t)
        if answered is not None:
            return answered
    sender.cancel_pending()
    return None


def _warm_up(medium: SimMedium, stacks: list[NetworkStack], until_s: float) -> float:
    """Heartbeats from everyone, a few rounds (some are lost), so that every node knows every other's
    hop count and epoch, as a team does after a few seconds."""
    t = 0.0
    for _ in range(8):
        for stack in stacks:
            stack.endpoint.send_heartbeat(t)
            medium.flush(t)
            t = round(t + 0.05, 9)
            medium.pump(t)
    medium.pump(max(until_s, t))
    for stack in stacks:
        while stack.endpoint.next_event() is not None:
            pass
    return until_s


def chain_confirm_latency(hops: int, trials: int = 100, seed: int = 0) -> LatencyFigures:
    """Round trip of a command and its Confirm across `hops` radio hops (hops - 1 relays)."""
    if hops < 1:
        raise ValueError(f"hops must be >= 1, got {hops}")
    medium, stacks = _team([(CHAIN_SPACING_M * i, 0.0) for i in range(hops + 1)], seed)
    t = _warm_up(medium, stacks, 3.0)
    rtts = []
    for _ in range(trials):
        answered = _exchange(medium, stacks, t, 3.0)
        if answered is not None:
            rtts.append(answered - t)
        t = round(t + 3.0, 9)
        medium.pump(t)
    ms = np.array(rtts) * 1000.0
    return LatencyFigures(hops, trials, len(rtts), *(round(float(v), 1) for v in (
        np.percentile(ms, 50) if len(ms) else np.nan, np.percentile(ms, 95) if len(ms) else np.nan,
        ms.mean() if len(ms) else np.nan)))


def delivery_ratio(relays: int, *, extra_loss: float = 0.3, trials: int = 1000, window_s: float = 2.0,
                   seed: int = 0) -> float:
    """Fraction of commands confirmed within `window_s` s when every reception is lost with
    probability `extra_loss`, directly (relays = 0) or with `relays` relays that hear both ends."""
    positions = [(0.0, 0.0), (6.0, 0.0)] + [(3.0, 2.0 + 1.0 * k) for k in range(relays)]
    medium, stacks = _team(positions, seed, extra_loss=extra_loss)
    ordered = [stacks[0], *stacks[2:], stacks[1]]  # sender first, receiver last
    t = _warm_up(medium, ordered, 3.0)
    confirmed = 0
    for _ in range(trials):
        if _exchange(medium, ordered, t, window_s) is not None:
            confirmed += 1
        t = round(t + window_s + 0.5, 9)
        medium.pump(t)
    return confirmed / trials
