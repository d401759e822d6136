# The two commands of the README: `make demo` (main job) and `make test` (the test suite, as CI runs it).
# Both create .venv/ and install everything when needed; when nothing changed the install step is a no-op.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.tb4-installed
# The Jazzy build (nav2_msgs as TurtleBot 4s on Jazzy speak it) lives beside the default Kilted one.
JAZZY_VENV := .venv-jazzy
JAZZY_STAMP := $(JAZZY_VENV)/.tb4-installed
INSTALL_INPUTS := pyproject.toml CMakeLists.txt tools/install.sh tools/time_step.py $(shell find interfaces -type f 2>/dev/null) \
                  $(wildcard src/tb4/nav/*.c src/tb4/sim/*.c)
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST

.PHONY: demo test test-jazzy install install-jazzy lint typecheck bench clean

demo: $(STAMP)
	$(VENV)/bin/tb4 run nav_to_pose

test: $(STAMP)
	bash tools/install_browser.sh
	$(PY) -m ruff check src tests bench tools
	$(PY) -m ruff format --check src tests bench tools
	$(PY) -m mypy
	$(PY) -m pytest || { echo "$(RERUN_NOTE)"; $(PY) -m pytest --last-failed; }
	$(MAKE) test-jazzy

# The same simulator, navigator and tutorials over Jazzy's nav2_msgs: the interface and wire tests, the DDS tests of
# every Nav2 action and service whose wire format differs (through poses, waypoints, behaviors, path validity, the
# upstream-style scripts) and the Nav2 tutorials (the patrol and menu runs only repeat those calls). The Create 3, language, viewer and core tests do not touch nav2_msgs
# fields that differ, and run once, in the Kilted build.
JAZZY_TESTS := tests/core/test_interface_definitions.py tests/core/test_wire.py tests/core/test_jazzy_standard_types.py \
  tests/ros/test_nav2_server.py tests/ros/test_navigator_tasks.py tests/ros/test_upstream_scripts.py \
  tests/ros/test_navigator_services.py tests/ros/test_navigator_failures.py tests/e2e/test_tutorials.py
JAZZY_PYTEST := $(JAZZY_VENV)/bin/python -m pytest -o cache_dir=.pytest_cache_jazzy $(JAZZY_TESTS) \
  -k "not mail_delivery and not quiet_and_list and not patrol_loop"
# Stop-gap, stated in the issue notes: some DDS and e2e tests are timing-sensitive on a loaded 2-core machine (they
# pass alone, and fail now and then in a full run). The failed ones run once more; a second failure fails the build.
RERUN_NOTE := [make test] some tests failed: running only those once more (known DDS timing flakes under load)
test-jazzy: $(JAZZY_STAMP)
	$(JAZZY_PYTEST) || { echo "$(RERUN_NOTE)"; $(JAZZY_PYTEST) --last-failed; }

install: $(STAMP)

install-jazzy: $(JAZZY_STAMP)

$(STAMP): $(INSTALL_INPUTS)
	PYTHON=$(PYTHON) VENV=$(VENV) TB4_ROS_DISTRO=kilted bash tools/install.sh
	touch $(STAMP)

$(JAZZY_STAMP): $(INSTALL_INPUTS)
	PYTHON=$(PYTHON) VENV=$(JAZZY_VENV) TB4_ROS_DISTRO=jazzy bash tools/install.sh
	touch $(JAZZY_STAMP)

lint:
	$(PY) -m ruff check src tests bench tools && $(PY) -m ruff format --check src tests bench tools

typecheck:
	$(PY) -m mypy

bench: $(STAMP)
	$(PY) bench/run.py

clean:
	rm -rf build $(VENV) $(JAZZY_VENV)
