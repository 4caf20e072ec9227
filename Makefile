# Two entry points for a new user: `make demo` and `make test`.
# Both create .venv from pyproject.toml when it is missing or older than pyproject.toml.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test test-ros bench fuzz fuzz-control clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[sim,ble,test]'
	touch $@

demo: $(VENV)/.installed
	$(BIN)/rescuemesh run follow --out out/follow

test: $(VENV)/.installed
	$(BIN)/python -m pytest -q -m "not ros1"

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

bench: $(VENV)/.installed
	$(BIN)/rescuemesh bench --out out/bench.json

fuzz: $(VENV)/.installed
	$(BIN)/python -m rescuemesh.fuzz --frames 1000000

fuzz-control: $(VENV)/.installed  # the control plane's input path, 10^5 messages (docs/processes.md)
	$(BIN)/python -m rescuemesh.runtime.control_fuzz --messages 100000

clean:
	rm -rf $(VENV) $(ROS_VENV) out .pytest_cache
