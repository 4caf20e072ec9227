"""The world's stand-ins for robots that run in other processes: a brain whose status the world
keeps from the robot's replies and whose commands become typed requests, and a network stack the
radio medium can pump.

Owns: the stand-ins' read-only view of a brain (what scenarios, reports and recordings read: the
running behaviour, finished behaviours, commands sent and their outcome, the log, bulk data
received, counters), the typed commands a mission script may give, and the stack stand-in's rule
that keeps the medium exact (below). Must not know: Zenoh (it talks to the runtime's call methods),
MuJoCo, scenarios.

The medium calls a stack in a fixed pattern: `receive` or `handle_timer`, then `transmissions` and
`get_timer`. A robot answers `receive` and `handle_timer` with the stack's new transmissions and
timer at once, and the world primes the stand-in with the same pair at every flush (after the
brains ran and the mission script called into them). Between those calls nothing else touches a
robot's stack, so the stand-in's cached answers are what the stack itself would say, one round trip
per event instead of three. While the medium delivers one frame to all its receivers
(runtime/processes/lockstep_medium.py), receive() only queues its request with the others and answers
False (do not collect me yet); the medium collects it once every receiver has answered.
"""

from __future__ import annotations

from collections import Counter, deque

from rescuemesh.robot.records import BrainLog
from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.processes.control import ControlError


class RobotGone(ControlError):
    """The robot's process is gone (killed, crashed or left); it may join again."""


class RunningStandIn:
    """brain.running as scenarios read it: `.behaviour.name` (and a MoveAround's `waypoints` and
    `skipped`), `.started_s`."""

    def __init__(self, view: msg.RunningView) -> None:
        self.started_s = view.started_s
        self.behaviour = _BehaviourStandIn(view)

    def __repr__(self) -> str:
        return f"<running {self.behaviour.name} since {self.started_s} s (in its robot's process)>"


class _BehaviourStandIn:
    def __init__(self, view: msg.RunningView) -> None:
        self.name = view.name
        if view.waypoints is not None:
            self.waypoints = view.waypoints
        if view.skipped is not None:
            self.skipped = view.skipped


class _EndpointStandIn:
    def __init__(self, stack: "RemoteStack") -> None:
        self._stack = stack

    @property
    def stats(self):
        return self._stack.report().endpoint


class _BodyStandIn:
    """brain.body, read-only: the pose and odometry the world gave the robot."""

    def __init__(self, body) -> None:
        self._body = body

    def pose(self):
        return self._body.pose()

    def odometry(self):
        return self._body.odometry()


class RemoteBrain:
    """Robot `name`'s brain, running in its own process. Reads come from the status the robot sent
    with its latest reply (no round trip); commands are typed requests. Read-only: nothing else of
    the robot can be read or called from here."""

    def __init__(self, link, name: str, address: int, body, stack: "RemoteStack") -> None:
        self._link, self.name, self.address, self._stack = link, name, address, stack
        self.body = _BodyStandIn(body)
        self.endpoint = _EndpointStandIn(stack)
        self.reset()

    def reset(self) -> None:
        """A new process for this robot: a new brain, with nothing done yet."""
        self._running: RunningStandIn | None = None
        self.log = BrainLog()  # the robot's log as it reports it, a ring like its own
        self.finished: list = []
        self.outgoing: dict = {}
        self.received_data: deque = deque(maxlen=64)
        self.commands_failed = 0
        self.peer_capabilities: dict = {}  # address -> Capability, as RobotBrain.peer_capabilities

    def update(self, status: msg.StatusDelta) -> None:
        if status.running_changed:
            self._running = RunningStandIn(status.running) if status.running is not None else None
        self.finished.extend(status.finished)
        for command in status.outgoing:
            self.outgoing[command.seq] = command
        self.log.extend(status.log)
        if status.received_data is not None:
            self.received_data = deque(status.received_data, maxlen=64)
        self.commands_failed = status.commands_failed
        if status.peer_capabilities is not None:
            self.peer_capabilities = dict(status.peer_capabilities)

    def capabilities_of(self, peer: int):
        """What `peer` announced it can do (None before its first Heartbeat), as RobotBrain's."""
        return self.peer_capabilities.get(peer)

    @property
    def running(self) -> RunningStandIn | None:
        self._link.check_live(self.name)
        return self._running

    @property
    def behaviour(self) -> str:
        running = self.running
        return running.behaviour.name if running else "idle"

    # --- what a mission script may ask (RobotBrain's methods of the same names) ----------------

    def navigate_to(self, goal, now: float) -> None:
        self._command(msg.NavigateTo(goal, now))

    def command_goto(self, peer: int, goal, now: float) -> int:
        return self._command(msg.Command(msg.CommandKind.GOTO, peer, now, goal=goal))

    def command_return(self, peer: int, now: float) -> int:
        return self._command(msg.Command(msg.CommandKind.RETURN, peer, now))

    def command_follow(self, peer: int, now: float) -> int:
        return self._command(msg.Command(msg.CommandKind.FOLLOW, peer, now))

    def command_stop(self, peer: int, now: float) -> int:
        return self._command(msg.Command(msg.CommandKind.STOP, peer, now))

    def command_move_around(self, peer: int, radius_m: float, now: float) -> int:
        return self._command(msg.Command(msg.CommandKind.MOVE_AROUND, peer, now, radius_m=float(radius_m)))

    def send(self, peer: int, command, now: float) -> int:
        return self._command(msg.Send(peer, command, now))

    def _command(self, request):
        reply = self._link.command(self.name, request)
        self.update(reply.status)
        return reply.seq

    def __repr__(self) -> str:
        return f"<brain of {self.name} (in its own process)>"


class _NodeStandIn:
    def __init__(self, stack: "RemoteStack") -> None:
        self._stack = stack

    @property
    def stats(self):
        return self._stack.report().node

    def neighbours(self) -> list:
        return list(self._stack.report().neighbours)


class RemoteStack:
    """A robot's network stack as the radio medium sees it (transport.sim_medium.NetworkStack), and
    its counters for reports (`node.stats`, `node.neighbours()`, `hops_histogram`): one Report
    request, kept until the next tick."""

    def __init__(self, link, robot: str, address: int) -> None:
        self._link, self._robot, self.address = link, robot, address
        self._pending: list = []
        self._timer: float | None = None
        self._report: msg.ReportReply | None = None
        self.node = _NodeStandIn(self)

    def prime(self, transmissions: list, timer: float | None) -> None:
        """What the robot's stack answered last: handed out by the next transmissions() and get_timer()."""
        self._pending = list(transmissions)
        self._timer = timer
        self._report = None

    def report(self) -> msg.ReportReply:
        if self._report is None:
            self._report = self._link.report(self._robot)
        return self._report

    @property
    def hops_histogram(self) -> Counter:
        return Counter(self.report().hops_histogram)

    @property
    def robot(self) -> str:
        return self._robot

    def receive(self, data: bytes, now: float, *, rssi_dbm: float | None = None,
                relay_delay_s: float = 0.0) -> bool | None:
        request = msg.Receive(data, now, rssi_dbm, relay_delay_s)
        if self._link.batching:  # one arrival to all its receivers at once: the medium collects us after
            self._link.deliver_later(self, request)
            return False
        self.prime(*self._link.call_stack(self._robot, request))
        return None

    def handle_timer(self, now: float) -> None:
        self.prime(*self._link.call_stack(self._robot, msg.Timer(now)))

    def transmissions(self, now: float) -> list:
        pending = self._pending
        self._pending = []
        return pending

    def get_timer(self) -> float | None:
        return self._timer
