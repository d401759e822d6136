# The two commands of the README: `make demo` (main job) and `make test` (the test suite and the docs build, as CI
# runs it). Both create .venv/ and install everything when needed; when nothing changed the install step is a no-op.
# `make docs` builds the documentation site (mkdocs.yml) into build/site.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.tb4-installed
# The Jazzy environment (ROS 2 Jazzy's own middleware and rosidl, nav2_msgs as TurtleBot 4s on Jazzy speak it) lives
# beside the default Kilted one; the Jazzy wire environment (Jazzy's nav2_msgs on Kilted's middleware, an overlay of
# .venv) is the other half of the cross-distro stage.
JAZZY_VENV := .venv-jazzy
JAZZY_STAMP := $(JAZZY_VENV)/.tb4-installed
JAZZY_WIRE_VENV := .venv-jazzy-wire
JAZZY_WIRE_STAMP := $(JAZZY_WIRE_VENV)/.tb4-installed
INSTALL_INPUTS := pyproject.toml CMakeLists.txt tools/install.sh tools/time_step.py tools/venv_overlay.py \
                  tools/interface_cache.py tools/pyproject_requirements.py tools/shared_cache.py tools/wheel_cache.py \
                  $(shell find interfaces -type f 2>/dev/null) \
                  $(wildcard src/tb4/nav/*.c src/tb4/sim/*.c src/tb4/core/*.c)
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
# pytest-xdist workers per test stage (two stages run side by side). A DDS test waits part of its time (discovery, a
# paced simulator, a process starting), so more tests than cores run at once: on a 2-core machine, three per stage
# keep it busy without the crowding that makes each test cost more CPU (fewer leave it partly idle, more only add
# CPU). The DDS tests are handed out first and the short core tests last (tests/conftest.py), so they fill the end of
# the run. Each worker has a DDS domain of its own (tests/conftest.py); --dist loadgroup keeps the tests that share a
# module-scoped simulator on one worker. TEST_WORKERS=0: no xdist; JAZZY_TEST_WORKERS: the Jazzy stage's own.
TEST_WORKERS ?= 3
JAZZY_TEST_WORKERS ?= $(TEST_WORKERS)
xdist = $(if $(filter 0,$(1)),,-n $(1) --dist loadgroup)
XDIST := $(call xdist,$(TEST_WORKERS))
# The docs tools (pyproject.toml's [docs] extra), installed into .venv by the first `make docs` and again when
# pyproject.toml changes; tools/install.sh installs them too.
DOCS_STAMP := $(VENV)/.tb4-docs-installed
SITE := build/site

# .venv is always the Kilted build and .venv-jazzy the Jazzy one: the recipes below set TB4_ROS_DISTRO themselves.
# A TB4_ROS_DISTRO=jazzy in the environment (tools/install.sh's variable) would otherwise get a Kilted .venv without
# a word, so make stops and names the Jazzy target. It may stay set for the Jazzy targets, which agree with it.
ifneq ($(filter-out kilted,$(TB4_ROS_DISTRO)),)
ifneq ($(filter-out install-jazzy install-jazzy-wire test-jazzy test-cross-distro clean,$(or $(MAKECMDGOALS),demo)),)
$(error TB4_ROS_DISTRO=$(TB4_ROS_DISTRO): make builds .venv for Kilted only. For a Jazzy robot run \
`make install-jazzy` (.venv-jazzy, tested by `make test-jazzy`), or `TB4_ROS_DISTRO=jazzy VENV=DIR bash \
tools/install.sh` for an environment of its own; unset TB4_ROS_DISTRO for the other targets)
endif
endif

.PHONY: demo test test-jazzy test-cross-distro install install-jazzy install-jazzy-wire lint typecheck docs bench clean \
        bytecode

demo: $(STAMP) bytecode
	$(VENV)/bin/tb4 run nav_to_pose

# Our sources' bytecode, written ahead (only what changed): where PYTHONDONTWRITEBYTECODE is set, as on this machine,
# every process compiles each tb4 module it imports again, about 0.1 s of CPU per process, and make test starts
# hundreds. Python checks each file's timestamp, so a stale one is never used.
bytecode: $(STAMP)
	@$(PY) -m compileall -q src > /dev/null

# The Kilted environment is installed first; then the Kilted stage runs (tools/test_suites.sh) with, beside it, the
# lint and type checks and the docs build, and the Jazzy environments' install (a no-op when they are installed)
# followed by the Jazzy stage and the cross-distro stage. The tests run with bytecode writing on (whatever the caller's PYTHONDONTWRITEBYTECODE): pytest
# keeps each test module's assertion-rewritten bytecode in tests/**/__pycache__ (ignored by git), where with it off
# every worker rewrote and compiled every test module again, about twice the CPU of a collection from the cache.
test: export PYTHONDONTWRITEBYTECODE =
test: $(STAMP) bytecode
	bash tools/install_browser.sh
	JAZZY_INSTALL="$(MAKE) --no-print-directory $(JAZZY_STAMP) $(JAZZY_WIRE_STAMP)" \
	  CHECKS="$(MAKE) --no-print-directory lint typecheck docs" \
	  KILTED_PYTEST="$(PY) -m pytest $(XDIST) $(addprefix --ignore=,$(JAZZY_STAGE_ONLY) $(CROSS_TESTS))" \
	  JAZZY_PYTEST="$(JAZZY_PYTEST)" CROSS_PYTEST="$(CROSS_PYTEST)" bash tools/test_suites.sh

# The same simulator, navigator, tutorials and viewer on ROS 2 Jazzy's own middleware and nav2_msgs: the interface and
# wire tests, then the DDS and e2e suites, less the core tests (no DDS) and the tests that run in the Kilted stage
# only (below).
JAZZY_TESTS := tests/core/test_interface_definitions.py tests/core/test_wire.py tests/core/test_jazzy_standard_types.py \
  tests/core/test_one_stage_packages.py tests/ros tests/e2e
# Tests whose subject no nav2_msgs field reaches run once, in one stage: they test our code, which is the same in both
# builds, and each middleware (Kilted's rclpy and Fast DDS 3, Jazzy's rclpy and Fast DDS 2.14) still runs the
# simulator, the navigator, the tutorials and the viewer in its own stage (tests/core/test_one_stage_packages.py checks
# which middleware each stage runs on).
# Which stage is a matter of balance: the Kilted stage is the longer (it has the core tests), and one stage running
# alone at the end leaves the machine partly idle, so each stage gets the share that makes both end together.
# - Mechanics: the simulator's loop and world reset, `tb4 pose` (geometry_msgs' initialpose and
#   amcl_pose), a spinner at rclpy.shutdown (Kilted stage); the CLI's errors and network defaults, and the viewer's
#   fleet drawing and picking (its NavigateToPose goals are the one-robot viewer's, whose browser tests run in both)
#   (Jazzy stage).
# - Tests whose only nav2_msgs traffic is navigate_to_pose goals, which the tutorial, script and navigator tests of
#   both stages send too, and whose subject is elsewhere: the language executor over DDS (hostile programs refused,
#   the parking brake; its other commands are the Create 3's dock and undock) and a fleet's namespaces (two
#   navigators, two robots) (Kilted stage).
# - The Create 3 tests: only irobot_create_msgs, geometry_msgs, nav_msgs and sensor_msgs, never nav2_msgs (Jazzy
#   stage: they wait on simulated time at a few times real time, a long stretch of a worker's time).
# - A user's own missions, the test kit and sweeps: `tb4 run` and `tb4 sweep` around a mission (their missions'
#   nav2_msgs goals are the tutorials'), and Foxglove serving, which forwards whatever bytes DDS carries (Jazzy
#   stage, with the recording report through tb4 run); the recorder against what was published, the navigator's
#   signal handling and liveness, named places
#   over the world topic, the docs' examples, and bursts of requests and replies (QoS depth) (Kilted stage).
KILTED_STAGE_ONLY := tests/ros/test_sim_loop.py tests/ros/test_cmd_pose.py \
  tests/ros/test_spinner_at_shutdown.py tests/ros/test_language_nav.py tests/ros/test_fleet_over_dds.py \
  tests/ros/test_navigator_signals.py tests/ros/test_navigator_liveness.py tests/ros/test_places_over_dds.py \
  tests/e2e/test_docs_examples.py tests/ros/test_recording_complete.py tests/ros/test_reply_burst.py \
  tests/ros/test_world_reset_over_dds.py tests/ros/test_sim_teardown_bound.py
JAZZY_STAGE_ONLY := tests/e2e/test_cli_environment.py tests/e2e/test_viewer_fleet.py \
  tests/ros/test_create3_drive_goals.py tests/ros/test_create3_hazards.py tests/ros/test_create3_hostile.py \
  tests/ros/test_create3_sensors_ui.py tests/ros/test_simulator_create3.py tests/e2e/test_create3_api.py \
  tests/e2e/test_own_missions.py tests/e2e/test_testing_kit.py tests/e2e/test_sweep.py tests/e2e/test_replay.py \
  tests/e2e/test_foxglove_live.py tests/e2e/test_foxglove_run.py tests/e2e/test_recording_report.py
# Tests whose nav2_msgs traffic the other tests of the Jazzy stage send too, and whose subject is elsewhere, run in
# the Kilted stage only:
# - the longest missions (three runs: the patrol's charge cycle, the fleet delivery with two seeds): over nav2_msgs
#   nothing but navigate_to_pose (docking and the battery are irobot_create_msgs and sensor_msgs, the same in both
#   builds); their length tests the simulation, not the wire;
# - `tb4 run`'s terminal and command-line mechanics: the mail delivery's menu and its end at end of input, create_path
#   with poses sent by `tb4 pose`, the quiet and list modes, a killed `tb4 run` (navigate_to_pose and follow_waypoints
#   goals, which nav_to_pose, nav_through_poses and follow_waypoints send here through the same `tb4 run` monitor);
# - the upstream patrol and mail delivery scripts (navigate_to_pose goals, the battery, docking), which the upstream
#   nav_to_pose, nav_through_poses, follow_waypoints and create_path scripts cover here over nav2_msgs.
KILTED_STAGE_ONLY_TESTS := $(addprefix tests/e2e/test_tutorials.py::,test_patrol_loop_full_charge_cycle \
    test_fleet_delivery_three_robots_deliver_everything_and_dock test_mail_delivery_menu_in_a_terminal \
    test_mail_delivery_ends_cleanly_at_end_of_input test_create_path_from_poses_sent_with_tb4_pose \
    test_quiet_and_list_modes test_a_killed_tb4_run_leaves_neither_its_simulator_nor_its_tutorial_running) \
  $(addprefix tests/ros/test_upstream_scripts.py::,test_mail_delivery_driven_from_stdin test_patrol_loop_one_lap \
    test_patrol_loop_stops_on_a_critical_battery)
JAZZY_PYTEST := $(JAZZY_VENV)/bin/python -m pytest $(call xdist,$(JAZZY_TEST_WORKERS)) -o cache_dir=.pytest_cache_jazzy $(JAZZY_TESTS) \
  $(addprefix --ignore=,$(KILTED_STAGE_ONLY)) $(addprefix --deselect=,$(KILTED_STAGE_ONLY_TESTS))
# The Jazzy stage alone (make test runs it beside the Kilted stage).
test-jazzy: $(JAZZY_STAMP)
	$(JAZZY_PYTEST)

# The cross-distro stage: the pairs users have, a process on ROS 2 Jazzy's own middleware with one on Kilted's, both
# speaking Jazzy's nav2_msgs (every type hash the same on both sides): a Jazzy navigator driving a simulator on the
# Jazzy wire environment, a navigator there driving a simulator on Jazzy, a tutorial across the pair. Run by the
# Jazzy environment's pytest; tests/cross/conftest.py finds the other environment in TB4_CROSS_PEER_VENV.
CROSS_TESTS := tests/cross
CROSS_PYTEST := env TB4_CROSS_PEER_VENV=$(JAZZY_WIRE_VENV) $(JAZZY_VENV)/bin/python -m pytest $(call xdist,$(JAZZY_TEST_WORKERS)) \
  -o cache_dir=.pytest_cache_cross $(CROSS_TESTS)
test-cross-distro: $(JAZZY_STAMP) $(JAZZY_WIRE_STAMP)
	$(CROSS_PYTEST)

install: $(STAMP)

install-jazzy: $(JAZZY_STAMP)

install-jazzy-wire: $(JAZZY_WIRE_STAMP)

$(STAMP): $(INSTALL_INPUTS)
	PYTHON=$(PYTHON) VENV=$(VENV) TB4_ROS_DISTRO=kilted bash tools/install.sh
	touch $(STAMP)

# A whole environment of its own: Jazzy's ROS wheels (pyproject.toml's [tool.tb4.jazzy]), every interface package
# built with Jazzy's rosidl, the Python dependencies (from the same wheel cache).
$(JAZZY_STAMP): $(INSTALL_INPUTS)
	PYTHON=$(PYTHON) VENV=$(JAZZY_VENV) TB4_ROS_DISTRO=jazzy bash tools/install.sh
	touch $(JAZZY_STAMP)

# An overlay of the Kilted environment (tools/venv_overlay.py): it builds only Jazzy's nav2_msgs and takes the rest
# (the ROS wheels, the other interface packages, the Python dependencies) from .venv.
$(JAZZY_WIRE_STAMP): $(INSTALL_INPUTS) $(STAMP)
	VENV=$(JAZZY_WIRE_VENV) TB4_ROS_DISTRO=jazzy TB4_BASE_VENV=$(VENV) bash tools/install.sh
	touch $(JAZZY_WIRE_STAMP)

lint: $(STAMP)
	$(PY) -m ruff check src tests bench tools
	$(PY) -m ruff format --check src tests bench tools

# mypy's cache is shared by every clone on the machine, like the interface build cache (MYPY_CACHE_DIR chooses
# another), so a fresh clone's check starts from another clone's work instead of from nothing. mypy still checks
# each module's source against it (a type error added in one clone is reported there).
typecheck: export MYPY_CACHE_DIR ?= $(or $(XDG_CACHE_HOME),$(HOME)/.cache)/turtlebot4-navigator/mypy
typecheck: $(STAMP)
	$(PY) -m mypy

# The documentation site, built strictly: a broken link, a missing page or an API reference that does not resolve
# fails (make test runs it beside the lint and type checks). The CLI reference is generated from the argparse
# parsers at each build (tools/mkdocs_hooks.py), never committed. Not --quiet: it hides the warnings --strict counts.
docs: $(STAMP) $(DOCS_STAMP)
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --site-dir $(SITE)

$(DOCS_STAMP): pyproject.toml tools/pyproject_requirements.py | $(STAMP)
	set -o pipefail; $(PY) tools/pyproject_requirements.py extra docs | xargs -d '\n' $(PY) -m pip install -q
	touch $(DOCS_STAMP)

bench: $(STAMP)
	$(PY) bench/run.py

clean:
	rm -rf build $(VENV) $(JAZZY_VENV) $(JAZZY_WIRE_VENV)
