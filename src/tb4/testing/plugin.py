"""The pytest plugin (entry point `pytest11: tb4`): fixtures for testing TurtleBot 4 missions in the built-in
simulator, with no launch file and no ROS install.

- `tb4_settings`: the simulator's settings for this test, from its `tb4` marker:
  `@pytest.mark.tb4(world="depot", seed=3, battery=0.5, exact=True, localization="truth", robots=0)`.
- `tb4_simulator`: a `tb4 sim` of the test's own (its own DDS domain, on loopback), stopped after the test;
  `tb4_simulator.finish()` stops it and returns the run's RunRecord.
- `tb4_navigator`: a TurtleBot4Navigator bound to that simulator (rclpy initialised in its domain).
- `tb4_mission(target, *arguments, module=False, time_limit=None, record=False, fail_on_bump=False, **settings)`:
  runs a script, module or tutorial under `tb4 run` in a simulator of its own; its RunRecord.
- `tb4_trial(callable, time_limit=600, **settings)`: runs `callable(navigator)` against a simulator of its own;
  its RunRecord.

Every process is ended by PID and every Fast DDS file removed; parallel tests (pytest-xdist) each get their own
domain. Assertions for the records: tb4.testing.assertions. `-p no:tb4` turns the plugin off.
"""

from __future__ import annotations

import dataclasses
import difflib
import itertools
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

from tb4.testing.record import RunRecord
from tb4.testing.simulator import SimSettings, Simulator

__all__ = ["tb4_settings", "tb4_simulator", "tb4_navigator", "tb4_mission", "tb4_trial", "settings_from"]

_FIELDS = [f.name for f in dataclasses.fields(SimSettings)]


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "tb4(world, seed, rate, battery, exact, localization, robots, namespace): the settings of the test's "
        "tb4 simulator (tb4_simulator, tb4_navigator, tb4_mission, tb4_trial)",
    )


def settings_from(base: SimSettings | None = None, **values: Any) -> SimSettings:
    """SimSettings with `values` over `base`; an unknown name fails with a "did you mean".

    Raises:
        TypeError: a name SimSettings does not have.
    """
    for name in values:
        if name not in _FIELDS:
            close = difflib.get_close_matches(name, _FIELDS, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise TypeError(f"tb4: unknown simulator setting {name!r}{hint} (settings: {', '.join(_FIELDS)})")
    return dataclasses.replace(base or SimSettings(), **values)


@pytest.fixture
def tb4_settings(request: pytest.FixtureRequest) -> SimSettings:
    """The settings of this test's simulator: SimSettings' defaults under the test's `tb4` marker."""
    marker = request.node.get_closest_marker("tb4")
    return settings_from(**(marker.kwargs if marker else {}))


@pytest.fixture
def tb4_simulator(tb4_settings: SimSettings, tmp_path: Path) -> Iterator[Simulator]:
    """A running `tb4 sim` of this test's own, stopped (by PID) after it."""
    simulator = Simulator(tb4_settings, tmp_path / "tb4-sim")
    simulator.start()
    try:
        yield simulator
    finally:
        simulator.stop()


@pytest.fixture
def tb4_navigator(tb4_simulator: Simulator, monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    """A TurtleBot4Navigator talking to `tb4_simulator`, destroyed (and rclpy shut down) after the test."""
    import rclpy

    from tb4.navigator import TurtleBot4Navigator

    if rclpy.ok():
        raise RuntimeError("rclpy is already initialised in this test process: tb4_navigator initialises it itself")
    monkeypatch.setenv("ROS_DOMAIN_ID", str(tb4_simulator.domain_id))
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    rclpy.init()
    navigator = TurtleBot4Navigator(namespace=tb4_simulator.settings.namespace)
    try:
        yield navigator
    finally:
        navigator.destroyNode()
        rclpy.try_shutdown()


_TRIAL_OPTIONS = ("module", "time_limit", "record", "fail_on_bump", "cwd")


@pytest.fixture
def tb4_mission(tb4_settings: SimSettings, tmp_path: Path) -> Callable[..., RunRecord]:
    """Run a script, module or tutorial under `tb4 run` in a simulator of its own: its RunRecord."""
    from tb4.testing.trials import run_mission

    count = itertools.count(1)

    def run(target: str | Path, *arguments: str, **options: Any) -> RunRecord:
        trial = {k: options.pop(k) for k in list(options) if k in _TRIAL_OPTIONS}
        settings = settings_from(tb4_settings, **options)
        return run_mission(
            target, list(arguments), settings, tmp_path / f"tb4-runs-{next(count)}", cwd=Path.cwd(), **trial
        )

    return run


@pytest.fixture
def tb4_trial(tb4_settings: SimSettings, tmp_path: Path) -> Callable[..., RunRecord]:
    """Run `mission(navigator)` against a simulator of its own: its RunRecord."""
    from tb4.testing.trials import run_trial

    count = itertools.count(1)

    def run(mission: Callable[[Any], Any], time_limit: float = 600.0, **settings: Any) -> RunRecord:
        return run_trial(
            mission,
            settings_from(tb4_settings, **settings),
            tmp_path / f"tb4-trial-{next(count)}",
            time_limit=time_limit,
        )

    return run
