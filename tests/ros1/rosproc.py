"""Processes of a ROS 1 test: a roscore on a free port, fake robots, the team, rostopic, publishers.

Owns: starting each in its own session with output to files, bounded waits, and ending each with
its children (roslaunch starts rosmaster and rosout in sessions of their own, so they are found by
parent pid, not by process group). Must not know: what a test asserts. The test process itself
never imports rospy: everything ROS runs in these children.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
import xmlrpc.client
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: Debian's Python, which has rospy: the fake robots, publishers and rostopic run on it.
ROS_PYTHON = "/usr/bin/python3"


def wait_for(predicate, timeout_s: float, what: str, poll_s: float = 0.05):
    """predicate()'s first truthy value, or AssertionError after `timeout_s` s."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:g} s waiting for {what}")
        time.sleep(poll_s)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def read_json(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


def _children() -> dict[int, list[int]]:
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry.name))
    return children


def descendants(pid: int) -> list[int]:
    tree, out, todo = _children(), [], [pid]
    while todo:
        for child in tree.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


class Proc:
    """One child process with its stdout and stderr in files."""

    def __init__(self, name: str, cmd: list[str], env: dict, workdir: Path) -> None:
        self.name, self.cmd = name, cmd
        self.out, self.err = workdir / f"{name}.out", workdir / f"{name}.err"
        with open(self.out, "w") as out, open(self.err, "w") as err:
            self.popen = subprocess.Popen(cmd, env=env, stdout=out, stderr=err, stdin=subprocess.DEVNULL,
                                          start_new_session=True)

    def stdout(self) -> str:
        return self.out.read_text(errors="replace")

    def stderr(self) -> str:
        return self.err.read_text(errors="replace")

    def alive(self) -> bool:
        return self.popen.poll() is None

    def wait(self, timeout_s: float) -> int:
        try:
            return self.popen.wait(timeout_s)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"{self.name} still running after {timeout_s:g} s; stderr:\n{self.stderr()[-2000:]}")

    def stop(self, grace_s: float = 8.0) -> None:
        """SIGINT (rospy and roslaunch shut down cleanly on it), then SIGKILL for it and its children."""
        family = descendants(self.popen.pid)
        if self.alive():
            os.kill(self.popen.pid, signal.SIGINT)
            try:
                self.popen.wait(grace_s)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(5)
        family += [pid for pid in descendants(self.popen.pid) if pid not in family]
        for pid in family:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


class RosSession:
    """A roscore of its own and the processes a test starts against it; `close` ends them all."""

    def __init__(self, workdir: Path, msg_path: str, msg_cache: str) -> None:
        self.workdir = workdir
        self.port = free_port()
        self.master_uri = f"http://127.0.0.1:{self.port}"
        self.env = {**os.environ, "ROS_MASTER_URI": self.master_uri, "ROS_IP": "127.0.0.1",
                    "ROS_HOSTNAME": "127.0.0.1", "ROS_HOME": str(workdir / "ros_home"),
                    "PYTHONPATH": msg_path, "RESCUEMESH_ROS1_MSGS": msg_cache, "PYTHONUNBUFFERED": "1"}
        self.procs: list[Proc] = []
        self.roscore = self.start("roscore", ["roscore", "-p", str(self.port)])
        master = xmlrpc.client.ServerProxy(self.master_uri)

        def master_up() -> bool:
            try:
                return master.getPid("/test")[0] == 1
            except OSError:
                return False
        wait_for(master_up, 30.0, f"roscore on port {self.port}", poll_s=0.2)

    def start(self, name: str, cmd: list[str]) -> Proc:
        taken = sum(p.name.split("#")[0] == name for p in self.procs)
        proc = Proc(f"{name}#{taken}" if taken else name, cmd, self.env, self.workdir)
        self.procs.append(proc)
        return proc

    def robot(self, name: str, start: str) -> Proc:
        """A fake ROS robot at `start` ("x,y,yaw"), its state in STATE(name)."""
        return self.start(f"fake_{name}", [ROS_PYTHON, str(HERE / "fake_robot.py"), "--name", name,
                                           f"--start={start}", "--state", str(self.state_path(name))])

    def state_path(self, name: str) -> Path:
        return self.workdir / f"fake_{name}.json"

    def state(self, name: str) -> dict | None:
        return read_json(self.state_path(name))

    def wait_robots(self, *names: str) -> None:
        for name in names:
            wait_for(lambda: self.state(name), 20.0, f"fake {name} to start")

    def team(self, robots: list[str], *args: str) -> Proc:
        """The rescuemesh team on ROS bodies (tests/ros1/team.py), with this project's Python."""
        cmd = [sys.executable, str(HERE / "team.py"), "--report", str(self.report_path)]
        for name in robots:
            cmd += ["--robot", name]
        proc = self.start("team", cmd + list(args))
        return proc

    def wait_for_state(self, name: str, predicate, timeout_s: float, what: str) -> dict:
        """The fake robot's first state that satisfies `predicate`."""
        return wait_for(lambda: (s := self.state(name)) is not None and predicate(s) and s, timeout_s, what)

    def wait_for_report(self, predicate, timeout_s: float, what: str) -> dict:
        """The team's first report (written every second) that satisfies `predicate`."""
        return wait_for(lambda: (r := self.report()) is not None and predicate(r) and r, timeout_s, what)

    @property
    def report_path(self) -> Path:
        return self.workdir / "team_report.json"

    def report(self) -> dict | None:
        return read_json(self.report_path)

    def wait_ready(self, team: Proc, timeout_s: float = 60.0) -> None:
        def ready():
            if not team.alive():
                raise AssertionError(f"the team exited {team.popen.returncode}:\n{team.stderr()[-3000:]}")
            return "ready" in team.stdout()
        wait_for(ready, timeout_s, "the team to be ready")

    def echo(self, topic: str, count: int | None = None) -> Proc:
        """`rostopic echo [-n count] topic`, as a ROS user runs it."""
        name = "echo" + topic.replace("/", "_")
        return self.start(name, ["rostopic", "echo", *(["-n", str(count)] if count else []), topic])

    def wait_linked(self, topic: str, timeout_s: float = 30.0) -> None:
        """Until `topic` has a publisher and a subscriber registered with the master (`rostopic
        info`): a subscriber that registered after a message was published never sees it."""
        def linked() -> bool:
            info = subprocess.run(["rostopic", "info", topic], env=self.env, capture_output=True, text=True,
                                  timeout=10)
            return info.returncode == 0 and "Publishers: None" not in info.stdout \
                and "Subscribers: None" not in info.stdout
        wait_for(linked, timeout_s, f"a publisher and a subscriber on {topic}", poll_s=0.2)

    def rostopic_pub(self, topic: str, yaml: str, timeout_s: float = 20.0) -> None:
        """`rostopic pub -1 topic rescuemesh_msgs/Command YAML`, as in docs/ros1.md; waits for it."""
        proc = self.start("rostopic_pub", ["rostopic", "pub", "-1", topic, "rescuemesh_msgs/Command", yaml])
        assert proc.wait(timeout_s) == 0, proc.stderr()

    def publish(self, topic: str, requests: list[dict], timeout_s: float = 30.0) -> None:
        """A rospy node (tests/ros1/publish.py) sends `requests` on `topic`; waits for it."""
        proc = self.start("publisher", [ROS_PYTHON, str(HERE / "publish.py"), topic, json.dumps(requests)])
        assert proc.wait(timeout_s) == 0, proc.stderr()

    def close(self) -> None:
        """End every process, newest first, roscore last."""
        for proc in reversed(self.procs):
            proc.stop()
