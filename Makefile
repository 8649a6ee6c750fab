# ext_sense: the two commands a newcomer needs are `make demo` and `make test`.
# Each runs scripts/setup.sh first (idempotent; well under a second when nothing changed).

# Python writes its compiled files (__pycache__), even where the environment says not to, as
# container images often do (PYTHONDONTWRITEBYTECODE=1): then every node process and every test
# collection compiled the sources again (a collection of the tests took 17.9 s, 9.8 s compiled).
unexport PYTHONDONTWRITEBYTECODE

VENV        ?= .venv
JAZZY_VENV  ?= .venv-jazzy
PY          := $(VENV)/bin/python

.PHONY: setup demo demo-sessions test test-fast lint format bench bench-quick test-jazzy setup-jazzy colcon clean

setup:
	@scripts/setup.sh kilted

## The main job: tap localization on the emulated NUSkin, printing estimates beside ground truth.
demo: setup
	@$(VENV)/bin/ext-sense demo

## Sessions on the simulator: collect, train, score on a second day, calibrate, score again.
demo-sessions: setup
	@scripts/demo_sessions.sh

## Lint and every test (unit, node, system). CI runs exactly this. Every test but the graphs of
## node processes (marked slow and ros) runs on both cores, test-fast's and the slow training
## ones; the graphs, which assert on live timing, then one at a time, alone on the machine.
## Each lane ends with its 15 slowest tests. A test that outlives its timeout by a minute (hung
## in C, or in a teardown) ends its process with every thread's stack (conftest.py).
test: setup lint
	@$(VENV)/bin/pytest -m "not (slow and ros)" -n 2 --durations=15
	@$(VENV)/bin/pytest -m "slow and ros" --durations=15

## The everyday lane: lint and the tests not marked slow (no graph subprocesses, no training on
## hundreds of taps), on both cores. Run `make test` before you push.
test-fast: setup lint
	@$(VENV)/bin/pytest -m "not slow" -n 2

lint: setup
	@$(VENV)/bin/ruff check .
	@$(VENV)/bin/ruff format --check .

format: setup
	@$(VENV)/bin/ruff format .
	@$(VENV)/bin/ruff check --fix .

## Benchmarks: figures and ratios measured side by side in one run (see docs/benchmarks.md).
bench: setup
	@set -e; for f in bench/bench_*.py; do echo "== $$f"; $(PY) $$f; done

bench-quick: setup
	@set -e; for f in bench/bench_*.py; do echo "== $$f"; $(PY) $$f --quick; done

## The node tests again on ROS 2 Jazzy (LTS), in a second venv built from the ros-jazzy-* wheels.
setup-jazzy:
	@scripts/setup.sh jazzy

test-jazzy: setup-jazzy
	@$(JAZZY_VENV)/bin/pytest -m ros

## Build the workspace with colcon (as the Docker image does), into ros2_ws/{build,install,log}:
## then `source ros2_ws/install/setup.bash`. colcon is the one scripts/setup.sh installs beside
## the venv (requirements/colcon.txt); the venv's ROS stands for a sourced /opt/ros. make test
## builds the same way into a temporary directory (test/test_colcon_workspace.py).
colcon: setup
	@PATH=$(abspath $(VENV))/bin:$$PATH AMENT_PREFIX_PATH=$(abspath $(VENV)) PYTHON=$(abspath $(PY)) \
	  scripts/build_workspace.sh

clean:
	rm -rf build ros2_ws/build ros2_ws/install ros2_ws/log
