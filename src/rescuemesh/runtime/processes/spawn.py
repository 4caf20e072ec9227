"""Starting and ending robot processes for `rescuemesh run --processes`.

Owns: the options of a run in processes, what carries its control plane (pipes to each robot process,
or Zenoh), picking the world's endpoint, starting `rescuemesh robot` per robot (each told to die with
its parent; over pipes, handed its ends of a pair of pipes), ending them so that none outlives the
run. Must not know: MuJoCo or what the robots do, so that the run can start its robots before it
imports the world (they import and connect meanwhile).
"""

from __future__ import annotations

import ctypes
import enum
import os
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

#: How long robot processes get to leave (after "bye") before they are terminated, then killed, in s.
#: A robot terminated halts and leaves too (SIGTERM): this only spares it the signal.
LEAVE_TIMEOUT_S = 1.0


class ControlCarrier(enum.Enum):
    """What carries the world's calls to the robot processes it starts (docs/processes.md)."""

    PIPES = "pipes"  # a pair of pipes per robot process: the fastest, and nothing else can reach them
    ZENOH = "zenoh"  # Zenoh on loopback, as robots started by hand talk to a `rescuemesh world`


def free_endpoint(host: str = "127.0.0.1") -> str:
    """A TCP endpoint on `host` with a port no one listens on now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind((host, 0))
        return f"tcp/{host}:{probe.getsockname()[1]}"


def _die_with_parent() -> None:  # runs in the child before exec: SIGTERM when the parent dies
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


class RobotProcesses:
    """Robot processes started for `run --processes`: `rescuemesh robot` per robot, each told to die
    with its parent, each writing to `<log_dir>/<name>.log`. Over `ControlCarrier.PIPES` each gets a
    pair of pipes (`channels[name]`, the world's ends; `connect` is not used); over ZENOH it connects
    to `connect`. `close()` leaves no process behind."""

    def __init__(self, connect: str | None, run: str, log_dir: Path, *, key_file: Path | None = None,
                 control: ControlCarrier = ControlCarrier.ZENOH) -> None:
        self.connect, self.run, self.log_dir, self.key_file = connect, run, Path(log_dir), key_file
        self.control = control
        if control is ControlCarrier.ZENOH and connect is None:
            raise ValueError("robot processes over Zenoh need the world's endpoint")
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.procs: dict[str, subprocess.Popen] = {}
        #: Over pipes: the world's ends of each robot's pipes (runtime/processes/pipes.py), the newest
        #: process's when a robot is started again.
        self.channels: dict = {}
        self._spent: list = []  # channels of processes started again since: closed at close()
        #: Without a key file, a fresh control key for this run, handed to each robot process in its
        #: environment (not on its command line, which every user of the host can read).
        self.control_key: bytes | None = os.urandom(32) if key_file is None else None

    def start(self, name: str) -> subprocess.Popen:
        command = [sys.executable, "-m", "rescuemesh", "robot", "--name", name]
        passed: tuple[int, ...] = ()
        if self.control is ControlCarrier.PIPES:
            requests_in, requests_out = os.pipe()  # neither end is inherited by other children
            replies_in, replies_out = os.pipe()
            passed = (requests_in, replies_out)
            command += ["--control-fds", f"{requests_in},{replies_out}"]
        else:
            command += ["--connect", self.connect, "--run-id", self.run]
        if self.key_file is not None:
            command += ["--key", str(self.key_file)]
        from rescuemesh.runtime.processes.control import CONTROL_KEY_ENV

        env = dict(os.environ)
        env.pop(CONTROL_KEY_ENV, None)
        if self.control_key is not None:
            env[CONTROL_KEY_ENV] = self.control_key.hex()
        try:
            with open(self.log_dir / f"{name}.log", "ab" if name in self.procs else "wb") as log:
                proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                        preexec_fn=_die_with_parent, env=env, pass_fds=passed)
        except BaseException:
            if passed:
                os.close(requests_out)
                os.close(replies_in)
            raise
        finally:
            for fd in passed:  # the child's ends: the world keeps only its own
                os.close(fd)
        self.procs[name] = proc
        if self.control is ControlCarrier.PIPES:
            from rescuemesh.runtime.processes.pipes import PipeChannel, PipeReader

            if name in self.channels:
                self._spent.append(self.channels[name])
            self.channels[name] = PipeChannel(requests_out, PipeReader(replies_in), proc)
        return proc

    def exited(self) -> dict[str, int]:
        return {name: proc.returncode for name, proc in self.procs.items() if proc.poll() is not None}

    def close(self, timeout_s: float = LEAVE_TIMEOUT_S) -> None:
        for channel in self._spent + list(self.channels.values()):
            channel.close()  # a robot still waiting for a request reads the end: it halts and leaves
        self._spent = []
        self.channels.clear()  # in place: a PipeHost reads this mapping
        deadline = time.monotonic() + timeout_s
        for proc in self.procs.values():
            try:
                proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.terminate()
        for proc in self.procs.values():
            try:
                proc.wait(2.0)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(2.0)


@dataclass(frozen=True)
class ProcessOptions:
    """Run the robots as separate processes (`--processes`, `rescuemesh world`).

    `listen`: the world's Zenoh endpoint (None: a free port on 127.0.0.1). `spawn`: start the robot
    processes here (False: wait for robots started by hand, over Zenoh). `control`: what carries the
    calls to robots started here. `key_file`: the team key file the robot processes read themselves
    (the key never crosses the control plane)."""

    listen: str | None = None
    control: ControlCarrier = ControlCarrier.PIPES
    run_id: str = "default"
    spawn: bool = True
    key_file: Path | None = None
    join_timeout_s: float = 60.0
    #: Robot processes already started at `listen` (the CLI starts them before it imports the world,
    #: so that they import and connect meanwhile); robots of the team not in it are started here.
    team: "RobotProcesses | None" = None
