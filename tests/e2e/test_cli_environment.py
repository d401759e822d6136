"""`tb4` on a broken or incomplete install says what is missing and how to fix it, without a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from tb4.processes import tb4_command


def _tb4(args: list[str], env: dict[str, str], timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run(tb4_command(*args), env=env, capture_output=True, text=True, timeout=timeout)


def test_missing_interface_package_is_reported_with_the_fix(tmp_path: Path) -> None:
    broken = tmp_path / "nav2_msgs"
    broken.mkdir()
    (broken / "__init__.py").write_text("raise ImportError('simulated failed interface build')\n")
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    result = _tb4(["sim", "--rate", "max"], env)
    assert result.returncode == 3
    output = result.stdout + result.stderr
    assert "nav2_msgs" in output and "make install" in output
    assert "Traceback" not in output
    doctor = _tb4(["doctor"], env)
    assert doctor.returncode == 1 and "nav2_msgs.action" in doctor.stdout and "MISSING" in doctor.stdout


def test_bad_arguments_get_a_clear_message(tmp_path: Path) -> None:
    env = dict(os.environ)
    for args, expected in (
        (["sim", "--world", "warehose"], "did you mean 'warehouse'"),
        (["sim", "--rate", "fast-ish"], "rate must be a positive number or 'max'"),
        (["run", "nav_to_pos"], "did you mean 'nav_to_pose'"),
        (["pose", "1", "nan"], "finite"),
    ):
        result = _tb4(args, env)
        output = result.stdout + result.stderr
        assert result.returncode != 0, args
        assert expected in output, (args, output)
        assert "Traceback" not in output, (args, output)


def test_safe_network_default_is_set_by_the_navigator_not_by_import_tb4() -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY")}
    plain = (
        "import os, tb4, tb4.core.geometry, tb4.sim.simulation; print(os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE'))"
    )
    result = subprocess.run([sys.executable, "-c", plain], env=env, capture_output=True, text=True, timeout=60)
    assert result.stdout.strip() == "None", result.stderr  # importing the library leaves the environment alone
    code = "import os, tb4.navigator; print(os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'])"
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert result.stdout.strip() == "LOCALHOST", result.stderr
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"  # an explicit choice is respected
    result = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60)
    assert result.stdout.strip() == "SUBNET"


BLAS_THREADS = """
import ctypes, numpy
path = next(line.split()[-1] for line in open("/proc/self/maps") if "openblas" in line)
library = ctypes.CDLL(path)
names = ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads")
print(next(getattr(library, name)() for name in names if hasattr(library, name)))
"""


def test_numpy_blas_runs_one_thread_in_our_processes_unless_the_user_chose() -> None:
    # a second OpenBLAS thread spins for work after NumPy's import and after each BLAS call (tb4.rosenv)
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    for first, expected in (("import tb4.navigator", "1"), ("import tb4", str(os.cpu_count()))):
        result = subprocess.run(
            [sys.executable, "-c", first + "\n" + BLAS_THREADS], env=env, capture_output=True, text=True, timeout=60
        )
        assert result.stdout.strip() == expected, (first, result.stdout, result.stderr)  # import tb4 changes nothing
    env["OPENBLAS_NUM_THREADS"] = "2"  # an explicit choice is respected
    result = subprocess.run(
        [sys.executable, "-c", "import tb4.navigator\n" + BLAS_THREADS],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.stdout.strip() == "2", result.stderr
