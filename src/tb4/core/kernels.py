"""The C kernels, one home: which ones exist, how each is built, and the one error when one is missing.

The hot loops of the simulator and the navigation core are small C extensions (plain C99 + the Python C API,
no NumPy C API) built by CMakeLists.txt at `pip install`. A module that needs one calls `load_kernel(name)` when
it is constructed (not at import, so importing tb4 never fails for a missing build); a kernel that is not built
raises KernelNotBuilt, which says how to build it: reinstall, or compile that one file into the source tree.

There is no NumPy fallback: each kernel is the NumPy code it replaced, operation for operation (the tests compare
them), and a silent slow path would hide a broken install.
"""

from __future__ import annotations

import importlib
import shlex
import sys
import sysconfig
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

__all__ = ["KERNELS", "Kernel", "KernelNotBuilt", "build_command", "load_kernel"]


@dataclass(frozen=True)
class Kernel:
    """One C extension: its module, its source (relative to the repository) and its compiler flags, the same
    as CMakeLists.txt gives it."""

    module: str
    source: str
    flags: tuple[str, ...] = ("-O2",)
    libraries: tuple[str, ...] = ()


KERNELS: dict[str, Kernel] = {
    k.module: k
    for k in (
        Kernel("tb4.nav._gridsearch", "src/tb4/nav/_gridsearch.c"),
        # no fused multiply-adds the source does not ask for: results must round exactly as the NumPy code's
        Kernel("tb4.sim._raymarch", "src/tb4/sim/_raymarch.c", ("-O2", "-ffp-contract=off"), ("m",)),
        Kernel("tb4.nav._costmapkernel", "src/tb4/nav/_costmapkernel.c", ("-O2", "-ffp-contract=off"), ("m",)),
        Kernel("tb4.core._distance", "src/tb4/core/_distance.c", ("-O2",), ("m",)),
    )
}


class KernelNotBuilt(RuntimeError):
    """A C kernel is not importable; the message says how to build it."""


def build_command(name: str) -> str:
    """The compiler command that builds kernel `name` into the source tree (for development; `pip install`
    builds every kernel through CMakeLists.txt)."""
    kernel = KERNELS[name]
    output = kernel.source[: -len(".c")] + str(sysconfig.get_config_var("EXT_SUFFIX") or ".so")
    args = ["gcc", *kernel.flags, "-shared", "-fPIC", "-std=c99", f"-I{sysconfig.get_paths()['include']}"]
    args += [kernel.source, *(f"-l{lib}" for lib in kernel.libraries), "-o", output]
    return shlex.join(args)


def load_kernel(name: str) -> ModuleType:
    """Import the C kernel `name` (a key of KERNELS), or raise KernelNotBuilt saying how to build it."""
    if name not in KERNELS:
        raise KeyError(f"unknown C kernel {name!r}; known: {', '.join(sorted(KERNELS))}")
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        root = Path(__file__).resolve().parents[3]
        raise KernelNotBuilt(
            f"the C extension {name} is not built ({exc}). Reinstall the package (`make install`, or "
            f"`{sys.executable} -m pip install --no-deps --no-build-isolation -e .` in {root}), "
            f"or for development compile it into the source tree, from {root}: {build_command(name)}"
        ) from exc
