"""One robot as its own process: brain, navigation, endpoint, mesh node and its Body, stepped by a
world process in lockstep over the control plane (runtime/processes/control.py).

Owns: what a robot process answers to each typed request (runtime/processes/control_messages.py: set-up, tick,
flush, a frame heard, a timer, the mission's commands, report, stats, bye), the status it sends with
every reply (what changed in its brain since the last one), the RemoteBody the world feeds, and the
process's life: waiting for the world, halting and leaving when the world is gone.
Must not know: MuJoCo (the world process owns physics, sensors and the radio medium), scenarios.

A tick from the world carries the simulated time and this robot's body state (pose, odometry, the
latest scan); the robot steps its brain and answers with what the stack has to send, its next timer,
the wheel command and its status. A flush, only after the mission script called into this robot,
asks again. Every call into the network stack answers with the stack's new transmissions and timer,
so the world's radio medium runs exactly as it does in one process. There is no request to read or
call anything by name.
"""

from __future__ import annotations

import math
import os
import queue
import signal
import sys
import time
from dataclasses import replace

from rescuemesh.body import Body, LaserScan, NoRendererError, RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.nav import Costmap
from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.assembly import assemble_robot, team_sealer
from rescuemesh.runtime.processes.control import (
    CONTROL_KEY_ENV,
    PUBLIC_CONTROL_KEY,
    Answerer,
    CallServer,
    ControlError,
    ControlKey,
    Keys,
    Liveliness,
    control_key_from_team_key,
    open_session,
)
from rescuemesh.runtime.processes.control_messages import BodyState, RobotSetup

__all__ = ["BodyState", "IDLE_TIMEOUT_S", "RemoteBody", "RobotSetup", "RobotWorker", "StatusTracker", "serve_robot",
           "serve_robot_over_pipes"]

#: A robot that hears nothing from its world this long (s) halts and leaves.
IDLE_TIMEOUT_S = 60.0


class RemoteBody(Body):
    """A Body whose state the world sends each tick and whose wheel command goes back at flush."""

    def __init__(self, name: str, start: Pose2D, kind: RobotKind, top_height: float | None) -> None:
        if kind is not RobotKind.GROUND:
            raise ControlError(f"{name}: only ground robots run as processes so far (a {kind.value} robot does not)")
        self.name, self.kind, self.top_height = name, kind, top_height
        self._pose, self._odometry, self._scan = start, (start, 0.0, 0.0), None
        self.command = (0.0, 0.0)

    def update(self, state: BodyState) -> None:
        self._pose, self._odometry = state.pose, state.odometry
        if state.scan is not None:
            self._scan = state.scan

    def pose(self) -> Pose2D:
        return self._pose

    def odometry(self) -> tuple[Pose2D, float, float]:
        return self._odometry

    def scan(self) -> LaserScan | None:
        return self._scan

    def camera(self):
        raise NoRendererError("camera images are not carried between processes (run in one process for ShowCam)")

    def set_velocity(self, linear: float, angular: float) -> None:
        if not (math.isfinite(linear) and math.isfinite(angular)):
            raise ValueError(f"{self.name}: velocity command must be finite, got ({linear}, {angular})")
        self.command = (float(linear), float(angular))


class StatusTracker:
    """What changed in a brain's status since the last delta: the running behaviour, behaviours
    finished, commands sent or updated, log lines, bulk data received, commands given up, the peers'
    announced capabilities."""

    def __init__(self, brain) -> None:
        self.brain = brain
        self._running = None
        self._finished = self._log = self._failed = 0
        self._outgoing: dict[int, tuple] = {}
        self._received = (0, None)
        self._capabilities: dict = {}

    def delta(self) -> msg.StatusDelta:
        brain = self.brain
        running = brain.running
        running_changed = running is not self._running
        view = None
        if running_changed:
            self._running = running
            if running is not None:
                behaviour = running.behaviour
                view = msg.RunningView(behaviour.name, running.started_s, _waypoints(behaviour, "waypoints"),
                                       _waypoints(behaviour, "skipped"))
        finished = brain.finished[self._finished:]
        self._finished += len(finished)
        outgoing = []
        for seq, command in brain.outgoing.items():
            key = (command.result, command.reason, command.sends, command.hops, command.failed)
            if self._outgoing.get(seq) != key:
                self._outgoing[seq] = key
                outgoing.append(command)
        log = brain.log  # a ring (robot/records.py BrainLog): `total` counts what it dropped too
        new = log.since(self._log) if log.total > self._log else []
        self._log = log.total
        received = brain.received_data
        key = (len(received), received[-1] if received else None)
        received_data = None
        if key[0] != self._received[0] or key[1] is not self._received[1]:
            self._received = key
            received_data = list(received)
        failed = brain.commands_failed
        capabilities = None
        if brain.peer_capabilities != self._capabilities:
            self._capabilities = capabilities = dict(brain.peer_capabilities)
        return msg.StatusDelta(running_changed, view, list(finished), outgoing, new, received_data, failed, capabilities)


def _waypoints(behaviour, name: str):
    value = getattr(behaviour, name, None)
    return list(value) if value is not None else None


class RobotWorker:
    """Answers the world's typed requests for one robot. `done` turns True after Bye."""

    def __init__(self, name: str, team_key: bytes | None = None) -> None:
        self.name, self.team_key = name, team_key
        self.brain = self.stack = self.body = self.status = None
        self.done = False
        self._handlers = {msg.RobotSetup: self._setup, msg.Tick: self._tick, msg.Flush: self._flush,
                          msg.Receive: self._receive, msg.Timer: self._timer, msg.NavigateTo: self._navigate_to,
                          msg.Command: self._command, msg.Send: self._send, msg.Report: self._report,
                          msg.Stats: self._stats, msg.Bye: self._bye}

    def handle(self, request):
        handler = self._handlers.get(type(request))
        if handler is None:
            raise ControlError(f"{self.name}: {type(request).__name__} is not a request")
        if self.brain is None and not isinstance(request, (msg.RobotSetup, msg.Stats, msg.Bye)):
            raise ControlError(f"{self.name}: {type(request).__name__} before set-up")
        return handler(request)

    def halt(self) -> None:
        """Stop the wheels (the world applies the command; a real body would stop now)."""
        if self.body is not None:
            self.body.set_velocity(0.0, 0.0)

    def _setup(self, setup: msg.RobotSetup) -> msg.SetupReply:
        if setup.name != self.name:
            raise ControlError(f"set-up for {setup.name} reached {self.name}")
        config = setup.config
        if self.team_key is not None:
            config = replace(config, team_key=self.team_key)
        elif not setup.key_from_seed and config.secure:
            raise ControlError(f"{self.name}: this world uses a team key file: start the robot with --key FILE")
        self.body = RemoteBody(self.name, setup.start, setup.kind, setup.top_height)
        self.brain, self.stack = assemble_robot(self.name, self.body, Costmap(setup.grid), config,
                                                team_sealer(config), setup.base, epoch=setup.epoch)
        self.status = StatusTracker(self.brain)
        return msg.SetupReply(self.stack.get_timer())

    def _tick(self, tick: msg.Tick) -> msg.TickReply:
        """Step the brain and answer as a flush would: the world needs no flush unless the mission
        script calls into this robot before the tick ends (the frames answered here are the world's)."""
        self.body.update(tick.body)
        self.brain.step(tick.now)
        return self._flush(tick)

    def _flush(self, request) -> msg.TickReply:
        now = request.now
        return msg.TickReply(self.stack.transmissions(now), self.stack.get_timer(), self.body.command,
                             self.status.delta())

    def _receive(self, frame: msg.Receive) -> msg.StackReply:
        self.stack.receive(frame.data, frame.now, rssi_dbm=frame.rssi_dbm, relay_delay_s=frame.relay_delay_s)
        return msg.StackReply(self.stack.transmissions(frame.now), self.stack.get_timer())

    def _timer(self, timer: msg.Timer) -> msg.StackReply:
        self.stack.handle_timer(timer.now)
        return msg.StackReply(self.stack.transmissions(timer.now), self.stack.get_timer())

    def _navigate_to(self, request: msg.NavigateTo) -> msg.CommandReply:
        self.brain.navigate_to(request.goal, request.now)
        return msg.CommandReply(None, self.status.delta())

    def _command(self, request: msg.Command) -> msg.CommandReply:
        brain, kind, peer, now = self.brain, request.kind, request.peer, request.now
        if kind is msg.CommandKind.GOTO:
            if request.goal is None:
                raise ControlError("a Goto command needs its goal")
            seq = brain.command_goto(peer, request.goal, now)
        elif kind is msg.CommandKind.MOVE_AROUND:
            if request.radius_m is None:
                raise ControlError("a MoveAround command needs its radius")
            seq = brain.command_move_around(peer, request.radius_m, now)
        else:
            seq = {msg.CommandKind.RETURN: brain.command_return, msg.CommandKind.FOLLOW: brain.command_follow,
                   msg.CommandKind.STOP: brain.command_stop}[kind](peer, now)
        return msg.CommandReply(seq, self.status.delta())

    def _send(self, request: msg.Send) -> msg.CommandReply:
        seq = self.brain.send(request.peer, request.message, request.now)
        return msg.CommandReply(seq, self.status.delta())

    def _report(self, request: msg.Report) -> msg.ReportReply:
        node = self.stack.node
        return msg.ReportReply(self.brain.endpoint.stats, node.stats, dict(self.stack.hops_histogram),
                               list(node.neighbours()))

    @staticmethod
    def _stats(request: msg.Stats) -> msg.StatsReply:
        return msg.StatsReply(os.getpid(), round(time.process_time(), 3))

    def _bye(self, request: msg.Bye) -> msg.Done:
        self.halt()
        self.done = True
        return msg.Done()


def _terminate(signum, frame):
    raise SystemExit(0)


def _say_leaving(name: str, why: str | None, refused: int, out) -> None:
    """A robot's last lines: why it leaves (None: the world said bye) and what it refused."""
    why = "the world's run is over" if why is None else why
    print(f"{name}: {why}: wheels halted, leaving", file=out, flush=True)
    if refused:
        print(f"{name}: {refused} control messages refused", file=out, flush=True)


def control_key_for(team_key: bytes | None) -> ControlKey:
    """The control key a robot process proves itself with: from its team key file; else the one its
    parent put in the environment (`run --processes`: a fresh key per run); else the public one."""
    if team_key is not None:
        return ControlKey(control_key_from_team_key(team_key))
    given = os.environ.pop(CONTROL_KEY_ENV, None)
    if given:
        try:
            return ControlKey(bytes.fromhex(given))
        except ValueError:
            raise ControlError(f"{CONTROL_KEY_ENV} is not a hex key of at least 16 bytes") from None
    return ControlKey(PUBLIC_CONTROL_KEY)


def serve_robot(name: str, connect: str, *, run: str = "default", team_key: bytes | None = None,
                wait_s: float = 30.0, idle_timeout_s: float = IDLE_TIMEOUT_S, out=sys.stdout) -> int:
    """Run robot `name` for the world at `connect` until the world says bye or is gone. Returns the
    exit status: 0 after bye or when the world left, 1 when no world was found. Requests are answered
    on Zenoh's thread as they come; this thread waits for the end (bye, the world gone, a signal)."""
    keys = Keys(run)
    control_key = control_key_for(team_key)
    signal.signal(signal.SIGTERM, _terminate)
    session = open_session(connect=[connect])
    worker = RobotWorker(name, team_key)
    events: queue.Queue = queue.Queue()

    def handle(request):
        reply = worker.handle(request)
        if worker.done:
            events.put("bye")
        return reply

    server = CallServer(session, keys, name, control_key, handle)
    world = Liveliness(session, keys.world_alive, on_change=lambda key, up: None if up else events.put("world gone"))
    token = None
    try:
        if not world.wait_for(bool, wait_s):
            print(f"{name}: no world process at {connect} (run {run!r}) after {wait_s:g} s", file=sys.stderr)
            return 1
        token = session.liveliness().declare_token(keys.robot_alive(name))
        print(f"{name}: joined the world at {connect} (run {run!r})", file=out, flush=True)
        calls, quiet_since = server.calls, time.monotonic()
        while True:
            try:
                item = events.get(timeout=min(1.0, idle_timeout_s))
            except queue.Empty:
                if server.calls != calls:
                    calls, quiet_since = server.calls, time.monotonic()
                if time.monotonic() - quiet_since < idle_timeout_s:
                    continue
                item = f"no call from the world in {idle_timeout_s:g} s"
            _say_leaving(name, None if item == "bye" else item, server.refusals.count, out)
            break
        return 0
    except KeyboardInterrupt:
        print(f"{name}: interrupted: wheels halted, leaving", file=out, flush=True)
        return 0
    finally:
        server.close()  # no more requests (one being answered finishes first)
        worker.halt()
        if token is not None:
            token.undeclare()
        world.close()
        session.close()


def serve_robot_over_pipes(name: str, requests_fd: int, replies_fd: int, *, team_key: bytes | None = None,
                           idle_timeout_s: float = IDLE_TIMEOUT_S, out=sys.stdout) -> int:
    """Run robot `name` for the world that started this process and handed it a pair of pipes
    (runtime/processes/pipes.py): requests arrive on `requests_fd`, replies go to `replies_fd`. This
    thread reads and answers each request in turn, until bye, the world's end of the pipe closing,
    no request for `idle_timeout_s`, or a signal. Returns 0 (1 for a stream it cannot read)."""
    from rescuemesh.runtime.processes.pipes import READY, PipeReader, write_frame

    control_key = control_key_for(team_key)
    signal.signal(signal.SIGTERM, _terminate)
    worker = RobotWorker(name, team_key)
    answerer = Answerer(name, control_key, worker.handle)
    requests = PipeReader(requests_fd)
    status = 0
    try:
        write_frame(replies_fd, READY)  # imported and listening: the world may call now
    except OSError:
        requests.close()
        os.close(replies_fd)
        print(f"{name}: world gone before this robot was ready: leaving", file=out, flush=True)
        return 0
    print(f"{name}: joined the world (its control plane: pipes from process {os.getppid()})", file=out, flush=True)
    try:
        while True:
            try:
                request = requests.next(idle_timeout_s)
            except queue.Empty:
                why = f"no call from the world in {idle_timeout_s:g} s"
                break
            except ControlError as error:
                why, status = f"the world's pipe is unreadable: {error}", 1
                break
            if request is None:
                why = "world gone"
                break
            reply = answerer.answer(request)
            if reply is not None:
                try:
                    write_frame(replies_fd, reply)
                except OSError:
                    why = "world gone"
                    break
            if worker.done:
                why = None
                break
        _say_leaving(name, why, answerer.refusals.count, out)
        return status
    except KeyboardInterrupt:
        print(f"{name}: interrupted: wheels halted, leaving", file=out, flush=True)
        return 0
    finally:
        worker.halt()
        requests.close()
        try:
            os.close(replies_fd)
        except OSError:
            pass
