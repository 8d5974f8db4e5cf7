"""``kernels.compiled_count`` (the node's ``kernels_compiled_late`` once a second): the loaded
modules are scanned for kernels once, and again only after an import, and the count still sees
every compilation, of a kernel found before or of one imported later."""
from __future__ import annotations

import sys
import types

import pytest

from sweep_core.numerics import kernels

SOURCE = """
import numba

@numba.njit(cache=False)
def twice(x):
    return 2 * x
"""


def late_module(monkeypatch: pytest.MonkeyPatch, name: str) -> types.ModuleType:
    """A sweep_core module with one uncached kernel, imported now (removed after the test)."""
    module = types.ModuleType(name)
    exec(compile(SOURCE, f"<{name}>", "exec"), module.__dict__)
    monkeypatch.setitem(sys.modules, name, module)
    return module


def test_a_kernel_compiled_later_is_counted(monkeypatch) -> None:
    start = kernels.compiled_count()
    first = late_module(monkeypatch, "sweep_core.late_kernels_one")
    assert kernels.compiled_count() == start  # found, not compiled yet
    assert first.twice(3) == 6
    assert kernels.compiled_count() == start + 1
    assert first.twice(1.5) == 3.0  # a new signature of a kernel already found
    assert kernels.compiled_count() == start + 2
    second = late_module(monkeypatch, "sweep_core.late_kernels_two")
    assert second.twice(4) == 8  # a module imported after the last count
    assert kernels.compiled_count() == start + 3
    assert first.twice in kernels.dispatchers() and second.twice in kernels.dispatchers()


def test_modules_are_scanned_again_only_after_an_import(monkeypatch) -> None:
    scans = []
    scan = kernels.kernels_in
    monkeypatch.setattr(kernels, "kernels_in", lambda modules: scans.append(1) or scan(modules))
    kernels.compiled_count()
    done = len(scans)
    for _ in range(20):
        kernels.compiled_count()
    assert len(scans) == done <= 1
    late_module(monkeypatch, "sweep_core.late_kernels_three")
    for _ in range(20):
        kernels.compiled_count()
    assert len(scans) == done + 1
