# The two commands of the README: `make demo` (main job) and `make test` (the test suite, as CI runs it).
# Both create .venv/ and install everything when needed; when nothing changed the install step is a no-op.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.tb4-installed
INSTALL_INPUTS := pyproject.toml CMakeLists.txt tools/install.sh $(shell find interfaces -type f 2>/dev/null) \
                  $(wildcard src/tb4/nav/*.c)
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST

.PHONY: demo test install lint typecheck bench clean

demo: $(STAMP)
	$(VENV)/bin/tb4 run nav_to_pose

test: $(STAMP)
	bash tools/install_browser.sh
	$(PY) -m ruff check src tests bench tools
	$(PY) -m ruff format --check src tests bench tools
	$(PY) -m mypy
	$(PY) -m pytest

install: $(STAMP)

$(STAMP): $(INSTALL_INPUTS)
	PYTHON=$(PYTHON) VENV=$(VENV) bash tools/install.sh
	touch $(STAMP)

lint:
	$(PY) -m ruff check src tests bench tools && $(PY) -m ruff format --check src tests bench tools

typecheck:
	$(PY) -m mypy

bench: $(STAMP)
	$(PY) bench/run.py

clean:
	rm -rf build $(VENV)
