"""The world as its own process: physics, sensors and the radio medium here, each robot in its own
process, stepped in lockstep over Zenoh (runtime/control.py).

Owns: the world's Zenoh host (its endpoint, liveliness token, the robots' tokens, the published
clock) and ProcessRuntime: SimRuntime's
loop with robots that are stand-ins (runtime/remote.py), robots that die and join again.
Must not know: scenarios' scripts and criteria, plots, what a brain does inside.

A tick at time t: the world steps to t, the medium delivers what is due (each frame heard is one call
to its robot), every live robot steps its brain and answers what it sends and how its wheels turn
(one call each, all at once), the mission script runs (its reads and calls go to the robots), a robot
the script called into is asked again what it sends, and the medium takes the frames. Same seed, same run as
in one process. A robot whose process is gone keeps its body in the world with the wheels stopped and
its radio silent; when a process for it joins again it is set up afresh with the next boot epoch.
"""

from __future__ import annotations

import os
import struct
import threading
import time
from collections import Counter
from dataclasses import replace

from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel
from rescuemesh.robot import robot_address
from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.control import Call, CallClient, ControlError, Keys, Liveliness, open_session
from rescuemesh.runtime.remote import RemoteObject, RemoteStack, RobotGone
from rescuemesh.runtime.robot_process import BodyState, RobotSetup
from rescuemesh.runtime.sim_loop import SimRuntime, _position_of

#: How long the world waits for its robots to join, in s.
JOIN_TIMEOUT_S = 60.0


class WorldHost:
    """The world's Zenoh side: a session listening at `listen`, the world's liveliness token, the
    robots' tokens as join and leave events, calls to robots, and the clock."""

    def __init__(self, listen: str, run: str = "default") -> None:
        self.listen, self.keys = listen, Keys(run)
        self.session = open_session(listen=[listen])
        self._events: list[tuple[str, bool]] = []
        self._lock = threading.Lock()
        self.robots = Liveliness(self.session, self.keys.robots_alive, on_change=self._changed)
        self.client = CallClient(self.session, self.keys)
        self._clock = self.session.declare_publisher(self.keys.clock)
        self._token = self.session.liveliness().declare_token(self.keys.world_alive)

    def _changed(self, key: str, up: bool) -> None:
        with self._lock:
            self._events.append((Keys.robot_of(key), up))

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

    def publish_clock(self, now: float) -> None:
        """Simulated time, like ROS's /clock: a little-endian float64 of seconds."""
        self._clock.put(struct.pack("<d", now))

    def close(self) -> None:
        for part in (self._token, self._clock):
            part.undeclare()
        self.robots.close()
        self.session.close()


class ProcessRuntime(SimRuntime):
    """SimRuntime with every robot in its own process. `rt.brains[name]` and `rt.stacks[name]` are
    stand-ins that read from and call into the robot (runtime/remote.py)."""

    def __init__(self, map_model: MapModel, starts: dict[str, Pose2D], config: SimConfig, host: WorldHost, *,
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
        self.time = 0.0
        super().__init__(map_model, starts, config)

    # --- the team ------------------------------------------------------------------------------

    def _make_team(self, starts: dict[str, Pose2D]) -> None:
        if not self.host.wait_for(starts, self.join_timeout_s):
            missing = sorted(set(starts) - self.host.alive())
            raise ControlError(f"robot processes did not join within {self.join_timeout_s:g} s: {', '.join(missing)} "
                               f"(start each with: rescuemesh robot --name NAME --connect {self.host.listen})")
        self.host.take_events()  # the joins just waited for
        for name in starts:
            self.brains[name] = RemoteObject(self, name, ("brain",))
            self.stacks[name] = RemoteStack(self, name, robot_address(name))
            self.medium.attach(robot_address(name), self.stacks[name], _position_of(self.world.bodies[name]))
            self._join(name)

    def _join(self, name: str) -> None:
        body = self.world.bodies[name]
        setup = RobotSetup(name, self.starts[name], replace(self.config, team_key=None), self.map,
                           epoch=self.joins[name], kind=body.kind, top_height=body.top_height,
                           key_from_seed=self.key_from_seed)
        timer = self.host.client.call(name, (Call.SETUP, setup))
        self.stacks[name].prime([], timer)
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

    # --- calls, as runtime/remote.py's stand-ins make them -------------------------------------

    def call(self, robot: str, request: tuple):
        if robot not in self.live:
            raise RobotGone(f"{robot}'s process is gone")
        if request[0] is Call.CALL:
            self._called.add(robot)
        try:
            return self.host.client.call(robot, request)
        except ControlError as error:
            self._lose(robot, str(error))
            raise RobotGone(f"{robot}'s process is gone: {error}") from None

    def call_stack(self, robot: str, request: tuple):
        try:
            return self.call(robot, request)
        except RobotGone:
            return [], None

    def _call_live(self, requests: dict[str, tuple]) -> dict:
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
        self._ticked = self._call_live({name: (Call.TICK, now, self._body_state(name)) for name in sorted(self.live)})
        self._called.clear()

    def _collect_robots(self, now: float) -> None:
        """What each robot sends and its wheel command: the tick's answer, and for a robot the mission
        script called into since, what that added (one pop of the stack at `now` split in two: the
        frames come out in the same order)."""
        again = self._call_live({name: (Call.FLUSH, now) for name in sorted(self._called & set(self._ticked))})
        for name, (transmissions, timer, command) in self._ticked.items():
            if name in again:
                more, timer, command = again[name]
                transmissions = transmissions + more
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
        for name, answer in sorted(self._call_live({n: (Call.STATS,) for n in sorted(self.live)}).items()):
            rows.append({"name": name, **answer, "joins": self.joins[name]})
        for name in sorted(set(self.brains) - self.live):
            rows.append({"name": name, "pid": None, "cpu_s": None, "joins": self.joins[name]})
        return rows

    def close(self) -> None:
        """Tell every live robot to halt and leave."""
        if self.live:
            self.host.client.call_all({name: (Call.BYE,) for name in sorted(self.live)}, tolerate=True)
            self.live.clear()
