"""The C kernels' one loader: every kernel loads through it, and a missing one fails with how to build it."""

from __future__ import annotations

import pytest

from tb4.core import kernels
from tb4.core.kernels import KERNELS, Kernel, KernelNotBuilt, build_command, load_kernel

pytestmark = pytest.mark.core


@pytest.mark.parametrize("name", sorted(KERNELS))
def test_every_kernel_loads(name: str) -> None:
    assert load_kernel(name).__name__ == name


def test_a_missing_kernel_says_how_to_build_it(monkeypatch: pytest.MonkeyPatch) -> None:
    missing = Kernel("tb4.nav._not_built", "src/tb4/nav/_not_built.c", ("-O2", "-ffp-contract=off"), ("m",))
    monkeypatch.setitem(kernels.KERNELS, missing.module, missing)
    with pytest.raises(KernelNotBuilt) as err:
        load_kernel(missing.module)
    message = str(err.value)
    assert "tb4.nav._not_built is not built" in message
    assert "pip install --no-deps --no-build-isolation -e ." in message
    assert build_command(missing.module) in message
    assert isinstance(err.value, RuntimeError)


def test_build_command_names_flags_source_and_output() -> None:
    command = build_command("tb4.sim._raymarch")
    assert command.startswith("gcc -O2 -ffp-contract=off -shared -fPIC -std=c99 -I")
    assert " src/tb4/sim/_raymarch.c -lm -o src/tb4/sim/_raymarch." in command


def test_an_unknown_kernel_is_a_key_error() -> None:
    with pytest.raises(KeyError, match="known: "):
        load_kernel("tb4.nav._nothing")
