"""The layout promises: the core never imports ROS, every module states its public names."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "tb4"
ROS_MODULES = (
    "rclpy",
    "rosidl",
    "nav2_msgs",
    "irobot_create_msgs",
    "tf2_msgs",
    "geometry_msgs",
    "nav_msgs",
    "sensor_msgs",
    "std_msgs",
    "builtin_interfaces",
    "lifecycle_msgs",
    "rosgraph_msgs",
    "action_msgs",
)
CORE_PACKAGES = ("core", "sim", "nav")


def _modules(package: str) -> list[Path]:
    return sorted((SRC / package).rglob("*.py"))


def _imported_names(path: Path) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", CORE_PACKAGES)
def test_core_packages_never_import_ros(package: str) -> None:
    offenders = {
        str(path.relative_to(SRC)): sorted(_imported_names(path) & set(ROS_MODULES)) for path in _modules(package)
    }
    assert {k: v for k, v in offenders.items() if v} == {}


def test_importing_the_whole_core_loads_no_ros_module() -> None:
    code = (
        "import sys, tb4.core.geometry, tb4.core.units, tb4.core.directions, tb4.core.maps, tb4.core.robot_params, "
        "tb4.core.waits, tb4.sim.simulation, tb4.sim.render, tb4.nav.server, tb4.sim.world;"
        f"bad = [m for m in sys.modules if m.split('.')[0] in {ROS_MODULES!r}];"
        "print(bad); sys.exit(1 if bad else 0)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr


def test_every_module_declares_its_public_names() -> None:
    missing = []
    for path in sorted(SRC.rglob("*.py")):
        if path.name == "__init__.py" or path.name.startswith("_") or "static" in path.parts:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        targets = [t for n in tree.body if isinstance(n, ast.Assign) for t in n.targets]
        targets += [n.target for n in tree.body if isinstance(n, ast.AnnAssign)]
        has_all = any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets)
        if not has_all:
            missing.append(str(path.relative_to(SRC)))
    assert missing == []


#: Where an executor may be built: the one background-spinner helper, and loops that spin in the foreground.
EXECUTOR_HOMES = {"ros/background.py", "ros/simulator.py", "ros/future_waits.py", "tutorials/natural_language_nav.py"}


def test_nodes_are_spun_on_threads_only_by_the_background_helper() -> None:
    """tb4.ros.background is the one home of "spin a node on a thread": nobody else builds an executor for a
    thread or starts a thread that spins."""
    offenders = []
    for path in sorted(SRC.rglob("*.py")):
        name = path.relative_to(SRC).as_posix()
        if name == "ros/background.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Call):
                continue
            called = ast.unparse(node.func)
            pools = ("ThreadPoolExecutor", "ProcessPoolExecutor")  # concurrent.futures: no ROS executor
            if called.endswith("Executor") and not called.endswith(pools) and name not in EXECUTOR_HOMES:
                offenders.append(f"{name}:{node.lineno} builds {called}")
            target = next((k.value for k in node.keywords if k.arg == "target"), None)
            if called.endswith("Thread") and target is not None and "spin" in ast.unparse(target):
                offenders.append(f"{name}:{node.lineno} starts a spinning thread")
    assert offenders == []
