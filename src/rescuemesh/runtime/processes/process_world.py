"""The world as its own process: physics, sensors and the radio medium here, each robot in its own
process, stepped in lockstep over the control plane (runtime/processes/control.py): Zenoh, or pipes to
robot processes this world started (runtime/processes/pipes.py).

Owns: the world's Zenoh host (its endpoint, liveliness token, the robots' tokens, the published
clock, its control key) and ProcessRuntime: SimRuntime's loop with robots that are stand-ins
(runtime/processes/remote.py), robots that join (proving the control key), die and join again.
Must not know: scenarios' scripts and criteria, plots, what a brain does inside.

A tick at time t: the world steps to t, the medium delivers what is due (a frame that ends on the air
goes to all the robots that hear it in one parallel round, runtime/processes/lockstep_medium.py; each
stack timer is one call), every live robot steps its
brain and answers what it sends, how its wheels turn and what changed in its status (one call each,
all at once), the mission script runs (its reads come from that status, its commands go to the
robots), a robot the script commanded is asked again what it sends, and the medium takes the frames.
Same seed, same run as in one process. A robot whose process is gone keeps its body in the world with
the wheels stopped and its radio silent; when a process for it joins again it is set up afresh with
the next boot epoch. A liveliness token alone admits nobody: a robot joins when it answers the
set-up authenticated with the run's control key.
"""

from __future__ import annotations

import os
import struct
import sys
import threading
import time
from collections import Counter
from dataclasses import replace

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel
from rescuemesh.robot import robot_address
from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.processes import control_messages as msg
from rescuemesh.runtime.processes.control import (
    PUBLIC_CONTROL_KEY,
    CallClient,
    ControlError,
    ControlKey,
    Keys,
    Liveliness,
    control_key_from_team_key,
    open_session,
)
from rescuemesh.runtime.processes.control_messages import BodyState, RobotSetup
from rescuemesh.runtime.processes.lockstep_medium import LockstepMedium
from rescuemesh.runtime.processes.spawn import ControlCarrier
from rescuemesh.runtime.processes.remote import RemoteBrain, RemoteStack, RobotGone
from rescuemesh.runtime.inprocess.sim_loop import SimRuntime, _position_of

#: How long the world waits for its robots to join, in s.
JOIN_TIMEOUT_S = 60.0
#: How long one try at setting a robot up waits for its answer, in s (a token with no robot behind it
#: costs this, then the world tries again until the join timeout).
SETUP_TIMEOUT_S = 5.0


def world_control_key(team_key: bytes | None, spawned_key: bytes | None, *, out=sys.stderr) -> bytes:
    """The run's control key: from the team key file's key; else the fresh key of the robot processes
    this run spawned; else (robots started by hand, no key file) the public key, with a warning."""
    if team_key is not None:
        return control_key_from_team_key(team_key)
    if spawned_key is not None:
        return spawned_key
    print("world: no --key: the control plane uses the public development key; anyone who can reach "
          "the endpoint can join as a robot (give the world and each robot --key FILE)", file=out)
    return PUBLIC_CONTROL_KEY


class WorldHost:
    """The world's Zenoh side: a session listening at `listen`, the world's liveliness token, the
    robots' tokens as join and leave events, calls to robots, and the clock."""

    def __init__(self, listen: str, run: str = "default", *, control_key: bytes = PUBLIC_CONTROL_KEY) -> None:
        self.listen, self.keys = listen, Keys(run)
        self.join_hint = f"start each with: rescuemesh robot --name NAME --connect {listen}"
        self.carrier = ControlCarrier.ZENOH
        self.session = open_session(listen=[listen])
        self._events: list[tuple[str, bool]] = []
        self._lock = threading.Lock()
        self.client = CallClient(self.session, self.keys, ControlKey(control_key))
        self.robots = Liveliness(self.session, self.keys.robots_alive, on_change=self._changed)
        self._clock = self.session.declare_publisher(self.keys.clock)
        self._token = self.session.liveliness().declare_token(self.keys.world_alive)

    def _changed(self, key: str, up: bool) -> None:
        with self._lock:
            self._events.append((Keys.robot_of(key), up))
        if not up:
            self.client.gone(Keys.robot_of(key))

    def take_events(self) -> list[tuple[str, bool]]:
        """Robots that joined (True) or left (False) since the last call, in order."""
        with self._lock:
            events, self._events = self._events, []
        return events

    def alive(self) -> set[str]:
        return {Keys.robot_of(key) for key in self.robots.alive}

    def wait_for(self, names, timeout_s: float) -> bool:
        wanted = {self.keys.robot_alive(n) for n in names}
        return self.robots.wait_for(lambda alive: wanted <= alive, timeout_s)

    def wait_for_any(self, names, timeout_s: float) -> bool:
        wanted = {self.keys.robot_alive(n) for n in names}
        return self.robots.wait_for(lambda alive: bool(wanted & alive), timeout_s)

    def publish_clock(self, now: float) -> None:
        """Simulated time, like ROS's /clock: a little-endian float64 of seconds."""
        self._clock.put(struct.pack("<d", now))

    def close(self) -> None:
        for part in (self._token, self._clock):
            part.undeclare()
        self.robots.close()
        self.client.close()
        self.session.close()


class ProcessRuntime(SimRuntime):
    """SimRuntime with every robot in its own process. `rt.brains[name]` and `rt.stacks[name]` are
    stand-ins that read from and call into the robot (runtime/processes/remote.py). `host` carries
    the calls: a WorldHost (Zenoh: robots started anywhere) or a PipeHost (runtime/processes/pipes.py:
    robots this world started)."""

    medium_class = LockstepMedium

    def __init__(self, map_model: MapModel, starts: dict[str, Pose2D], config: SimConfig, host, *,
                 key_from_seed: bool = True, join_timeout_s: float = JOIN_TIMEOUT_S) -> None:
        self.host, self.key_from_seed, self.join_timeout_s = host, key_from_seed, join_timeout_s
        self.starts = dict(starts)
        self.live: set[str] = set()
        self.joins: Counter[str] = Counter()
        self.process_log: list[tuple[float, str, str]] = []  # (time s, robot, what happened)
        self._lost_now: set[str] = set()
        self._sent_scan: dict[str, object] = {}
        self._ticked: dict[str, tuple] = {}  # this tick's answers: (transmissions, timer, wheel command)
        self._called: set[str] = set()  # robots the mission script called into since the tick
        self._batch: list | None = None  # one arrival's deliveries: (stand-in, request), in the medium's order
        self.time = 0.0
        super().__init__(map_model, starts, config)
        self.medium.deliveries = self

    # --- the team ------------------------------------------------------------------------------

    def _make_team(self, starts: dict[str, Pose2D]) -> None:
        for name in starts:
            self.stacks[name] = stack = RemoteStack(self, name, robot_address(name))
            self.brains[name] = RemoteBrain(self, name, robot_address(name), self.world.bodies[name], stack)
            self.medium.attach(robot_address(name), stack, _position_of(self.world.bodies[name]))
        deadline = time.monotonic() + self.join_timeout_s
        why: dict[str, str] = {}
        waiting = list(starts)
        while waiting:
            left = deadline - time.monotonic()
            if left <= 0:
                missing = ", ".join(f"{n} ({why[n]})" if n in why else n for n in waiting)
                raise ControlError(f"robot processes did not join within {self.join_timeout_s:g} s: {missing} "
                                   f"({self.host.join_hint})")
            self.host.wait_for_any(waiting, min(left, 1.0))
            alive = self.host.alive()
            for name in [n for n in waiting if n in alive]:
                try:
                    self._join(name, timeout_s=min(SETUP_TIMEOUT_S, max(0.5, deadline - time.monotonic())))
                    waiting.remove(name)
                except ControlError as error:
                    why[name] = str(error)
            if waiting:
                time.sleep(0.2)  # a token with no robot that answers: try again soon, not in a busy loop
        self.host.take_events()  # the joins just made

    def _join(self, name: str, *, timeout_s: float | None = None) -> None:
        """Set robot `name` up: it must answer with the run's control key (Hello, then the set-up
        that echoes its process's nonce)."""
        body = self.world.bodies[name]
        client = self.host.client
        client.expect(name)
        hello = client.call(name, msg.Hello(), timeout_s=timeout_s or SETUP_TIMEOUT_S)
        setup = RobotSetup(name, self.starts[name], replace(self.config, team_key=None), self.map.grid,
                           epoch=self.joins[name], kind=body.kind, top_height=body.top_height,
                           key_from_seed=self.key_from_seed, robot_nonce=hello.robot_nonce,
                           base=self.map.bases.get(name, self.starts[name]))
        timer = client.call(name, setup, timeout_s=timeout_s or SETUP_TIMEOUT_S).timer
        self.stacks[name].prime([], timer)
        self.brains[name].reset()
        self._sent_scan.pop(name, None)
        self.live.add(name)
        if self.joins[name]:
            self.medium.set_radio_enabled(robot_address(name), True, self.time)
            self.process_log.append((self.time, name, f"process joined again (boot epoch {self.joins[name]})"))
        self.joins[name] += 1

    def _lose(self, name: str, reason: str) -> None:
        if name in self.live:
            self.live.discard(name)
            self._lost_now.add(name)
            self.stacks[name].prime([], None)
            self.process_log.append((self.time, name, f"process lost: {reason}"))

    def _membership(self) -> None:
        """Apply joins and losses seen since the last tick (outside the medium's pump)."""
        for name, up in self.host.take_events():
            if name not in self.brains:
                continue
            if not up:
                self._lose(name, "its liveliness token is gone")
            elif name not in self.live:
                try:
                    self._join(name)
                except ControlError as error:
                    self._lose(name, f"set-up failed: {error}")
        for name in self._lost_now:
            self.medium.set_radio_enabled(robot_address(name), False, self.time)
            self.world.bodies[name].set_velocity(0.0, 0.0)
        self._lost_now.clear()

    # --- calls, as runtime/processes/remote.py's stand-ins make them -------------------------------------

    def check_live(self, robot: str) -> None:
        if robot not in self.live:
            raise RobotGone(f"{robot}'s process is gone")

    def call(self, robot: str, request):
        self.check_live(robot)
        try:
            return self.host.client.call(robot, request)
        except ControlError as error:
            self._lose(robot, str(error))
            raise RobotGone(f"{robot}'s process is gone: {error}") from None

    def command(self, robot: str, request) -> msg.CommandReply:
        """A mission script's command: the robot is flushed again before the medium takes its frames."""
        self._called.add(robot)
        return self.call(robot, request)

    def report(self, robot: str) -> msg.ReportReply:
        return self.call(robot, msg.Report())

    def call_stack(self, robot: str, request):
        try:
            reply = self.call(robot, request)
        except RobotGone:
            return [], None
        return reply.transmissions, reply.timer

    # --- one arrival: the frame to every robot that hears it at once (runtime/processes/lockstep_medium.py)

    @property
    def batching(self) -> bool:
        return self._batch is not None

    def begin(self) -> None:
        self._batch = []

    def deliver_later(self, stack, request) -> None:
        """A stand-in's receive() while an arrival is delivered: sent with the others at end()."""
        self._batch.append((stack, request))

    def end(self) -> list:
        """Send the arrival's requests to their robots together, take every answer, prime each stand-in
        with its robot's answer (nothing, for a robot whose process is gone), and return the stand-ins
        in the order the medium visited them."""
        batch, self._batch = self._batch, None
        requests = {stack.robot: request for stack, request in batch if stack.robot in self.live}
        answers = self._call_live(requests) if requests else {}
        for stack, _ in batch:
            answer = answers.get(stack.robot)
            if answer is None:  # its process is gone (or went during this round)
                stack.prime([], None)
            else:
                stack.prime(answer.transmissions, answer.timer)
        return [stack for stack, _ in batch]

    def _call_live(self, requests: dict) -> dict:
        answers = self.host.client.call_all(requests, tolerate=True)
        for name, answer in list(answers.items()):
            if isinstance(answer, ControlError):
                self._lose(name, str(answer))
                del answers[name]
        return answers

    # --- the loop's hooks ----------------------------------------------------------------------

    def step(self, script=None) -> None:
        self._membership()
        super().step(script)

    def _step_robots(self, now: float) -> None:
        self._ticked = self._call_live({name: msg.Tick(now, self._body_state(name)) for name in sorted(self.live)})
        for name, reply in self._ticked.items():
            self.brains[name].update(reply.status)
        self._called.clear()

    def _collect_robots(self, now: float) -> None:
        """What each robot sends and its wheel command: the tick's answer, and for a robot the mission
        script called into since, what that added (one pop of the stack at `now` split in two: the
        frames come out in the same order)."""
        again = self._call_live({name: msg.Flush(now) for name in sorted(self._called & set(self._ticked))})
        for name, reply in self._ticked.items():
            transmissions, timer, command = reply.transmissions, reply.timer, reply.command
            if name in again:
                more = again[name]
                self.brains[name].update(more.status)
                transmissions, timer, command = transmissions + more.transmissions, more.timer, more.command
            elif name in self._called:
                continue  # lost since the tick
            self.stacks[name].prime(transmissions, timer)
            self.world.bodies[name].set_velocity(*command)
        self._ticked = {}
        self.host.publish_clock(now)

    def _body_state(self, name: str) -> BodyState:
        body = self.world.bodies[name]
        scan = body.scan()
        fresh = scan if scan is not self._sent_scan.get(name) else None
        self._sent_scan[name] = scan
        return BodyState(body.pose(), body.odometry(), fresh)

    # --- the end -------------------------------------------------------------------------------

    def processes(self) -> list[dict]:
        """Each process of the run: name, pid, CPU time in s (the robots' as they report it)."""
        rows = [{"name": "world", "pid": os.getpid(), "cpu_s": round(time.process_time(), 3)}]
        for name, answer in sorted(self._call_live({n: msg.Stats() for n in sorted(self.live)}).items()):
            rows.append({"name": name, "pid": answer.pid, "cpu_s": answer.cpu_s, "joins": self.joins[name]})
        for name in sorted(set(self.brains) - self.live):
            rows.append({"name": name, "pid": None, "cpu_s": None, "joins": self.joins[name]})
        return rows

    def control_plane(self) -> dict:
        """The requests the world sent its robots, by type, and the rounds it waited for (one request,
        or one parallel round to several robots), over the whole run."""
        client = self.host.client
        return {"carrier": self.host.carrier.value, "requests": dict(sorted(client.requests.items())), "rounds": dict(sorted(client.rounds.items())),
                "ticks": self.ticks}

    def close(self) -> None:
        """Tell every live robot to halt and leave."""
        if self.live:
            self.host.client.call_all({name: msg.Bye() for name in sorted(self.live)}, tolerate=True)
            self.live.clear()
