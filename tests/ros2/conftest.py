"""Fixtures of the ROS 2 tests: rclpy and rescuemesh_msgs must be importable (`make test-ros2` builds
.venv-ros2 with both; plain `make test` deselects these tests with -m "not ros2"), and each test gets a
graph of its own: a ROS_DOMAIN_ID no other test uses, discovery on this host only, every process ended."""

import itertools
import os
import subprocess
import sys

import pytest

from .graph import Ros2Graph

_DOMAINS = itertools.count()


def pytest_configure(config):
    config.addinivalue_line("markers", "ros2: needs ROS 2 (rclpy): `make test-ros2` runs them, `make test` "
                                       "deselects them")


@pytest.fixture(scope="session")
def ros2_installed() -> None:
    probe = subprocess.run([sys.executable, "-c", "import rclpy, nav_msgs.msg, sensor_msgs.msg, rescuemesh_msgs.msg"],
                           capture_output=True, text=True, timeout=60)
    if probe.returncode != 0:
        pytest.fail(f"ROS 2 is not importable here ({probe.stderr.strip().splitlines()[-1:]}): run `make test-ros2`, "
                    f"which builds .venv-ros2")


@pytest.fixture
def ros2(tmp_path, ros2_installed):
    domain = 20 + (os.getpid() * 7 + next(_DOMAINS)) % 80  # 20..99: Fast DDS's ports stay valid
    graph = Ros2Graph(tmp_path, domain)
    try:
        yield graph
    finally:
        graph.close()
