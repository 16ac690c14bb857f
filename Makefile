# sonar_tracking: two commands for users (`make demo`, `make test`), both self-contained.
#
# Without a ROS installation they create .venv with the ROS 2 Jazzy wheels from PyPI.
# With a sourced ROS 2 Jazzy (rclpy importable) they create .venv on top of it
# (--system-site-packages) and install no ROS wheels.

SHELL := /bin/bash

# First interpreter on PATH in the range the Jazzy wheels support (cp310-cp312).
PYTHON ?= $(shell for p in python3 python3.12 python3.11 python3.10; do \
	command -v $$p >/dev/null 2>&1 && \
	$$p -c 'import sys; sys.exit(not (3, 10) <= sys.version_info[:2] <= (3, 12))' 2>/dev/null && \
	{ echo $$p; break; }; done)

VENV := .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
ROS_WHEELS := "ros-jazzy-rclpy[fastrtps]" ros-jazzy-common-interfaces ros-jazzy-std-srvs
# A sourced ROS installation is used as it is.
ROS_SOURCED := $(shell $(PYTHON) -c 'import rclpy' >/dev/null 2>&1 && echo yes)

# Keep test and demo DDS traffic on this machine.
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST

.PHONY: all demo test build bench venv clean help

all: test

help:
	@echo "make demo   run the simulated scenario through the pipeline and show the result"
	@echo "make test   build with colcon and run the whole test suite"
	@echo "make build  colcon build into install/ (source install/setup.bash, then run executables)"
	@echo "make bench  run the benchmarks (sonar_eval bench)"
	@echo "make clean  remove .venv, build/, install/, log/, out/"

venv: $(STAMP)

$(STAMP): requirements.txt requirements-test.txt requirements-cluster.txt setup.py package.xml
	@test -n "$(PYTHON)" || { echo "error: need Python 3.10, 3.11 or 3.12 (the ROS 2 Jazzy wheels' range); set PYTHON=..." >&2; exit 1; }
	@echo "==> creating $(VENV) with $$($(PYTHON) --version)$(if $(ROS_SOURCED), on the sourced ROS installation, with the ROS 2 Jazzy wheels)"
	rm -rf $(VENV)
	$(PYTHON) -m venv $(if $(ROS_SOURCED),--system-site-packages) $(VENV)
	$(VPY) -m pip install --quiet --upgrade pip
	$(VPY) -m pip install --quiet $(if $(ROS_SOURCED),,$(ROS_WHEELS)) -r requirements.txt -r requirements-test.txt -r requirements-cluster.txt
	$(VPY) -m pip install --quiet --no-deps -e .
	touch $@

build: $(STAMP)
	$(VENV)/bin/colcon --log-base log build --symlink-install --paths . --build-base build --install-base install
	@echo "==> built install/sonar_tracking (source install/setup.bash to use it)"

test: build
	$(VPY) -m pytest test

demo: $(STAMP)
	$(VPY) -m sonar_tracking.tools.demo

# Stone Soup is a bench-only extra (the IMM-IPDA comparison), never a runtime dependency.
bench: $(STAMP)
	$(VPY) -m pip install --quiet -r requirements-bench.txt
	$(VENV)/bin/sonar_eval bench --json out/bench.json

clean:
	rm -rf $(VENV) build install log out
