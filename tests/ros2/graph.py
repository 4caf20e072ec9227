"""Processes of a ROS 2 test on one ROS_DOMAIN_ID, discovery on this host only: fake robots, rescuemesh
robot processes with ROS 2 bodies, a reader of the paper's topics, an action client.

Owns: starting each with output to files, their environment, ending them. Must not know: what a test
asserts. The test process itself never imports rclpy: everything ROS runs in these children.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from ros1.rosproc import Proc, free_port, read_json, wait_for  # the same process handling as the ROS 1 tests

HERE = Path(__file__).resolve().parent

__all__ = ["Ros2Graph", "free_port", "wait_for"]


class Ros2Graph:
    """The processes of one test; `close` ends them all."""

    def __init__(self, workdir: Path, domain: int) -> None:
        self.workdir, self.domain = workdir, domain
        self.env = {**os.environ, "ROS_DOMAIN_ID": str(domain), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
                    "ROS_LOG_DIR": str(workdir / "ros_log"), "PYTHONUNBUFFERED": "1",
                    "RMW_IMPLEMENTATION": os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")}
        self.env.pop("ROS_LOCALHOST_ONLY", None)
        self.procs: list[Proc] = []

    def start(self, name: str, cmd: list[str]) -> Proc:
        taken = sum(p.name.split("#")[0] == name for p in self.procs)
        proc = Proc(f"{name}#{taken}" if taken else name, cmd, self.env, self.workdir)
        self.procs.append(proc)
        return proc

    def fake_robot(self, name: str, start: str, *args: str) -> Proc:
        """A fake ROS 2 robot at `start` ("x,y,yaw"), its state in state(name)."""
        return self.start(f"fake_{name}", [sys.executable, str(HERE / "fake_robot.py"), "--name", name,
                                           f"--start={start}", "--state", str(self.state_path(name)), *args])

    def state_path(self, name: str) -> Path:
        return self.workdir / f"fake_{name}.json"

    def state(self, name: str) -> dict | None:
        return read_json(self.state_path(name))

    def wait_robots(self, *names: str) -> None:
        for name in names:
            wait_for(lambda: self.state(name), 30.0, f"fake {name} to start")

    def wait_for_state(self, name: str, predicate, timeout_s: float, what: str) -> dict:
        return wait_for(lambda: (s := self.state(name)) is not None and predicate(s) and s, timeout_s, what)

    def robot(self, name: str, *args: str, duration: float = 90.0) -> Proc:
        """`rescuemesh robot --link zenoh --body ros2 --name NAME ...` as a user runs it."""
        return self.start(name, [sys.executable, "-m", "rescuemesh", "robot", "--link", "zenoh", "--body", "ros2",
                                 "--name", name, "--duration", str(duration), *args])

    def reader(self, *topics: str, lifetime: float = 120.0) -> Proc:
        """tests/ros2/reader.py on TOPIC:TYPE specs; waits until it has subscribed."""
        proc = self.start("reader", [sys.executable, str(HERE / "reader.py"), "--lifetime", str(lifetime), *topics])
        wait_for(lambda: "reader: subscribed" in proc.stdout(), 30.0, "the reader to subscribe")
        return proc

    def command(self, robot: str, request: dict, timeout_s: float = 60.0, copies: int = 1) -> list[dict]:
        """tests/ros2/commander.py: `robot` sends `request` through its action (`copies` goals of it at
        once); the JSON lines printed."""
        proc = self.start("commander", [sys.executable, str(HERE / "commander.py"), robot, json.dumps(request),
                                        "--timeout", str(timeout_s), "--copies", str(copies)])
        code = proc.wait(timeout_s + 30)
        lines = [json.loads(line) for line in proc.stdout().splitlines() if line.startswith("{")]
        assert code == 0, (code, lines, proc.stderr()[-2000:])
        return lines

    def close(self) -> None:
        for proc in reversed(self.procs):
            proc.stop()
