"""What ble-check measures and reports: why a frame left a stack, each frame heard with its
latency (matched to its send by bytes), percentiles, and the report with its summary lines.

Owns: FrameLog, FrameSample, percentile, BleCheckReport. Must not know: bearers, asyncio,
the check's script (checks/ble_check.py runs it and fills the report).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from rescuemesh.transport.asyncio_pump import Cause
from typing import Any


# --- measurement -----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class FrameSample:
    """One frame heard by one robot: sent by `src` at `sent_s`, handed to robot `dst`'s stack
    `latency_s` later. `cause`: why the stack sent it (TIMER: for an Endpoint a resend; for a mesh
    stack also a delayed relay or a Heartbeat). `repeat`: `src` had sent the same bytes before (a
    cached Confirm sent again)."""

    src: int
    dst: int
    sent_s: float
    latency_s: float
    cause: Cause
    repeat: bool

    @property
    def resent(self) -> bool:
        """Not a first send, as far as the pump can tell without reading the frame."""
        return self.cause is Cause.TIMER or self.repeat


class FrameLog:
    """Matches receptions to sends by frame bytes: a reception counts against the latest send of the
    same bytes by another robot, once per (send, receiver). The radio is a broadcast medium, so every
    robot in range hears every frame; each one is a sample (a unicast frame's destination hears it
    at the same moment as the bystanders, and relays will need them)."""

    def __init__(self) -> None:
        self.sends: dict[bytes, list[tuple[int, float, Cause, bool]]] = {}  # (src, sent_s, cause, repeat)
        self.samples: list[FrameSample] = []
        self.frames_sent = 0
        self.frames_received = 0
        self.unmatched = 0  # heard, but no robot here sent those bytes (another node on the air)
        self._counted: set[tuple[int, int, float]] = set()

    def sent(self, src: int, frame: bytes, now: float, cause: Cause) -> None:
        self.frames_sent += 1
        history = self.sends.setdefault(frame, [])
        repeat = any(entry[0] == src for entry in history)
        history.append((src, now, cause, repeat))

    def received(self, dst: int, frame: bytes, now: float) -> None:
        self.frames_received += 1
        candidates = [entry for entry in self.sends.get(frame, ()) if entry[0] != dst and entry[1] <= now]
        if not candidates:
            self.unmatched += 1
            return
        src, sent_s, cause, repeat = max(candidates, key=lambda entry: entry[1])
        key = (dst, src, sent_s)
        if key in self._counted:
            return
        self._counted.add(key)
        self.samples.append(FrameSample(src, dst, sent_s, now - sent_s, cause, repeat))


def percentile(values: Sequence[float], q: float) -> float:
    """The q-th percentile (0..100) with linear interpolation between ranks; NaN when empty."""
    if not values:
        return math.nan
    ordered = sorted(values)
    rank = (len(ordered) - 1) * q / 100.0
    low = math.floor(rank)
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (rank - low)


# --- the report ------------------------------------------------------------------------------------


@dataclass
class BleCheckReport:
    """What one ble-check run measured. Times in ms unless named _s; NaN where nothing was measured."""

    controllers: str
    robots: int
    passed: bool = False
    failure: str | None = None
    authenticated: bool = False  # frames sealed under a team key (AES-CCM), as a robot's are
    warm_up_s: float = 0.0  # until the leader had heard every follower's Heartbeat
    commands_sent: int = 0
    commands_confirmed: int = 0
    pose_updates_sent: int = 0
    pose_updates_confirmed: int = 0
    frame_latency_p50_ms: float = math.nan
    frame_latency_p95_ms: float = math.nan
    frame_latency_max_ms: float = math.nan
    latency_samples: int = 0
    resent_samples: int = 0
    confirm_rtt_p50_ms: float = math.nan
    confirm_rtt_p95_ms: float = math.nan
    confirm_rtt_max_ms: float = math.nan
    frames_sent: int = 0  # handed to the bearers by the stacks
    frames_advertised: int = 0  # put on air (frames still queued at the end never fly)
    frames_received: int = 0  # handed to the stacks by the bearers (a repeat the bearer missed included)
    receptions: int = 0  # distinct (transmission, other robot) pairs heard = latency_samples
    receptions_expected: int = 0  # frames_advertised x (robots - 1): everyone hears everyone
    resends: int = 0
    duration_s: float = 0.0
    bearer_stats: dict[str, dict[str, int]] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def summary(self) -> str:
        """A few lines for people: one figure per line."""
        verdict = "PASS" if self.passed else "FAIL"
        lines = [
            f"ble-check: {verdict}, {self.robots} robots on {self.controllers}, {self.duration_s:.1f} s, "
            f"{'authenticated' if self.authenticated else 'unauthenticated'} frames",
            f"  Heartbeat warm-up {self.warm_up_s:.1f} s",
            f"  commands {self.commands_confirmed}/{self.commands_sent} confirmed",
            f"  PoseUpdates {self.pose_updates_confirmed}/{self.pose_updates_sent} confirmed",
            f"  frame latency p50 {self.frame_latency_p50_ms:.1f} ms, p95 {self.frame_latency_p95_ms:.1f} ms,"
            f" max {self.frame_latency_max_ms:.1f} ms ({self.latency_samples} receptions,"
            f" {self.resent_samples} of frames sent by a timer or repeated)",
            f"  confirm RTT p50 {self.confirm_rtt_p50_ms:.1f} ms, p95 {self.confirm_rtt_p95_ms:.1f} ms,"
            f" max {self.confirm_rtt_max_ms:.1f} ms",
            f"  frames sent {self.frames_sent}, on air {self.frames_advertised}; receptions"
            f" {self.receptions} of {self.receptions_expected}; resends {self.resends}",
        ]
        if self.failure:
            lines.append(f"  failure: {self.failure}")
        return "\n".join(lines)
