"""The navigator, the simulator and the navigation core work without the optional extras ([llm], [viewer],
[render]); a feature whose extra is missing says which extra to install."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from tb4.extras import EXTRAS

BLOCKED = sorted({m for _purpose, modules in EXTRAS.values() for m in modules})

# A meta-path finder that refuses every module of every extra, as if none were installed.
_BLOCKER = textwrap.dedent(
    f"""
    import importlib.abc, sys
    BLOCKED = {BLOCKED!r}
    class Blocker(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.split('.')[0] in BLOCKED:
                raise ModuleNotFoundError(f'No module named {{name!r}} (blocked by the test)', name=name)
            return None
    sys.meta_path.insert(0, Blocker())
    import importlib.util
    _find_spec = importlib.util.find_spec
    importlib.util.find_spec = lambda name, *a: None if name.split('.')[0] in BLOCKED else _find_spec(name, *a)
    """
)


def _run(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", _BLOCKER + textwrap.dedent(code)], capture_output=True, text=True, timeout=120
    )


def test_the_extras_list_matches_pyproject() -> None:
    from pathlib import Path

    tomllib = pytest.importorskip("tomllib")
    pyproject = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())
    optional = pyproject["project"]["optional-dependencies"]
    required = " ".join(pyproject["project"]["dependencies"])
    for extra, (_purpose, modules) in EXTRAS.items():
        assert extra in optional
        for module in modules:
            assert any(req.startswith(module) for req in optional[extra]), (extra, module)
            assert module not in required, f"{module} is an extra, not a requirement"
    assert set(EXTRAS) <= set(optional["all"][0].split("[")[1].rstrip("]").split(","))


def test_core_and_simulator_import_without_extras() -> None:
    result = _run(
        """
        import tb4, tb4.core.geometry, tb4.sim.simulation, tb4.nav.server, tb4.runner.session, tb4.cli.main
        import tb4.language.executor, tb4.language.model_client
        print('ok')
        """
    )
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr


def test_navigator_imports_without_extras() -> None:
    pytest.importorskip("rclpy", reason="ROS wheels not installed")
    result = _run(
        """
        import tb4.navigator
        from nav2_simple_commander.robot_navigator import BasicNavigator
        from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Navigator
        print('ok')
        """
    )
    assert result.returncode == 0 and result.stdout.strip() == "ok", result.stderr


def test_a_missing_extra_names_the_pip_command() -> None:
    result = _run(
        """
        from tb4.language.model_client import ModelClient, ModelError, ModelSettings
        try:
            ModelClient(ModelSettings(api_key='sk-test-key'))
        except ModelError as exc:
            print(exc)
        """
    )
    assert "pip install 'turtlebot4-navigator[llm]'" in result.stdout, result.stdout + result.stderr


def test_tb4_render_without_matplotlib_says_which_extra() -> None:
    result = _run(
        """
        import sys
        from tb4.cli.main import main
        sys.exit(main(["render", "depot", "--output", "/nonexistent/never-written.png"]))
        """
    )
    assert result.returncode == 2, result.stdout + result.stderr
    assert "turtlebot4-navigator[render]" in result.stdout + result.stderr
