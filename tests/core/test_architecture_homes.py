"""Each small helper has one home (tb4.core): nobody writes the quaternion maths, the angle wrap, the
(sec, nanosec) sum, a timeout exception or the robot's radius again elsewhere.

The "spin a node on a thread" home (tb4.ros.background) is checked in test_architecture.py.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src"

#: pattern -> (what it is, the files allowed to contain it, why)
RULES: dict[str, tuple[str, set[str]]] = {
    r"atan2\(\s*2(\.0)?\s*\*": ("quaternion -> yaw", {"tb4/core/geometry.py"}),
    r"\b(sin|cos)\([^()\n]*\byaw\b[^()\n]*(/\s*2(\.0)?|\*\s*0\.5)\s*\)": (
        "yaw -> quaternion",
        {"tb4/core/geometry.py"},
    ),
    r"\b(sin|cos)\(\s*0\.5\s*\*\s*(yaw|roll|pitch)\b": ("euler -> quaternion", {"tb4/core/geometry.py"}),
    r"%\s*\(\s*2(\.0)?\s*\*\s*(math|np)\.pi\s*\)\s*-\s*(math|np)\.pi": ("angle wrap", {"tb4/core/geometry.py"}),
    r"nanosec\w*\s*\*\s*1e-9": ("(sec, nanosec) -> seconds", {"tb4/core/units.py"}),
    r"\(\s*seconds\s*-\s*\w+\s*\)\s*\*\s*1e9": ("seconds -> nanosec", {"tb4/core/units.py"}),
    r"^class \w*(Timeout|TimedOut)\w*\(": (
        "a timeout exception",
        # the one type, and the navigator's public name that upstream-style scripts catch (a subclass of it)
        {"tb4/core/waits.py", "tb4/navigator/timeouts.py"},
    ),
    r"(?<![\d.])0\.175(?!\d)": ("the robot radius (robot.yaml's drive.radius)", set()),
    # servers whose replies wait for a brand-new client's reply reader (tb4.ros.replies says why)
    r"\.create_service\(": ("a service server", {"tb4/ros/replies.py"}),
    r"\bActionServer\(": ("an action server", {"tb4/ros/action_bridge.py"}),
    # rclpy 9.1.2's send_goal_async can return a future that never completes (tb4.ros.action_client says why);
    # the navigator's executor guard only checks isinstance against rclpy's class
    r"^\s*from rclpy\.action import[^\n]*\bActionClient\b": (
        "rclpy's ActionClient",
        {"tb4/ros/action_client.py", "tb4/navigator/basic_navigator.py"},
    ),
    # a C kernel is imported only by the loader (load_kernel), which says how to build a missing one
    r"^\s*(from tb4\.[\w.]+ import \(?\s*_[a-z]\w*|import tb4\.[\w.]+\._[a-z]\w*)": (
        "a C kernel's import",
        {"tb4/core/kernels.py"},
    ),
}


def _sources() -> list[Path]:
    return sorted(p for p in SRC.rglob("*.py") if "static" not in p.parts)


@pytest.mark.parametrize("pattern", list(RULES))
def test_helper_written_only_in_its_home(pattern: str) -> None:
    what, homes = RULES[pattern]
    regex = re.compile(pattern, re.M)
    offenders = []
    for path in _sources():
        name = path.relative_to(SRC).as_posix()
        if name in homes:
            continue
        text = path.read_text(encoding="utf-8")
        offenders += [f"{name}:{text.count(chr(10), 0, m.start()) + 1}" for m in regex.finditer(text)]
    assert offenders == [], f"{what} written outside {sorted(homes) or 'tb4.core'}: {offenders}"


def test_the_params_are_the_only_yaml_with_the_robot_radius() -> None:
    """robot.yaml says the robot's size once; nav2.yaml takes its robot_radius from it."""
    yamls = sorted((SRC / "tb4").rglob("*.yaml"))
    with_radius = [
        p.relative_to(SRC).as_posix() for p in yamls if re.search(r"^\s*(robot_)?radius:\s*0\.175", p.read_text(), re.M)
    ]
    assert with_radius == ["tb4/params/robot.yaml"]


def test_every_c_kernel_has_its_source_and_its_cmake_target() -> None:
    """tb4.core.kernels.KERNELS lists every C source under src/, and CMakeLists.txt builds each one with the same
    flags the loader's development command uses."""
    from tb4.core.kernels import KERNELS

    root = SRC.parent
    sources = sorted(p.relative_to(root).as_posix() for p in SRC.rglob("*.c"))
    assert sorted(k.source for k in KERNELS.values()) == sources
    cmake = (root / "CMakeLists.txt").read_text(encoding="utf-8")
    built = re.search(r"function\(tb4_kernel package name\)(.*?)endfunction\(\)", cmake, re.S)
    assert built, "CMakeLists.txt builds the kernels with tb4_kernel()"
    assert "Python3_add_library(${name} MODULE WITH_SOABI ${source})" in built.group(1)
    assert "target_compile_options(${name} PRIVATE -O2 ${ARGN})" in built.group(1)
    assert "install(TARGETS ${name} LIBRARY DESTINATION ${SKBUILD_PLATLIB_DIR}/tb4/${package})" in built.group(1)
    for kernel in KERNELS.values():
        package, target = kernel.module.split(".")[1:]
        assert kernel.source == f"src/tb4/{package}/{target}.c"
        call = re.search(rf"^tb4_kernel\({package} {target}( [^)]*)?\)$", cmake, re.M)
        assert call, target
        assert ("-O2", *(call.group(1) or "").split()) == kernel.flags, target
