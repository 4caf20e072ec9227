"""One robot as its own process: brain, navigation, endpoint, mesh node and its Body, stepped by a
world process in lockstep over the control plane (runtime/control.py).

Owns: what a robot process holds and answers (set-up, tick, flush, a frame heard, a timer, reads
and calls into its brain for scenarios and reports), the RemoteBody the world feeds, and the
process's life: waiting for the world, halting and leaving when the world is gone.
Must not know: MuJoCo (the world process owns physics, sensors and the radio medium), scenarios.

A tick from the world carries the simulated time and this robot's body state (pose, odometry, the
latest scan); the robot steps its brain and answers with what the stack has to send, its next timer
and the wheel command. A flush, only after the mission script called into this robot, asks again. Every call into the network stack answers with the stack's
new transmissions and timer, so the world's radio medium runs exactly as it does in one process.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import os
import queue
import signal
import sys
import time
from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from rescuemesh.body import Body, LaserScan, NoRendererError, RobotKind
from rescuemesh.geometry import Pose2D
from rescuemesh.maps import MapModel
from rescuemesh.nav import Costmap
from rescuemesh.runtime.assembly import assemble_robot, team_sealer
from rescuemesh.runtime.config import SimConfig
from rescuemesh.runtime.control import Answer, Call, CallServer, ControlError, Keys, Liveliness, open_session

#: A robot that hears nothing from its world this long (s) halts and leaves.
IDLE_TIMEOUT_S = 60.0


@dataclass(frozen=True)
class BodyState:
    """What the world tells a robot about its body at a tick. `scan` is None when unchanged."""

    pose: Pose2D
    odometry: tuple[Pose2D, float, float]
    scan: LaserScan | None


@dataclass(frozen=True)
class RobotSetup:
    """What a robot process is told when it joins: who it is, where, on which map, with which
    settings. The team key never travels: `config.team_key` is None, and with `key_from_seed`
    False the robot needs `--key FILE` itself."""

    name: str
    start: Pose2D
    config: SimConfig
    map_model: MapModel
    epoch: int
    kind: RobotKind
    top_height: float | None
    key_from_seed: bool


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


class RobotWorker:
    """Answers the world's calls for one robot. `done` turns True after Call.BYE."""

    def __init__(self, name: str, team_key: bytes | None = None) -> None:
        self.name, self.team_key = name, team_key
        self.brain = self.stack = self.body = None
        self.done = False
        self._handlers = {Call.SETUP: self._setup, Call.TICK: self._tick, Call.FLUSH: self._flush,
                          Call.RECEIVE: self._receive, Call.TIMER: self._timer, Call.GET: self._get,
                          Call.CALL: self._call, Call.STATS: self._stats, Call.BYE: self._bye}

    def handle(self, request: tuple) -> Any:
        kind, *args = request
        if self.brain is None and kind not in (Call.SETUP, Call.STATS, Call.BYE):
            raise ControlError(f"{self.name}: {kind.value} before set-up")
        return self._handlers[kind](*args)

    def halt(self) -> None:
        """Stop the wheels (the world applies the command; a real body would stop now)."""
        if self.body is not None:
            self.body.set_velocity(0.0, 0.0)

    def _setup(self, setup: RobotSetup):
        if setup.name != self.name:
            raise ControlError(f"set-up for {setup.name} reached {self.name}")
        config = setup.config
        if self.team_key is not None:
            config = replace(config, team_key=self.team_key)
        elif not setup.key_from_seed and config.secure:
            raise ControlError(f"{self.name}: this world uses a team key file: start the robot with --key FILE")
        self.body = RemoteBody(self.name, setup.start, setup.kind, setup.top_height)
        self.brain, self.stack = assemble_robot(self.name, self.body, Costmap(setup.map_model.grid), config,
                                                team_sealer(config),
                                                setup.map_model.bases.get(self.name, setup.start), epoch=setup.epoch)
        return self.stack.get_timer()

    def _tick(self, now: float, state: BodyState):
        """Step the brain and answer as a flush would: the world needs no flush unless the mission
        script calls into this robot before the tick ends (the frames answered here are the world's)."""
        self.body.update(state)
        self.brain.step(now)
        return self._flush(now)

    def _flush(self, now: float):
        return self.stack.transmissions(now), self.stack.get_timer(), self.body.command

    def _receive(self, data: bytes, now: float, rssi_dbm: float | None, relay_delay_s: float):
        self.stack.receive(data, now, rssi_dbm=rssi_dbm, relay_delay_s=relay_delay_s)
        return self.stack.transmissions(now), self.stack.get_timer()

    def _timer(self, at: float):
        self.stack.handle_timer(at)
        return self.stack.transmissions(at), self.stack.get_timer()

    def _resolve(self, path: tuple[str, ...]):
        roots = {"brain": self.brain, "stack": self.stack, "body": self.body}
        if not path or path[0] not in roots or any(p.startswith("_") for p in path):
            raise AttributeError(f"no public attribute {'.'.join(path)!r} on {self.name}")
        value = roots[path[0]]
        for part in path[1:]:
            value = getattr(value, part)
        return value

    def _get(self, path: tuple[str, ...]):
        """(Answer.VALUE, v) for data (is_data), (Answer.CALLABLE, None) for a method, (Answer.REFERENCE,
        None) for any other object: a behaviour with its navigation and costmap stays here, and the
        world reads what it needs of it."""
        value = self._resolve(path)
        if callable(value):
            return Answer.CALLABLE, None
        return (Answer.VALUE, value) if is_data(value) else (Answer.REFERENCE, None)

    def _call(self, path: tuple[str, ...], args: tuple, kwargs: dict):
        return self._resolve(path)(*args, **kwargs)

    @staticmethod
    def _stats() -> dict:
        return {"pid": os.getpid(), "cpu_s": round(time.process_time(), 3)}

    def _bye(self) -> None:
        self.halt()
        self.done = True


#: Values that are data by themselves.
_SCALARS = (type(None), bool, int, float, complex, str, bytes, enum.Enum, np.generic)
#: Arrays up to this many elements count as data (a scan, a path); larger ones stay in the robot.
_MAX_ARRAY_ELEMENTS = 1 << 16


def is_data(value, depth: int = 0) -> bool:
    """Whether `value` is plain data worth copying to the world: scalars, enums, small arrays, and
    lists, tuples, sets, dicts and dataclasses of data, nested at most 8 deep."""
    if isinstance(value, _SCALARS):
        return True
    if depth >= 8:
        return False
    if isinstance(value, np.ndarray):
        return value.size <= _MAX_ARRAY_ELEMENTS and value.dtype != object
    if isinstance(value, (list, tuple, set, frozenset, deque)):
        return all(is_data(item, depth + 1) for item in value)
    if isinstance(value, dict):
        return all(is_data(k, depth + 1) and is_data(v, depth + 1) for k, v in value.items())
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return all(is_data(getattr(value, f.name), depth + 1) for f in dataclasses.fields(value))
    return False


def _terminate(signum, frame):
    raise SystemExit(0)


def serve_robot(name: str, connect: str, *, run: str = "default", team_key: bytes | None = None,
                wait_s: float = 30.0, idle_timeout_s: float = IDLE_TIMEOUT_S, out=sys.stdout) -> int:
    """Run robot `name` for the world at `connect` until the world says bye or is gone. Returns the
    exit status: 0 after bye or when the world left, 1 when no world was found."""
    keys = Keys(run)
    signal.signal(signal.SIGTERM, _terminate)
    session = open_session(connect=[connect])
    worker = RobotWorker(name, team_key)
    server = CallServer(session, keys.robot_rpc(name))
    world = Liveliness(session, keys.world_alive, on_change=lambda key, up: None if up else server.wake("world gone"))
    token = None
    try:
        if not world.wait_for(bool, wait_s):
            print(f"{name}: no world process at {connect} (run {run!r}) after {wait_s:g} s", file=sys.stderr)
            return 1
        token = session.liveliness().declare_token(keys.robot_alive(name))
        print(f"{name}: joined the world at {connect} (run {run!r})", file=out, flush=True)
        while not worker.done:
            try:
                item = server.inbox.get(timeout=idle_timeout_s)
            except queue.Empty:
                item = f"no call from the world in {idle_timeout_s:g} s"
            if isinstance(item, str):
                print(f"{name}: {item}: wheels halted, leaving", file=out, flush=True)
                break
            CallServer.answer(item, worker.handle)
        else:
            print(f"{name}: the world's run is over: wheels halted, leaving", file=out, flush=True)
        return 0
    except KeyboardInterrupt:
        print(f"{name}: interrupted: wheels halted, leaving", file=out, flush=True)
        return 0
    finally:
        worker.halt()
        if token is not None:
            token.undeclare()
        world.close()
        server.close()
        session.close()
