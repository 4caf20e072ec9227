"""Starting and ending robot processes for `rescuemesh run --processes`.

Owns: the options of a run in processes, picking the world's endpoint, starting `rescuemesh robot` per robot (each told to die with its
parent), ending them so that none outlives the run. Must not know: MuJoCo or what the robots do, so
that the run can start its robots before it imports the world (they import and connect meanwhile).
"""

from __future__ import annotations

import ctypes
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
    with its parent, each writing to `<log_dir>/<name>.log`. `close()` leaves no process behind."""

    def __init__(self, connect: str, run: str, log_dir: Path, *, key_file: Path | None = None) -> None:
        self.connect, self.run, self.log_dir, self.key_file = connect, run, Path(log_dir), key_file
        self.log_dir.mkdir(parents=True, exist_ok=True)
        self.procs: dict[str, subprocess.Popen] = {}
        #: Without a key file, a fresh control key for this run, handed to each robot process in its
        #: environment (not on its command line, which every user of the host can read).
        self.control_key: bytes | None = os.urandom(32) if key_file is None else None

    def start(self, name: str) -> subprocess.Popen:
        command = [sys.executable, "-m", "rescuemesh", "robot", "--name", name, "--connect", self.connect,
                   "--run-id", self.run]
        if self.key_file is not None:
            command += ["--key", str(self.key_file)]
        from rescuemesh.runtime.processes.control import CONTROL_KEY_ENV

        env = dict(os.environ)
        env.pop(CONTROL_KEY_ENV, None)
        if self.control_key is not None:
            env[CONTROL_KEY_ENV] = self.control_key.hex()
        with open(self.log_dir / f"{name}.log", "ab" if name in self.procs else "wb") as log:
            proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                    preexec_fn=_die_with_parent, env=env)
        self.procs[name] = proc
        return proc

    def exited(self) -> dict[str, int]:
        return {name: proc.returncode for name, proc in self.procs.items() if proc.poll() is not None}

    def close(self, timeout_s: float = LEAVE_TIMEOUT_S) -> None:
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
    processes here (False: wait for robots started by hand). `key_file`: the team key file the robot
    processes read themselves (the key never crosses the control plane)."""

    listen: str | None = None
    run_id: str = "default"
    spawn: bool = True
    key_file: Path | None = None
    join_timeout_s: float = 60.0
    #: Robot processes already started at `listen` (the CLI starts them before it imports the world,
    #: so that they import and connect meanwhile); robots of the team not in it are started here.
    team: "RobotProcesses | None" = None
