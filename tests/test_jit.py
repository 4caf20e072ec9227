"""rescuemesh.jit.compiled: kernels are cached on disk where numba can write, in a temporary folder
when it cannot write where it looks, and compiled without a cache when nothing is writable; a robot
process runs in each case."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

#: Makes every folder numba looks in for its cache unwritable (as a read-only install, HOME and
#: NUMBA_CACHE_DIR would), except those under ALLOW (when set).
READ_ONLY = """
import os
from numba.core import caching
_ensure = caching._CacheLocator.ensure_cache_path
def ensure(self):
    allow = os.environ.get("ALLOW")
    if allow and self.get_cache_path().startswith(allow):
        return _ensure(self)
    raise PermissionError(13, "read-only", self.get_cache_path())
caching._CacheLocator.ensure_cache_path = ensure
"""
USE_KERNELS = """
import numpy as np
from rescuemesh.nav import kernels
from rescuemesh import jit
points = np.array([[1.0, 0.05], [2.0, -0.1]])
assert kernels.scan_clearance(points, 0.0, 0.0, 0.0, np.inf, 0.0, 0.18, 0.02, np.inf) > 0.5
print(type(kernels.scan_clearance._cache).__name__, jit.FALLBACK_CACHE_DIR)
"""


def _python(code: str, tmp: Path, allow: str | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "TMPDIR": str(tmp), "NUMBA_CACHE_DIR": ""}
    if allow is not None:
        env["ALLOW"] = allow
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)


def test_kernels_cache_in_a_temporary_folder_when_numba_cannot_write_where_it_looks(tmp_path):
    fallback = tmp_path / "rescuemesh-numba-cache"
    done = _python(READ_ONLY + USE_KERNELS, tmp_path, allow=str(fallback))
    assert done.returncode == 0, done.stderr
    cache, folder = done.stdout.split()
    assert cache == "FunctionCache" and folder == str(fallback)
    assert any(fallback.rglob("kernels.scan_clearance*.nbi"))  # the index numba writes beside the code


def test_kernels_compile_without_a_cache_when_nothing_is_writable(tmp_path):
    done = _python(READ_ONLY + USE_KERNELS, tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[0] == "NullCache"
    assert not any(tmp_path.rglob("*.nbi"))


def test_a_robot_process_runs_with_no_writable_numba_cache(tmp_path):
    from rescuemesh.maps import load_map, office_map_path
    from rescuemesh.runtime.processes.process_world import ProcessRuntime, WorldHost
    from rescuemesh.runtime.processes.spawn import free_endpoint
    from rescuemesh.scenarios import ScenarioOptions
    from rescuemesh.scenarios.follow import FollowScenario

    scenario = FollowScenario(ScenarioOptions(), load_map(office_map_path()))
    listen = free_endpoint()
    host = WorldHost(listen, run="readonly")
    env = {**os.environ, "TMPDIR": str(tmp_path), "NUMBA_CACHE_DIR": ""}
    code = READ_ONLY + ("import sys\nfrom rescuemesh.cli import main\n"
                        "sys.exit(main(['robot', '--name', {name!r}, '--connect', {listen!r}, '--run-id', 'readonly']))")
    robots = [subprocess.Popen([sys.executable, "-c", code.format(name=name, listen=listen)], env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
              for name in scenario.starts()]
    rt = None
    try:
        rt = ProcessRuntime(scenario.map, scenario.starts(), scenario.sim_config(), host, join_timeout_s=60)
        for _ in range(40):  # 2 s: heartbeats go round, brains step (navigation's kernels included)
            rt.step()
        heard = {n.address for n in rt.stacks["robot_2"].node.neighbours()}
        assert heard == {1, 3}  # robot_2 heard the others' heartbeats: its stack and brain ran
    finally:
        if rt is not None:
            rt.close()
        host.close()
        for robot in robots:
            out, _ = robot.communicate(timeout=60)
            assert robot.returncode == 0, out
    assert not any(tmp_path.rglob("*.nbi"))  # nothing could be cached, and the robots ran
