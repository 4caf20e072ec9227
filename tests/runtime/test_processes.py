"""Robots as processes, over pipes (`run --processes`' default) and over Zenoh: the same run as in one
process, and the faults of issue 9.

Every process a test starts is ended in a finally block; every wait is bounded.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rescuemesh.maps import load_map, office_map_path
from rescuemesh.protocol import ResultCode
from rescuemesh.robot import events as ev
from rescuemesh.runtime.processes.control import Keys
from rescuemesh.runtime.processes.process_world import ProcessRuntime, WorldHost
from rescuemesh.runtime.processes.pipes import PipeHost
from rescuemesh.runtime.processes.spawn import ControlCarrier, RobotProcesses, free_endpoint
from rescuemesh.runtime.processes.remote import RobotGone
from rescuemesh.scenarios import ScenarioOptions
from rescuemesh.scenarios.base import CommandRequest
from rescuemesh.scenarios.follow import FollowScenario

RESCUEMESH = [sys.executable, "-m", "rescuemesh"]
#: Wall-clock and process fields: the only parts of result.json a run in processes may change.
NOT_COMPARED = ("wall_time_s", "real_time_factor", "runtime")


def _result(folder: Path) -> dict:
    result = json.loads((folder / "result.json").read_text())
    for key in NOT_COMPARED:
        result.pop(key)
    return result


@pytest.mark.parametrize("scenario, args, control", [("follow", [], "pipes"),
                                                     ("stop", ["--loss", "0.2", "--seed", "3"], "pipes"),
                                                     ("move-around", ["--loss", "0.2", "--seed", "2"], "pipes"),
                                                     ("follow", [], "zenoh")])
def test_a_run_in_processes_is_the_same_run_as_in_one_process(tmp_path, scenario, args, control):
    one = subprocess.run(RESCUEMESH + ["run", scenario, "--quiet", "--out", str(tmp_path / "one")] + args,
                         capture_output=True, text=True, timeout=120)
    many = subprocess.run(RESCUEMESH + ["run", scenario, "--quiet", "--processes", "--control", control,
                                        "--out", str(tmp_path / "many")] + args,
                          capture_output=True, text=True, timeout=120)
    assert one.returncode == many.returncode == 0, many.stderr
    assert _result(tmp_path / "many") == _result(tmp_path / "one")
    runtime = json.loads((tmp_path / "many" / "result.json").read_text())["runtime"]
    assert runtime["kind"] == "processes"
    assert runtime["control_plane"]["carrier"] == control
    names = [p["name"] for p in runtime["processes"]]
    assert names == ["world", "robot_1", "robot_2", "robot_3"]
    assert len({p["pid"] for p in runtime["processes"]}) == 4 and all(p["cpu_s"] > 0 for p in runtime["processes"])
    plane = runtime["control_plane"]  # one parallel round of Ticks per tick
    assert plane["rounds"]["Tick"] == plane["ticks"] and plane["requests"]["Tick"] == 3 * plane["ticks"]
    # a frame goes to all the robots that hear it in one round (this used to be one round per robot)
    assert plane["rounds"]["Receive"] < 0.8 * plane["requests"]["Receive"]
    for name in names[1:]:
        log = (tmp_path / "many" / "processes" / f"{name}.log").read_text()
        assert "joined the world" in log and "the world's run is over: wheels halted, leaving" in log


def test_a_scenario_that_cannot_run_in_processes_says_so(tmp_path):
    done = subprocess.run(RESCUEMESH + ["run", "show-cam", "--processes", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert "does not run with --processes yet (these do: follow, stop" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("bad", ["", "a/b", "x*", "$run"])
def test_a_bad_run_id_is_refused(bad):
    with pytest.raises(ValueError, match="run id"):
        Keys(bad)


@pytest.mark.parametrize("argv, message", [
    (["robot", "--name", "robot_0", "--connect", "tcp/127.0.0.1:7447"], "robot"),
    (["robot", "--name", "robot_2", "--connect", "127.0.0.1:7447"], "expected tcp/IP:PORT"),
    (["robot", "--name", "robot_2", "--connect", "tcp/127.0.0.1:7447", "--wait", "-1"], "--wait"),
    (["world", "follow", "--listen", "tcp/localhost"], "expected tcp/IP:PORT"),
    (["robot", "--link", "udp", "--name", "robot_2"], "--link takes zenoh"),
    (["robot", "--link", "zenoh", "--name", "robot_2"], "give at least one --listen or --connect"),
    (["world", "follow", "--run-id", "a/b"], "run id"),
    (["run", "follow", "--control", "zenoh"], "--control chooses how run --processes calls its robots: add"),
    (["world", "follow", "--control", "pipes"], "robots started by hand call the world over Zenoh"),
    (["run", "follow", "--processes", "--control", "udp"], "invalid choice"),
])
def test_bad_process_arguments_are_one_line_errors(argv, message):
    done = subprocess.run(RESCUEMESH + argv, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert message in done.stderr and "Traceback" not in done.stderr


def test_a_robot_without_a_world_gives_up_after_its_wait():
    started = time.monotonic()
    done = subprocess.run(RESCUEMESH + ["robot", "--name", "robot_2", "--connect", free_endpoint(), "--wait", "1"],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 1
    assert "no world process at" in done.stderr
    assert time.monotonic() - started < 30


# --- faults ----------------------------------------------------------------------------------


def _speed(rt, name: str) -> float:
    return rt.trajectories[name][-1].speed


def _step_until(rt, predicate, limit_s: float) -> float:
    """Step until predicate(rt) holds; the simulated time it took. Fails after `limit_s` simulated s."""
    start = rt.time
    while not predicate(rt):
        assert rt.time - start < limit_s, f"not within {limit_s} s simulated"
        rt.step()
    return rt.time - start


def _accepted(rt, commander: str, peer: str, send_name: str, limit_s: float = 10.0) -> float:
    brain = rt.brain(commander)
    request = CommandRequest(brain, peer, getattr(brain, send_name))
    answer = {}

    def done(rt):
        answer["code"] = request.poll(rt.time)
        return answer["code"] is not None or request.given_up

    took = _step_until(rt, done, limit_s)
    assert answer["code"] == ResultCode.ACCEPTED
    return took


@pytest.mark.parametrize("control", list(ControlCarrier))
def test_a_killed_robot_is_lost_its_follower_halts_and_it_rejoins_and_is_commanded_again(tmp_path, control):
    scenario = FollowScenario(ScenarioOptions(seed=1), load_map(office_map_path()))
    if control is ControlCarrier.ZENOH:
        listen = free_endpoint()
        team = RobotProcesses(listen, "faults", tmp_path)
        host = WorldHost(listen, run="faults", control_key=team.control_key)
    else:
        team = RobotProcesses(None, "faults", tmp_path, control=control)
        host = PipeHost(team.channels, team.control_key)
    rt = None
    try:
        for name in scenario.starts():
            team.start(name)
        rt = ProcessRuntime(scenario.map, scenario.starts(), scenario.sim_config(), host)
        _accepted(rt, "robot_1", "robot_2", "command_follow")
        rt.brain("robot_1").navigate_to(scenario.goal(), rt.time)
        _step_until(rt, lambda rt: rt.time >= 6.0 and _speed(rt, "robot_2") > 0.15, 15.0)  # following

        team.procs["robot_1"].send_signal(signal.SIGKILL)  # the leader, in the middle of the Follow
        killed_s = rt.time
        _step_until(rt, lambda rt: "robot_1" not in rt.live, 5.0)
        with pytest.raises(RobotGone):
            rt.brain("robot_1").running
        # the follower hears no more PoseUpdates: it halts, then the mesh reports the link lost
        halted = _step_until(rt, lambda rt: _speed(rt, "robot_2") < 0.02, 5.0)
        _step_until(rt, lambda rt: any(isinstance(e, ev.LinkLost) for e in rt.brain("robot_2").log), 10.0)
        assert rt.world.bodies["robot_1"].command == (0.0, 0.0)  # a dead robot's wheels stop
        assert any("process lost" in what for _, name, what in rt.process_log if name == "robot_1")

        lost_s = next(e.time_s for e in rt.brain("robot_2").log if isinstance(e, ev.LinkLost)) - killed_s
        team.start("robot_1")  # again: a new process, the next boot epoch
        restarted, deadline, rejoined = time.monotonic(), time.monotonic() + 30.0, rt.time
        while "robot_1" not in rt.live and time.monotonic() < deadline:
            rt.step()
        rejoined, rejoined_wall = rt.time - rejoined, time.monotonic() - restarted
        assert rt.joins["robot_1"] == 2
        assert _accepted(rt, "robot_1", "robot_2", "command_follow") < 5.0  # its new commands are accepted
        assert _accepted(rt, "robot_3", "robot_1", "command_follow") < 5.0  # and it can be commanded again
        log = [e.kind for e in rt.brain("robot_2").log]
        assert "peer_restarted" in log
        print(f"killed at {killed_s:.2f} s simulated; follower halted {halted:.2f} s later, link lost after "
              f"{lost_s:.2f} s; the new process joined {rejoined_wall:.2f} s (wall) after its start "
              f"({rejoined:.2f} s simulated went by)")
    finally:
        if rt is not None:
            rt.close()
        team.close()
        host.close()
    assert not team.exited().keys() ^ team.procs.keys()  # every robot process has ended


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _wait(predicate, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return predicate()


def _joined(folder: Path, names) -> bool:
    return all((folder / "processes" / f"{n}.log").exists()
               and "joined" in (folder / "processes" / f"{n}.log").read_text() for n in names)


@pytest.mark.parametrize("how", ["ctrl-c to the group", "sigint to the parent", "sigkill to the parent"])
def test_no_robot_process_outlives_an_interrupted_run(tmp_path, how):
    run = subprocess.Popen(RESCUEMESH + ["run", "follow", "--processes", "--realtime", "--quiet", "--out", str(tmp_path)],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    children: list[int] = []
    try:
        assert _wait(lambda: _joined(tmp_path, ["robot_1", "robot_2", "robot_3"]), 60), "robots never joined"
        children = _children(run.pid)
        assert len(children) == 3
        started = time.monotonic()
        if how == "ctrl-c to the group":
            os.killpg(run.pid, signal.SIGINT)  # what a terminal's Ctrl-C does
        elif how == "sigint to the parent":
            os.kill(run.pid, signal.SIGINT)
        else:
            os.kill(run.pid, signal.SIGKILL)
        run.wait(timeout=20)
        assert _wait(lambda: not any(_alive(pid) for pid in children), 10), f"orphans after {how}"
        print(f"{how}: every robot process gone {time.monotonic() - started:.2f} s after the signal")
        if how != "sigkill to the parent":
            assert run.returncode == 130
            assert "Traceback" not in run.stderr.read().decode()
    finally:
        for pid in children + [run.pid]:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        run.wait(timeout=10)


def test_killing_the_world_halts_every_robot_and_each_leaves_in_bounded_time(tmp_path):
    listen = free_endpoint()
    world = subprocess.Popen(RESCUEMESH + ["world", "follow", "--listen", listen, "--realtime", "--quiet",
                                           "--out", str(tmp_path)], stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, start_new_session=True)
    (tmp_path / "processes").mkdir()
    logs = {name: tmp_path / "processes" / f"{name}.log" for name in ("robot_1", "robot_2", "robot_3")}
    robots = {}
    for name, log in logs.items():
        with open(log, "wb") as out:
            robots[name] = subprocess.Popen(RESCUEMESH + ["robot", "--name", name, "--connect", listen],
                                            stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        assert _wait(lambda: _joined(tmp_path, logs), 60), "robots never joined"
        time.sleep(1.0)  # stepping (a realtime follow lasts ~25 s)
        assert world.poll() is None and all(r.poll() is None for r in robots.values())
        world.send_signal(signal.SIGKILL)
        started = time.monotonic()
        for name, robot in robots.items():
            robot.wait(timeout=15)
            out = logs[name].read_text()
            assert robot.returncode == 0, out
            assert "world gone: wheels halted, leaving" in out
        print(f"every robot left {time.monotonic() - started:.2f} s after the world was killed")
    finally:
        for proc in [world, *robots.values()]:
            if proc.poll() is None:
                proc.kill()
            proc.wait(timeout=10)
