"""Small validators shared by the scene, field and simulator options.

Each returns the cleaned value or raises :class:`SceneError` naming the field and the fix.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from sweep_core.errors import SceneError


def number(value: Any, field: str, *, positive: bool = False, nonnegative: bool = False) -> float:
    """A finite float (optionally > 0 or >= 0)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SceneError(field, f"must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise SceneError(field, f"must be finite, got {value!r}")
    if positive and value <= 0:
        raise SceneError(field, f"must be > 0, got {value!r}")
    if nonnegative and value < 0:
        raise SceneError(field, f"must be >= 0, got {value!r}")
    return value


def integer(value: Any, field: str, *, low: int = 0, fix: str = "") -> int:
    """An int (numpy integers too, never a bool) >= low."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise SceneError(field, f"must be an integer >= {low}, got {value!r}", fix)
    return int(value)


def array(value: Any, field: str, shape: tuple[int | None, ...], what: str = "") -> np.ndarray:
    """A finite float64 array of the given shape (None = any length)."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise SceneError(field, f"must be numbers{what and ' ' + what}, got {value!r}") from err
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
        raise SceneError(field, f"has shape {arr.shape}, expected {want}{what and ' ' + what}")
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise SceneError(field, f"holds a non-finite number at index {tuple(int(b) for b in bad)}")
    return arr


def vec2(value: Any, field: str) -> np.ndarray:
    """A finite 2-vector, written [x, y]."""
    return array(value, field, (2,), "as [x, y]")


def per_agent(value: Any, n: int, field: str, *, positive: bool = False,
              nonnegative: bool = False) -> np.ndarray:
    """A scalar broadcast to (n,), or a list of n numbers."""
    if np.ndim(value) == 0:
        arr = np.full(n, number(value, field, positive=positive, nonnegative=nonnegative))
    else:
        arr = array(value, field, (n,), f"(one per agent, {n} agents)")
    if positive and np.any(arr <= 0):
        i = int(np.argmin(arr))
        raise SceneError(field, f"must be > 0, agent {i} has {arr[i]!r}")
    if nonnegative and np.any(arr < 0):
        i = int(np.argmin(arr))
        raise SceneError(field, f"must be >= 0, agent {i} has {arr[i]!r}")
    return arr


def mapping(value: Any, field: str, allowed: set[str] | None = None,
            required: set[str] | None = None) -> dict:
    """A dict whose keys are within ``allowed`` and include ``required``."""
    if not isinstance(value, dict):
        raise SceneError(field, f"must be a mapping, got {type(value).__name__}")
    if allowed is not None:
        extra = set(value) - allowed
        if extra:
            raise SceneError(field, f"unknown keys {sorted(extra)}", f"allowed keys: {sorted(allowed)}")
    for key in sorted(required or ()):
        if key not in value:
            raise SceneError(f"{field}.{key}", "missing", "add it")
    return value


def kind(value: dict, field: str, kinds: Any, default: str | None = None) -> str:
    """The ``kind`` of a tagged mapping, one of ``kinds``."""
    k = value.get("kind", default)
    if k not in kinds:
        raise SceneError(f"{field}.kind", f"unknown kind {k!r}", f"use one of {sorted(kinds)}")
    return str(k)
