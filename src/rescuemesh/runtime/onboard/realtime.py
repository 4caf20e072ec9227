"""The real-time robot loop: one robot's brain and network stack on wall-clock time, over a frame link.
Owns: the robot process's clock and loop (control ticks, waking on frames and stack timers, the bounded
run, halting the body on exit). Must not know: Zenoh (it is handed a link), what frames contain, missions.
"""

# Theory of operation. Time is `clock()` in s (time.monotonic from 0 by default; a fake clock in
# tests). Every `control_dt` s the loop takes the frames heard, fires due stack timers, steps the
# brain and the mission hook, and sends what the stack has to send. Between ticks it sleeps in
# `link.wait` until the next tick, the stack's next timer or a frame, whichever comes first. A frame
# is handed to the stack at once; when it reached the protocol endpoint (a command, a Confirm, a
# PoseUpdate, a Heartbeat), the brain is stepped at once too, so a command is confirmed within the
# link's round trip, not at the next tick, and the answer leaves before the loop sleeps again.
# (The brain's step is a function of `now`, so extra steps between ticks are harmless: the
# navigator integrates its acceleration limit over the real interval.)

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Protocol

import numpy as np

#: A relaying stack re-broadcasts after a random 0..10 ms (Mesh Profile 1.0, 3.4.6.3); the sans-IO
#: mesh layer draws no random numbers, so the loop does (as the simulated medium and ble-check do).
RELAY_DELAY_MAX_S = 0.010
#: Frames handed to the stack per wake-up at most (a flood cannot starve the control tick). The link
#: is asked for at most this many, taken fairly over its sources (ZenohLink.drain: round-robin); a link
#: that hands more has the excess dropped at random and counted, never the tail: under a flood the
#: tail is where a genuine frame sits.
MAX_FRAMES_PER_WAKE = 256


class FrameLink(Protocol):
    """What the loop needs of a bearer (transport.zenoh_link.ZenohLink has it)."""

    def send(self, frame: bytes) -> None: ...
    def wait(self, timeout_s: float | None) -> bool: ...
    def drain(self, limit: int | None = None) -> list[bytes]: ...


def monotonic_from_zero() -> Callable[[], float]:
    """A clock in s that reads 0 now and follows time.monotonic: a robot process's time."""
    start = time.monotonic()
    return lambda: time.monotonic() - start


@dataclass
class LoopStats:
    """What the loop did: control ticks, ticks that started late by more than a tick (skipped
    ahead), extra brain steps on arrival, frames in, out and dropped (a flood), stack timers fired."""

    ticks: int = 0
    overruns: int = 0
    arrival_steps: int = 0
    frames_in: int = 0
    frames_out: int = 0
    frames_dropped: int = 0
    timers: int = 0
    wakeups: int = 0
    ran_s: float = 0.0

    def as_dict(self) -> dict:
        return asdict(self)


class RealtimeLoop:
    """Robot `brain` with its network `stack` over `link`, on `clock`.

    `on_step(loop, now)`: the mission hook, called after every brain step (each tick and each
    arrival step); what it makes the brain send leaves at once. `relay_delay()`: a relay's random
    delay in s (default: uniform 0..10 ms from `rng`).
    """

    def __init__(self, brain, stack, link: FrameLink, *, control_dt: float = 0.05,
                 clock: Callable[[], float] | None = None,
                 on_step: Callable[["RealtimeLoop", float], None] | None = None,
                 rng: np.random.Generator | None = None, relay_delay: Callable[[], float] | None = None) -> None:
        if not control_dt > 0:
            raise ValueError(f"control_dt must be > 0 s, got {control_dt}")
        self.brain, self.stack, self.link = brain, stack, link
        self.control_dt = float(control_dt)
        self.clock = clock if clock is not None else monotonic_from_zero()
        self.on_step = on_step
        rng = rng if rng is not None else np.random.default_rng()
        self._rng = rng
        if relay_delay is None:
            relay_delay = lambda: float(rng.uniform(0.0, RELAY_DELAY_MAX_S))  # noqa: E731
        self._relay_delay = relay_delay
        self.stats = LoopStats()
        self.stopped = False  # set from a signal handler or the mission: the run ends at the next wake-up
        self._endpoint_stats = stack.endpoint.stats

    def stop(self) -> None:
        """Ask the run to end (safe from a signal handler)."""
        self.stopped = True

    def run(self, max_s: float, until: Callable[[float], bool] | None = None) -> float:
        """Run for at most `max_s` s of the clock, or until `until(now)` holds after a step, or
        stop() is called. The body is halted on the way out, whatever ends the run. Returns the time
        the run ended."""
        start = self.clock()
        end = start + max_s
        next_tick = start
        stats = self.stats
        try:
            while not self.stopped:
                now = self.clock()
                if now >= end:
                    break
                if now >= next_tick:
                    self._tick(now)
                    if until is not None and until(now):
                        break
                    next_tick += self.control_dt
                    if next_tick <= now:  # late by more than a tick: skip ahead rather than burst
                        stats.overruns += 1
                        next_tick = now + self.control_dt
                    continue
                deadline = min(next_tick, end)
                timer = self.stack.get_timer()
                if timer is not None and timer < deadline:
                    deadline = timer
                if self.link.wait(max(0.0, deadline - now)):
                    stats.wakeups += 1
                    now = self.clock()
                    self._on_frames(now)
                    if until is not None and until(now):
                        break
                else:
                    now = self.clock()
                    timer = self.stack.get_timer()
                    if timer is not None and timer <= now:
                        self._fire_timers(now)
        finally:
            self._halt()
        stats.ran_s += self.clock() - start
        return self.clock()

    # --- steps ---------------------------------------------------------------------------------

    def _tick(self, now: float) -> None:
        self.stats.ticks += 1
        self._receive(now)
        timer = self.stack.get_timer()
        if timer is not None and timer <= now:
            self.stack.handle_timer(now)
            self.stats.timers += 1
        self._step(now)

    def _on_frames(self, now: float) -> None:
        heard = self._endpoint_stats.frames_received
        self._receive(now)
        if self._endpoint_stats.frames_received != heard:  # the endpoint has news: act on it now
            self.stats.arrival_steps += 1
            self._step(now)
        else:
            self._flush(now)  # relays and mesh control frames leave at once

    def _fire_timers(self, now: float) -> None:
        self.stats.timers += 1
        self.stack.handle_timer(now)
        self._flush(now)

    def _receive(self, now: float) -> None:
        frames = self.link.drain(MAX_FRAMES_PER_WAKE)
        if len(frames) > MAX_FRAMES_PER_WAKE:  # this used to keep the first 256 and drop the rest
            self.stats.frames_dropped += len(frames) - MAX_FRAMES_PER_WAKE
            keep = np.sort(self._rng.choice(len(frames), MAX_FRAMES_PER_WAKE, replace=False))
            frames = [frames[i] for i in keep]
        self.stats.frames_in += len(frames)
        receive, delay = self.stack.receive, self._relay_delay
        for frame in frames:
            receive(frame, now, relay_delay_s=delay())

    def _step(self, now: float) -> None:
        self.brain.step(now)
        if self.on_step is not None:
            self.on_step(self, now)
        self._flush(now)

    def _flush(self, now: float) -> None:
        frames = self.stack.frames_to_send(now)
        self.stats.frames_out += len(frames)
        for frame in frames:
            self.link.send(frame)

    def _halt(self) -> None:
        self.brain.body.set_velocity(0.0, 0.0)
