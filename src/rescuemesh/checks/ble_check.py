"""ble-check: three robots command each other in real time over Bluetooth advertising bearers;
frame latency and confirm round trips are timed on the event loop's clock. Owns the check's script
and report (the asyncio pump between a stack and a bearer is transport/asyncio_pump.py). Must not know
frame layouts.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol, TextIO

import numpy as np

from rescuemesh.mesh import MeshConfig, MeshNode, NetworkStack
from rescuemesh.protocol import (
    CommandReceived,
    ConfirmReceived,
    DeliveryFailed,
    Endpoint,
    EndpointConfig,
    Follow,
    MessageType,
    Pose,
    PoseUpdateReceived,
    ReliabilityConfig,
    ResultCode,
    Stop,
)
from rescuemesh.checks.ble_measure import BleCheckReport, FrameLog, percentile
from rescuemesh.transport.asyncio_pump import Cause, FrameStack, StackPump, endpoint_of

if TYPE_CHECKING:  # bumble is imported only when a check runs
    from rescuemesh.transport.ble import BleTiming

#: Robots in the check; robot_n has address n. robot_1 leads, the others follow it.
ROBOTS = 3
LEADER = 1
#: PoseUpdates go out at 2 Hz, as in the follow scenario (paper IV.A).
POSE_UPDATE_PERIOD_S = 0.5
#: Resend after this long without a Confirm, in s. The advertising bearer sends one frame per
#: hold (3 x 20 ms) per radio, so a Confirm can wait behind two frames at each end (about 4 x 65 ms);
#: the protocol default of 0.15 s would resend frames that are only queued.
BLE_ACK_TIMEOUT_S = 0.5
#: A relaying stack re-broadcasts after a random 0..10 ms (Mesh Profile 1.0, 3.4.6.3), drawn here
#: because the sans-IO mesh layer draws no random numbers (the simulated medium does the same).
RELAY_DELAY_MAX_S = 0.010
#: After the script, frames still on air get this long to land before the bearers stop, in s.
DRAIN_S = 0.25
#: Each robot's bearer gets this long to stop, in s (a dead dongle must not hang the exit).
STOP_TIMEOUT_S = 5.0
#: The team key of the check's robots derives from this seed (as `rescuemesh robot --seed 0`'s).
CHECK_SEED = 0
#: How often the warm-up looks whether the leader has heard every follower's Heartbeat, in s.
WARM_UP_POLL_S = 0.05
#: TTL of the check's Heartbeats: 0, not relayed (the check's robots hear each other directly; relayed
#: copies would only queue on the bearers ahead of the commands).
WARM_UP_HEARTBEAT_TTL = 0
#: Each robot sends a Heartbeat this often during the warm-up, in s.
WARM_UP_PERIOD_S = 0.5
#: After the warm-up, the relays of its Heartbeats (two per Heartbeat among three robots, a hold of
#: 60 ms each, queued behind each other) get this long to leave the air, in s.
WARM_UP_SETTLE_S = 0.5


class CommandEndpoint(Protocol):
    """What the check's robots call: the protocol Endpoint's sending calls and its events."""

    def send_command(self, dst: int, command: Any, now: float) -> int: ...
    def send_pose_update(self, dst: int, pose: Pose, now: float) -> int: ...
    def confirm(
        self, dst: int, ref_seq: int, ref_type: MessageType, result: ResultCode, now: float
    ) -> None: ...
    def next_event(self) -> Any: ...


def default_stack(address: int) -> FrameStack:
    """A robot's network stack as in the simulation (endpoint with the BLE ack timeout, on a mesh
    node that relays, its frames authenticated and encrypted under the team key of CHECK_SEED, as a
    robot's are by default): the stack the check uses unless told otherwise. No relay retransmit: the
    bearer already keeps every frame on the air for three advertising events, which is what a
    Bluetooth Mesh stack's network and relay retransmissions amount to; more would queue."""
    from rescuemesh.mesh.keys import team_key_from_seed
    from rescuemesh.mesh.security import FrameSealer

    endpoint = Endpoint(address, EndpointConfig(reliability=ReliabilityConfig(ack_timeout_s=BLE_ACK_TIMEOUT_S),
                                                heartbeat_ttl=WARM_UP_HEARTBEAT_TTL))
    sealer = FrameSealer.from_team_key(team_key_from_seed(CHECK_SEED))
    return NetworkStack(endpoint, MeshNode(address, MeshConfig(), sealer))


# --- the robots ------------------------------------------------------------------------------------


class _Robot:
    """One robot of the check: a stack, its bearer, its pump and the little application on top."""

    def __init__(
        self, address: int, stack: FrameStack, bearer: Any, log: FrameLog, rng: np.random.Generator
    ) -> None:
        self.address = address
        self.stack = stack
        self.endpoint: CommandEndpoint = endpoint_of(stack)
        self.bearer = bearer
        self.following: int | None = None
        self.pending: dict[tuple[int, int], tuple[float, asyncio.Future[Any]]] = {}  # (dst, seq)
        self.rtts_s: list[float] = []
        self.pump = StackPump(
            stack,
            bearer,
            on_event=self._on_event,
            on_sent=lambda frame, now, cause: log.sent(address, frame, now, cause),
            on_received=lambda frame, now: log.received(address, frame, now),
            relay_delay=lambda: float(rng.uniform(0.0, RELAY_DELAY_MAX_S)),
        )
        bearer.on_frame = self.pump.frame_received
        self._loop = asyncio.get_running_loop()
        # event type -> handler; other events (Heartbeats, rejected frames, network events) are
        # not this check's business
        self._handlers: dict[type, Callable[[Any], None]] = {
            ConfirmReceived: self._on_confirm,
            DeliveryFailed: self._on_delivery_failed,
            CommandReceived: self._on_command,
            PoseUpdateReceived: self._on_pose_update,
        }

    # leader side
    def command(self, dst: int, command: Any) -> asyncio.Future[Any]:
        now = self._loop.time()
        return self._track(dst, self.endpoint.send_command(dst, command, now), now)

    def pose_update(self, dst: int, pose: Pose) -> asyncio.Future[Any]:
        now = self._loop.time()
        return self._track(dst, self.endpoint.send_pose_update(dst, pose, now), now)

    def _track(self, dst: int, seq: int, now: float) -> asyncio.Future[Any]:
        future = self._loop.create_future()
        self.pending[(dst, seq)] = (now, future)
        self.pump.transmit(Cause.APP)
        return future

    def _on_event(self, event: Any) -> None:
        handler = self._handlers.get(type(event))
        if handler is not None:
            handler(event)

    # leader side
    def _on_confirm(self, event: ConfirmReceived) -> None:
        # only the first, solicited Confirm finds its frame pending; later reports find nothing
        sent_s, future = self.pending.pop((event.src, event.ref_seq), (0.0, None))
        if future is not None and not future.done():
            self.rtts_s.append(event.now - sent_s)
            future.set_result(event)

    def _on_delivery_failed(self, event: DeliveryFailed) -> None:
        _, future = self.pending.pop((event.dst, event.seq), (0.0, None))
        if future is not None and not future.done():
            future.set_result(event)

    # follower side: Follow -> ACCEPTED and follow the sender, Stop -> DONE, anything else UNSUPPORTED
    def _on_command(self, event: CommandReceived) -> None:
        kind = event.command.TYPE
        following, result = _ANSWERS.get(kind, (self.following, ResultCode.UNSUPPORTED))
        self.following = event.src if following is _SENDER else following
        self.endpoint.confirm(event.src, event.seq, kind, result, event.now)

    def _on_pose_update(self, event: PoseUpdateReceived) -> None:
        result = ResultCode.ACCEPTED if self.following == event.src else ResultCode.DENIED
        self.endpoint.confirm(event.src, event.seq, MessageType.POSE_UPDATE, result, event.now)


#: A follower's answer to a command: whom it follows afterwards (_SENDER: the sender) and the result.
_SENDER = object()
_ANSWERS: dict[MessageType, tuple[Any, ResultCode]] = {
    MessageType.FOLLOW: (_SENDER, ResultCode.ACCEPTED),
    MessageType.STOP: (None, ResultCode.DONE),
}


def _confirmed(outcome: Any, expected: ResultCode) -> bool:
    return isinstance(outcome, ConfirmReceived) and outcome.result is expected


class _Script:
    """robot_1 sends Follow to the others, streams PoseUpdates at 2 Hz, then sends Stop."""

    def __init__(self, robots: dict[int, _Robot], report: BleCheckReport, updates: int) -> None:
        self.robots = robots
        self.report = report
        self.updates = updates
        self.phase = "starting"
        self.started = asyncio.get_running_loop().time()

    async def run(self) -> None:
        leader = self.robots[LEADER]
        followers = [a for a in self.robots if a != LEADER]
        loop = asyncio.get_running_loop()
        pose = Pose(0.0, 0.0, 0.0, 0.0)

        # Heartbeat warm-up: a robot commands a peer it has heard (its Heartbeat, authenticated), as
        # `rescuemesh robot`'s mission does; a stack without a liveness table (a bare Endpoint) skips it
        # (every robot sends a Heartbeat each WARM_UP_PERIOD_S: it carries the sender's epoch, which an
        # authenticated frame's receiver needs, as a robot's brain sends one each second)
        self.phase = "Heartbeat warm-up"
        def everyone_heard(now: float) -> bool:  # each robot has heard each other's Heartbeat (its epoch)
            return all(r.stack.is_reachable(other, now) for a, r in self.robots.items() for other in self.robots
                       if other != a)

        if all(callable(getattr(r.stack, "is_reachable", None)) for r in self.robots.values()):
            from rescuemesh.robot.records import heartbeat_phase_s

            # each robot's Heartbeats at its own phase, as brains send theirs: not all on air at once
            next_beat = {a: loop.time() + heartbeat_phase_s(a, WARM_UP_PERIOD_S) for a in self.robots}
            while not everyone_heard(loop.time()):
                for address, robot in self.robots.items():
                    if loop.time() >= next_beat[address]:
                        robot.endpoint.send_heartbeat(loop.time())
                        robot.pump.transmit(Cause.TIMER)
                        next_beat[address] += WARM_UP_PERIOD_S
                await asyncio.sleep(WARM_UP_POLL_S)
            await asyncio.sleep(WARM_UP_SETTLE_S)  # the Heartbeats' relays leave the air before the Follow
            self.report.warm_up_s = loop.time() - self.started

        self.phase = "Follow"
        outcomes = await self._commands(leader, followers, lambda: Follow(pose))
        self.report.commands_confirmed += sum(_confirmed(o, ResultCode.ACCEPTED) for o in outcomes)

        self.phase = "PoseUpdates"
        futures: list[asyncio.Future[Any]] = []
        start = loop.time()
        for i in range(self.updates):
            await asyncio.sleep(max(0.0, start + i * POSE_UPDATE_PERIOD_S - loop.time()))
            pose_i = Pose(0.25 * (i + 1), 0.0, 0.0, 0.0)  # the leader drives along x at 0.5 m/s
            for dst in followers:
                futures.append(leader.pose_update(dst, pose_i))
                self.report.pose_updates_sent += 1
        outcomes = await asyncio.gather(*futures)
        self.report.pose_updates_confirmed = sum(_confirmed(o, ResultCode.ACCEPTED) for o in outcomes)

        self.phase = "Stop"
        outcomes = await self._commands(leader, followers, Stop)
        self.report.commands_confirmed += sum(_confirmed(o, ResultCode.DONE) for o in outcomes)
        self.phase = "done"

    async def _commands(self, leader: _Robot, followers: list[int], make: Callable[[], Any]) -> list[Any]:
        futures = [leader.command(dst, make()) for dst in followers]
        self.report.commands_sent += len(futures)
        return list(await asyncio.gather(*futures))


# --- running the check -----------------------------------------------------------------------------


def check_hci_specs(hci: str | Sequence[str] | None) -> list[str | None]:
    """One HCI spec (or None: virtual) per robot. Raises ValueError unless `hci` is empty/None
    (three virtual controllers) or names three distinct controllers: virtual and real controllers
    cannot hear each other, and one radio per robot is the point of the check."""
    specs = [hci] if isinstance(hci, str) else list(hci or [])
    if not specs:
        return [None] * ROBOTS
    if len(specs) != ROBOTS:
        raise ValueError(
            f"--hci names {len(specs)} controller(s); ble-check needs one per robot: give --hci "
            f"{ROBOTS} times (e.g. --hci usb:0 --hci usb:1 --hci usb:2), or not at all for virtual "
            "controllers"
        )
    if len(set(specs)) != len(specs):
        raise ValueError(f"--hci names the same controller twice: {', '.join(specs)}")
    return list(specs)


async def run_ble_check(
    hci: str | Sequence[str] | None = None,
    *,
    updates: int = 6,
    timeout_s: float = 30.0,
    make_stack: Callable[[int], FrameStack] = default_stack,
    timing: BleTiming | None = None,
    seed: int = 0,
) -> BleCheckReport:
    """Run the check on three bearers (virtual controllers, or the three controllers in `hci`) and
    return its report. `make_stack(address)` builds each robot's stack (see FrameStack and
    endpoint_of); `seed` seeds the relay delays. Raises ValueError for bad `hci` or `updates`,
    BleSetupError when a controller cannot be opened; a timeout or a failure during the run gives a
    report with passed False."""
    from rescuemesh.transport.ble import BleBearer, new_virtual_link  # bumble only when asked for

    specs = check_hci_specs(hci)
    if not (isinstance(updates, int) and 0 <= updates <= 1000):
        raise ValueError(f"updates must be an int 0..1000, got {updates!r}")
    virtual = specs[0] is None
    report = BleCheckReport(controllers="virtual controllers" if virtual else ", ".join(specs), robots=ROBOTS)
    link = new_virtual_link() if virtual else None
    bearers = {
        address: BleBearer(spec, link=link, timing=timing, name=f"robot_{address}")
        for address, spec in zip(range(1, ROBOTS + 1), specs)
    }
    log = FrameLog()
    robots: dict[int, _Robot] = {}
    loop = asyncio.get_running_loop()
    started = finished = loop.time()
    script: _Script | None = None
    try:
        await _start_all(list(bearers.values()))
        streams = np.random.SeedSequence(seed).spawn(len(bearers))
        robots = {
            address: _Robot(address, make_stack(address), bearer, log, np.random.default_rng(stream))
            for (address, bearer), stream in zip(bearers.items(), streams)
        }
        report.authenticated = all(getattr(getattr(r.stack, "node", None), "sealer", None) is not None
                                   for r in robots.values())
        script = _Script(robots, report, updates)
        started = loop.time()
        try:
            await asyncio.wait_for(script.run(), timeout_s)
        except asyncio.TimeoutError:
            report.failure = f"timed out after {timeout_s:g} s in the {script.phase} phase"
        finished = loop.time()
        await asyncio.sleep(DRAIN_S)  # the last Confirm's other listeners, queued Heartbeats
    finally:
        for robot in robots.values():
            robot.pump.close()
        await asyncio.gather(*(_stop(bearer) for bearer in bearers.values()))
    report.duration_s = finished - started
    _fill_figures(report, robots, bearers, log)
    return report


async def _start_all(bearers: list[Any]) -> None:
    results = await asyncio.gather(*(bearer.start() for bearer in bearers), return_exceptions=True)
    errors = [result for result in results if isinstance(result, BaseException)]
    if errors:
        raise errors[0]


async def _stop(bearer: Any) -> None:
    try:
        await asyncio.wait_for(bearer.stop(), STOP_TIMEOUT_S)
    except Exception:  # stop() never raises; the timeout is the only way here
        pass


def _fill_figures(
    report: BleCheckReport, robots: dict[int, _Robot], bearers: dict[int, Any], log: FrameLog
) -> None:
    latencies = [s.latency_s * 1000.0 for s in log.samples]
    report.latency_samples = len(latencies)
    report.resent_samples = sum(s.resent for s in log.samples)
    report.frame_latency_p50_ms = percentile(latencies, 50)
    report.frame_latency_p95_ms = percentile(latencies, 95)
    report.frame_latency_max_ms = max(latencies) if latencies else math.nan
    rtts = [rtt * 1000.0 for robot in robots.values() for rtt in robot.rtts_s]
    report.confirm_rtt_p50_ms = percentile(rtts, 50)
    report.confirm_rtt_p95_ms = percentile(rtts, 95)
    report.confirm_rtt_max_ms = max(rtts) if rtts else math.nan
    report.frames_sent = log.frames_sent
    report.frames_received = log.frames_received
    report.receptions = len(log.samples)
    report.frames_advertised = sum(bearer.stats.frames_advertised for bearer in bearers.values())
    report.receptions_expected = report.frames_advertised * (len(bearers) - 1)
    report.resends = sum(_resends(robot, log) for robot in robots.values())
    report.bearer_stats = {f"robot_{a}": b.stats.as_dict() for a, b in bearers.items()}
    errors = [f"robot_{a}: {e}" for a, robot in robots.items() for e in robot.pump.errors]
    if errors:
        pump_failure = f"{len(errors)} error(s) in the pump, first: {errors[0]}"
        report.failure = pump_failure if report.failure is None else f"{report.failure}; {pump_failure}"
    unconfirmed = (report.commands_sent - report.commands_confirmed) + (
        report.pose_updates_sent - report.pose_updates_confirmed
    )
    if unconfirmed and report.failure is None:
        report.failure = f"{unconfirmed} command(s) or PoseUpdate(s) not confirmed as expected"
    report.passed = report.failure is None and report.commands_sent > 0


def _resends(robot: _Robot, log: FrameLog) -> int:
    """The endpoint's own resend count when it keeps one (Endpoint.stats.retries), else the frames
    this robot's timer sent."""
    retries = getattr(getattr(robot.endpoint, "stats", None), "retries", None)
    if isinstance(retries, int):
        return retries
    return sum(1 for entries in log.sends.values() for src, _, cause, _ in entries
               if src == robot.address and cause is Cause.TIMER)


def ble_check(hci: str | Sequence[str] | None = None, **options: Any) -> BleCheckReport:
    """run_ble_check(hci, **options) on a fresh event loop, for callers that have none."""
    return asyncio.run(run_ble_check(hci, **options))


def main_ble_check(
    hci_specs: Sequence[str] | None, out: TextIO, *, updates: int = 6, timeout_s: float = 30.0,
    err: TextIO | None = None,
) -> int:
    """`rescuemesh ble-check [--hci SPEC]...`: print the report to `out`; 0 when every command and
    PoseUpdate was confirmed, 1 when not, 2 for bad input (wrong --hci count, a controller that
    cannot be opened, bumble missing), with a one-line message on `err` (default: `out`)."""
    err = err if err is not None else out
    try:
        from rescuemesh.transport.ble import BleSetupError
    except ImportError as exc:
        print(f"rescuemesh: error: ble-check needs the ble extra (pip install 'rescuemesh[ble]'): {exc}", file=err)
        return 2
    try:
        specs = check_hci_specs(list(hci_specs or []))
    except ValueError as exc:
        print(f"rescuemesh: error: {exc}", file=err)
        return 2
    try:
        report = ble_check([s for s in specs if s is not None], updates=updates, timeout_s=timeout_s)
    except BleSetupError as exc:
        print(f"rescuemesh: error: {exc}", file=err)
        return 2
    print(report.summary(), file=out)
    return 0 if report.passed else 1
