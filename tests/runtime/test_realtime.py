"""RealtimeLoop on a fake clock: robot_2's loop over a fake link to robot_1, stepped by hand on the same
clock (frames cross in 1 ms). Time passes only inside the link's wait(), so nothing sleeps."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from rescuemesh.geometry import Pose2D
from rescuemesh.protocol import MessageType, ResultCode
from rescuemesh.robot import events as ev
from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.onboard.linked_robot import EXIT_LINGER_S, ExitWhenDone, Mission, build_robot
from rescuemesh.runtime.onboard.realtime import MAX_FRAMES_PER_WAKE, RealtimeLoop

LATENCY_S = 0.001
PEER_PHASE_S = 0.025  # robot_1 ticks half a control step after robot_2


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class FakeAir:
    """robot_2's link, with robot_1 (brain, stack, an optional mission hook) on the far side. robot_1
    ticks every control step at PEER_PHASE_S past robot_2's ticks and answers frames on arrival."""

    def __init__(self, clock: Clock, peer=None, dt: float = 0.05) -> None:
        self.clock, self.peer, self.dt = clock, peer, dt
        self.inbox: list[tuple[float, bytes]] = []  # frames for robot_2: (arrival s, bytes)
        self.to_peer: list[tuple[float, bytes]] = []
        self.scheduled: list[tuple[float, object]] = []  # (s, callable(now))
        self.sent: list[tuple[float, bytes]] = []  # what robot_2 sent: (s, bytes)
        self.peer_next_tick = PEER_PHASE_S
        self.peer_hook = None
        self._spins, self._last_wait = 0, -1.0

    # --- the FrameLink robot_2's loop uses ---

    def send(self, frame: bytes) -> None:
        self.sent.append((self.clock.t, frame))
        if self.peer is not None:
            self.to_peer.append((self.clock.t + LATENCY_S, frame))

    def wait(self, timeout_s):
        self._spins = self._spins + 1 if self.clock.t == self._last_wait else 0
        self._last_wait = self.clock.t
        assert self._spins < 10_000, "the loop spins without letting time pass"
        target = math.inf if timeout_s is None else self.clock.t + max(0.0, timeout_s)
        while True:
            if any(at <= self.clock.t for at, _ in self.inbox):
                return True
            at, what = self._next_event()
            if at > target:
                self.clock.t = target
                return False
            self.clock.t = max(self.clock.t, at)
            what()

    def drain(self, limit: int | None = None) -> list[bytes]:  # hands everything: the loop cuts
        ready = [f for at, f in self.inbox if at <= self.clock.t]
        self.inbox = [(at, f) for at, f in self.inbox if at > self.clock.t]
        return ready

    # --- the far side ---

    def inject(self, at: float, frames: list[bytes]) -> None:
        self.scheduled.append((at, lambda now: self.inbox.extend((now, f) for f in frames)))

    def _next_event(self):
        events = [(at, lambda: self._deliver_to_peer()) for at, _ in self.to_peer[:1]]
        events += [(at, lambda: None) for at, _ in self.inbox]  # an arrival for robot_2: wait() returns
        events += [(at, lambda a=at, f=fn: self._run_scheduled(a, f)) for at, fn in self.scheduled]
        if self.peer is not None:
            events.append((self.peer_next_tick, self._peer_tick))
            timer = self.peer.stack.get_timer()
            if timer is not None:
                events.append((timer, self._peer_timer))
        return min(events, key=lambda e: e[0]) if events else (math.inf, lambda: None)

    def _run_scheduled(self, at, fn) -> None:
        self.scheduled.remove((at, fn))
        fn(self.clock.t)

    def _deliver_to_peer(self) -> None:
        _, frame = self.to_peer.pop(0)
        heard = self.peer.stack.endpoint.stats.frames_received
        self.peer.stack.receive(frame, self.clock.t)
        if self.peer.stack.endpoint.stats.frames_received != heard:
            self._peer_step()
        else:
            self._peer_flush()

    def _peer_timer(self) -> None:
        self.peer.stack.handle_timer(self.clock.t)
        self._peer_flush()

    def _peer_tick(self) -> None:
        self.peer_next_tick += self.dt
        self._peer_step()

    def _peer_step(self) -> None:
        now = self.clock.t
        self.peer.brain.step(now)
        if self.peer_hook is not None:
            self.peer_hook(self.peer, now)
        self._peer_flush()

    def _peer_flush(self) -> None:
        for frame in self.peer.stack.frames_to_send(self.clock.t):
            self.inbox.append((self.clock.t + LATENCY_S, frame))


def robot(name: str, start: Pose2D, clock: Clock):
    body, brain, stack = build_robot(name, start, SimConfig(), clock)
    return SimpleNamespace(body=body, brain=brain, stack=stack)


def pair(dt: float = 0.05):
    """robot_2's loop over a FakeAir to robot_1."""
    clock = Clock()
    r1 = robot("robot_1", Pose2D(0.0, 0.0), clock)
    r2 = robot("robot_2", Pose2D(-1.5, 0.0), clock)
    air = FakeAir(clock, r1, dt)
    loop = RealtimeLoop(r2.brain, r2.stack, air, control_dt=dt, clock=clock, rng=np.random.default_rng(0))
    return clock, r1, r2, air, loop


def confirm_time(brain, command: MessageType) -> float:
    return next(e.time_s for e in brain.log if isinstance(e, ev.Confirm) and e.command is command)


def test_a_command_is_confirmed_on_arrival_not_at_the_next_tick():
    clock, r1, r2, air, loop = pair()
    sent_at = 0.1123  # between robot_2's ticks (0.10, 0.15), after both heard each other's heartbeat
    seqs = []
    air.scheduled.append((sent_at, lambda now: (seqs.append(r1.brain.command_follow(2, now)), air._peer_flush())))
    loop.run(0.3)
    assert r1.brain.outgoing[seqs[0]].result == ResultCode.ACCEPTED
    # Follow reaches robot_2 at +1 ms; its Confirm leaves at once and reaches robot_1 at +2 ms
    assert confirm_time(r1.brain, MessageType.FOLLOW) == pytest.approx(sent_at + 2 * LATENCY_S, abs=1e-3)
    assert loop.stats.arrival_steps >= 1


def test_a_resend_leaves_on_its_timer_between_ticks():
    clock, r1, r2, air, loop = pair(dt=0.04)  # ticks at 0.12, 0.16, 0.28, 0.32: resends due at 0.15, 0.30
    air.peer = None  # nobody answers
    air.to_peer.clear()
    loop.on_step = lambda lp, now: r2.brain.command_stop(9, now) if now == 0.0 else None
    loop.run(0.5)
    times = [round(t, 6) for t, _ in air.sent]
    assert 0.15 in times and 0.3 in times, times
    assert r2.brain.outgoing[next(iter(r2.brain.outgoing))].failed  # given up after 3 sends
    assert loop.stats.timers >= 2


def test_run_is_bounded_ends_early_and_halts_the_body():
    clock, r1, r2, air, loop = pair()
    r2.brain.navigate_to(Pose2D(5.0, 0.0), 0.0)
    ended = loop.run(1.0)
    assert 1.0 <= ended <= 1.0 + loop.control_dt
    assert r2.body.distance_m > 0.1  # it was driving...
    assert r2.body.odometry()[1:] == (0.0, 0.0)  # ... and is halted on the way out
    start = clock.t
    assert loop.run(10.0, until=lambda now: now - start >= 0.3) == pytest.approx(start + 0.3, abs=0.06)
    loop.on_step = lambda lp, now: lp.stop()
    assert loop.run(10.0) == pytest.approx(clock.t) and clock.t - start < 0.5


def test_a_brain_that_raises_still_leaves_the_body_halted():
    clock, r1, r2, air, loop = pair()
    r2.brain.navigate_to(Pose2D(5.0, 0.0), 0.0)

    def boom(lp, now):
        if now > 0.5:  # moving by then
            raise RuntimeError("mission bug")

    loop.on_step = boom
    with pytest.raises(RuntimeError):
        loop.run(1.0)
    assert r2.body.distance_m > 0.05 and r2.body.odometry()[1:] == (0.0, 0.0)


GARBAGE = [b"", b"\x00", b"\xff" * 20, bytes(range(20)), b"\x01" * 1024, b"rescuemesh" * 3]


def test_garbage_from_a_peer_never_crashes_the_robot_and_commands_still_get_through():
    clock, r1, r2, air, loop = pair()
    rng = np.random.default_rng(1)
    junk = GARBAGE + [bytes(rng.integers(0, 256, int(rng.integers(0, 40)), dtype=np.uint8)) for _ in range(200)]
    real = []

    def capture(now):  # a real frame of robot_1's, corrupted bit by bit
        r1.brain.command_stop(2, now)
        frame = r1.stack.frames_to_send(now)[0]
        r1.stack.endpoint.cancel_pending(2)  # never sent intact
        real.append(frame)
        air.inbox.extend((now, frame[:i] + bytes([frame[i] ^ 0x10]) + frame[i + 1:]) for i in range(len(frame)))

    air.inject(0.07, junk)
    air.scheduled.append((0.08, capture))
    seqs = []
    air.scheduled.append((0.2123, lambda now: (seqs.append(r1.brain.command_follow(2, now)), air._peer_flush())))
    loop.run(0.5)
    assert r1.brain.outgoing[seqs[0]].result == ResultCode.ACCEPTED
    assert not any(isinstance(e, ev.CommandReceived) and e.command is MessageType.STOP
                   for e in r2.brain.log)  # no forged Stop
    mesh = r2.stack.node.stats
    assert mesh.received - mesh.accepted >= len(junk) + len(real[0])  # not one bad frame was used


def test_a_flood_is_cut_at_the_wake_up_limit():
    clock, r1, r2, air, loop = pair()
    air.peer = None  # robot_1 silent: only the flood arrives
    air.inject(0.02, [b"\x00" * 20] * (MAX_FRAMES_PER_WAKE + 100))
    loop.run(0.1)
    assert loop.stats.frames_dropped == 100 and loop.stats.frames_in == MAX_FRAMES_PER_WAKE
    assert loop.stats.ticks >= 2  # the loop kept its ticks


def test_follow_over_the_loop_in_fake_time():
    clock, r1, r2, air, loop = pair()
    mission = Mission(follower=2, goal=Pose2D(3.0, 0.0), linger_s=1.0)
    air.peer_hook = lambda peer, now: mission.on_step(SimpleNamespace(brain=peer.brain, stack=peer.stack), now)
    loop.run(30.0, until=lambda now: mission.done_s is not None)
    assert mission.follow_result == ResultCode.ACCEPTED and mission.ok
    assert r2.brain.finished[0].name == "follow" and r2.brain.finished[0].result == ResultCode.CANCELLED
    leader, follower = r1.body.pose(), r2.body.pose()
    assert leader.distance_to(Pose2D(3.0, 0.0)) < 0.2
    assert r2.body.distance_m > 2.0 and follower.distance_to(leader) < 1.6


def test_exit_when_done_counts_from_the_latest_end():
    brain = SimpleNamespace(running=None, finished=[])
    until = ExitWhenDone(brain, None)
    assert not until(0.0)  # nothing ran yet
    brain.finished.append("follow")  # a Stop ended the Follow at 1.0 s...
    assert not until(1.0)
    brain.running = "follow"  # ... and a new Follow came at 1.1 s
    assert not until(1.1)
    brain.running = None  # which ended at 3.0 s
    assert not until(3.0) and not until(3.0 + EXIT_LINGER_S / 2)
    assert until(3.01 + EXIT_LINGER_S)
    mission = SimpleNamespace(done_s=None)
    until = ExitWhenDone(brain, mission)  # with a mission, its end decides
    assert not until(5.0)
    mission.done_s = 5.0
    assert not until(5.0) and until(5.01 + EXIT_LINGER_S)


@pytest.mark.parametrize("x", [330.0, math.nan], ids=["x=330 m", "NaN"])
def test_a_pose_the_wire_cannot_carry_halts_the_leader_with_a_warning_and_no_exception(x, caplog):
    # this used to raise EncodeError out of brain.step (its next PoseUpdate) and end the robot process
    clock, r1, r2, air, loop = pair()
    mission = Mission(follower=2, goal=None, linger_s=30.0)
    air.peer_hook = lambda peer, now: mission.on_step(SimpleNamespace(brain=peer.brain, stack=peer.stack), now)
    loop.run(3.0, until=lambda now: mission.accepted_s is not None)
    assert mission.follow_result == ResultCode.ACCEPTED and r1.brain.streams
    r1.body.set_velocity(0.3, 0.0)
    r1.body._x = x  # the leader's odometry jumps (a drift past 327.67 m, a driver's NaN)
    with caplog.at_level("WARNING"):
        loop.run(6.0)  # robot_1 is stepped on the same clock: nothing may raise
    assert r1.brain.pose_fault is not None and not r1.brain.streams
    assert r1.body._v == 0.0 and r1.body._w == 0.0  # halted
    assert [type(e) for e in r1.brain.log].count(ev.PoseFault) == 1  # reported once, not every step
    assert any("outside the wire's range" in record.getMessage() for record in caplog.records)
    r1.body._x = 10.0  # back in range: the fault clears
    loop.run(0.5)
    assert r1.brain.pose_fault is None and ev.PoseFaultCleared in [type(e) for e in r1.brain.log]


def _received(i: int) -> ev.CommandReceived:
    return ev.CommandReceived(float(i), "robot_1", MessageType.GOTO, 2, i, 1)


def test_the_brains_log_is_a_ring_with_a_count_of_what_it_dropped():
    # this used to grow without bound: a key holder's commands each add a line
    from rescuemesh.robot.records import BrainLog

    log = BrainLog(capacity=8)  # holds at most 8 + 8 // 8 = 9, then keeps the latest 8
    for i in range(10):
        log.append(_received(i))
    assert len(log) == 8 and log.total == 10 and log.dropped == 2
    assert [e.seq for e in log] == list(range(2, 10))
    assert [e.seq for e in log.since(1)][:1] == [2] and [e.seq for e in log.since(9)] == [9]
    assert log.since(10) == [] and log[-1].seq == 9
    for i in range(10, 10_000):
        log.append(_received(i))
    assert len(log) <= 9 and log.total == 10_000


def test_a_brain_log_extended_counts_and_bounds_like_appends():
    # the process world mirrors a robot's log with extend(); list.extend used to skip the count, so a
    # reader of since(total) (the recorder) read nothing or everything again
    from rescuemesh.robot.records import BrainLog

    log = BrainLog(capacity=8)
    log.extend(_received(i) for i in range(20))
    assert log.total == 20 and len(log) <= 9 and log.dropped == 20 - len(log)
    assert [e.time_s for e in log.since(18)] == [18.0, 19.0]
