"""Dependencies as extras: the base install runs a robot; commands that need an extra name it."""

from __future__ import annotations

import subprocess
import sys

import pytest

from rescuemesh.maps import load_map, office_map_path
from rescuemesh.runtime.processes.process_world import ProcessRuntime, WorldHost
from rescuemesh.runtime.processes.spawn import free_endpoint
from rescuemesh.scenarios import ScenarioOptions
from rescuemesh.scenarios.follow import FollowScenario

#: The packages the sim and ble extras bring: a base install has none of them (numba is in the base).
EXTRA_PACKAGES = ("mujoco", "matplotlib", "mcap", "foxglove", "bumble")
HIDE = f"import sys\nfor m in {EXTRA_PACKAGES!r}: sys.modules[m] = None\n"


def _without_extras(code: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", HIDE + code], capture_output=True, text=True, timeout=timeout)


@pytest.mark.parametrize("argv, extra", [
    (["run", "follow"], "sim"), (["world", "follow"], "sim"), (["bench"], "sim"),
    (["radio-map", "--from", "1,1"], "sim"), (["ble-check"], "ble"),
])
def test_a_command_whose_extra_is_missing_names_the_extra(argv, extra):
    done = _without_extras(f"from rescuemesh.cli import main\nsys.exit(main({argv!r}))")
    assert done.returncode == 2, done.stderr
    assert f"pip install 'rescuemesh[{extra}]'" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_robot_process_runs_without_the_sim_and_ble_extras(tmp_path):
    scenario = FollowScenario(ScenarioOptions(), load_map(office_map_path()))
    listen = free_endpoint()
    host = WorldHost(listen, run="extras")
    robots = [subprocess.Popen([sys.executable, "-c", HIDE + "from rescuemesh.cli import main\n"
                                f"sys.exit(main(['robot', '--name', {name!r}, '--connect', {listen!r}, "
                                "'--run-id', 'extras']))"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                               text=True)
              for name in scenario.starts()]
    rt = None
    try:
        rt = ProcessRuntime(scenario.map, scenario.starts(), scenario.sim_config(), host, join_timeout_s=20)
        for _ in range(40):  # 2 s: heartbeats go round, brains step, the medium calls every stack
            rt.step()
        heard = {n.address for n in rt.stacks["robot_2"].node.neighbours()}
        assert heard == {1, 3}  # robot_2 heard the others' heartbeats
    finally:
        if rt is not None:
            rt.close()
        host.close()
        for robot in robots:
            out, _ = robot.communicate(timeout=20)
            assert robot.returncode == 0, out
