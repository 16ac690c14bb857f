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

.PHONY: all demo test test-all test-slow lint interfaces build bench venv clean help view view-deps kernels

all: test

help:
	@echo "make demo   run the simulated scenario through the pipeline and show the result"
	@echo "make test   build with colcon, lint (ruff, mypy) and run the test suite (all but the tests marked slow)"
	@echo "make test-all  the same with the slow tests (soak, long studies); CI runs them too"
	@echo "make build  colcon build into install/ (source install/setup.bash, then run executables)"
	@echo "make bench  run the benchmarks (sonar_eval bench)"
	@echo "make kernels  compile the numba kernels into their cache (demo and test do it first; ~15 s once)"
	@echo "make view   install the view extra (Rerun) and run sonar_view (VIEW_ARGS=\"--bag out/demo_bag\" for a bag)"
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

# view-deps: sonar_view's tests need its extra, and its browser test Debian's chromium (~25 s here).
# interfaces: the live imaging-sonar adapter's test needs marine_acoustic_msgs (built once, ~45 s).
# The suite runs with install/ sourced, as `ros2 run` would.
TEST_DEPS := build interfaces view-deps lint kernels
test: $(TEST_DEPS)
	source install/setup.bash && $(VPY) -m pytest test -m "not slow" -n 2 --dist loadfile

test-slow: $(TEST_DEPS)
	source install/setup.bash && $(VPY) -m pytest test -m slow -n 2 --dist loadgroup

test-all: $(TEST_DEPS)
	source install/setup.bash && $(VPY) -m pytest test

# ruff (rules in ruff.toml) on the whole tree; mypy (mypy.ini) on core, msgs and ros.
lint: $(STAMP)
	$(VENV)/bin/ruff check .
	$(VENV)/bin/mypy

# The compiled kernels (numba) in their cache before anything runs: a fresh checkout compiles them
# here once (~15 s), later runs load them (~1 s), so no node compiles while data queue up.
kernels: $(STAMP)
	$(VPY) -m sonar_tracking.ros.warmup

# marine_acoustic_msgs is not among the ROS wheels: generated from its definitions with the Jazzy
# rosidl wheels, cmake and a C compiler. Where they are missing the live adapter's test says so.
INTERFACES := install/marine_acoustic_msgs/share/marine_acoustic_msgs/package.xml
$(INTERFACES): $(STAMP) sonar_tracking/io/importers/msgdefs.py sonar_tracking/cli/build_interfaces.py
	$(VPY) -m sonar_tracking.cli.build_interfaces --install-base install \
		|| echo "warning: marine_acoustic_msgs did not build (cmake and a C compiler needed); the live adapter's test will be skipped" >&2

interfaces: $(INTERFACES)

# The view is an extra: the demo runs (and writes its PNG) without it when it cannot install.
demo: $(STAMP) kernels
	@$(MAKE) --no-print-directory $(VIEW_STAMP) || echo "note: the view extra (requirements-view.txt) did not install; the demo runs without the live view"
	$(VPY) -m sonar_tracking.cli.demo

# sonar_view's extra (Rerun's SDK with its web viewer, ~170 MB), never a dependency of the nodes.
VIEW_STAMP := $(VENV)/.view-installed
$(VIEW_STAMP): $(STAMP) requirements-view.txt
	$(VPY) -m pip install --quiet -r requirements-view.txt
	touch $@

VIEW_ARGS ?=
view: $(VIEW_STAMP)
	$(VENV)/bin/sonar_view $(VIEW_ARGS)

# What the view's browser test needs: the extra, and Debian's chromium (apt-get as root, else sudo -n).
view-deps: $(VIEW_STAMP)
	@command -v chromium >/dev/null 2>&1 || { \
		SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo -n); \
		$$SUDO apt-get update -q && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -q --no-install-recommends chromium \
		|| echo "warning: chromium did not install; the browser test of sonar_view will be skipped" >&2; }

# Stone Soup is a bench-only extra (the IMM-IPDA comparison), never a runtime dependency.
bench: $(STAMP)
	$(VPY) -m pip install --quiet -r requirements-bench.txt
	$(VENV)/bin/sonar_eval bench --json out/bench.json

clean:
	rm -rf $(VENV) build install log out
