"""Small validators shared by the scene, field and simulator options.

Each returns the cleaned value or raises :class:`SceneError` naming the field, the offending
value (shown plainly, see :func:`sweep_core.errors.show`) and the fix.
"""
from __future__ import annotations

import math
import stat
from typing import Any

import numpy as np

from sweep_core.errors import SceneError, show


def _bound(positive: bool, nonnegative: bool) -> str:
    return "> 0" if positive else ">= 0" if nonnegative else ""


def number(value: Any, field: str, *, positive: bool = False, nonnegative: bool = False,
           fix: str = "") -> float:
    """A finite float (optionally > 0 or >= 0); ``fix`` replaces the generic fix."""
    bound = _bound(positive, nonnegative)
    want = f"a finite number{' ' + bound if bound else ''}"
    fix = fix or f"set {field} to {want}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SceneError(field, f"must be a number, got {show(value)}", fix)
    value = float(value)
    if not math.isfinite(value):
        raise SceneError(field, f"must be finite, got {show(value)}", fix)
    if positive and value <= 0:
        raise SceneError(field, f"must be > 0, got {show(value)}", fix)
    if nonnegative and value < 0:
        raise SceneError(field, f"must be >= 0, got {show(value)}", fix)
    return value


def integer(value: Any, field: str, *, low: int = 0, fix: str = "") -> int:
    """An int (numpy integers too, never a bool) >= low."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise SceneError(field, f"must be an integer >= {low}, got {show(value)}",
                         fix or f"set {field} to a whole number >= {low}")
    return int(value)


def array(value: Any, field: str, shape: tuple[int | None, ...], what: str = "",
          fix: str = "") -> np.ndarray:
    """A finite float64 array of the given shape (None = any length).

    ``what`` describes the layout in the message (e.g. ``"as [x, y]"``); ``fix`` replaces the
    generic fix."""
    want = "(" + ", ".join("n" if s is None else str(s) for s in shape) + ")"
    fix = fix or f"write {field} as numbers of shape {want}{what and ' ' + what}"
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as err:
        raise SceneError(field, f"must be numbers{what and ' ' + what}, got {show(value)}",
                         fix) from err
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        got = "(" + ", ".join(str(int(a)) for a in arr.shape) + ")"
        raise SceneError(field, f"has shape {got}, expected {want}{what and ' ' + what}: "
                         f"got {show(value)}", fix)
    if not np.all(np.isfinite(arr)):
        bad = tuple(int(b) for b in np.argwhere(~np.isfinite(arr))[0])
        where = ", ".join(str(b) for b in bad)
        raise SceneError(field, f"holds a non-finite number {show(arr[bad])} at index [{where}]",
                         f"replace {field}[{where}] with a finite number")
    return arr


def vec2(value: Any, field: str) -> np.ndarray:
    """A finite 2-vector, written [x, y]."""
    return array(value, field, (2,), "as [x, y]", f"write {field} as [x, y], two numbers")


def per_agent(value: Any, n: int, field: str, *, positive: bool = False,
              nonnegative: bool = False) -> np.ndarray:
    """A scalar broadcast to (n,), or a list of n numbers."""
    bound = _bound(positive, nonnegative)
    if np.ndim(value) == 0:
        arr = np.full(n, number(value, field, positive=positive, nonnegative=nonnegative))
    else:
        arr = array(value, field, (n,), f"(one per agent, {n} agents)",
                    f"give {field} one number{' ' + bound if bound else ''} for every agent, "
                    f"or a list of {n} such numbers")
    if (positive and np.any(arr <= 0)) or (nonnegative and np.any(arr < 0)):
        i = int(np.argmin(arr))
        bad = int(np.count_nonzero(arr <= 0 if positive else arr < 0))
        more = f" ({bad} agents in all)" if bad > 1 else ""
        raise SceneError(field, f"must be {bound}, agent {i} has {show(arr[i])}{more}",
                         f"set {field}[{i}] to a number {bound}")
    return arr


def mapping(value: Any, field: str, allowed: set[str] | None = None,
            required: set[str] | None = None) -> dict:
    """A dict whose keys are within ``allowed`` and include ``required``."""
    if not isinstance(value, dict):
        raise SceneError(field, f"must be a mapping, got {type(value).__name__} {show(value)}",
                         f"write {field} as 'key: value' pairs"
                         + (f" with keys {sorted(allowed)}" if allowed else ""))
    if allowed is not None:
        extra = set(value) - allowed
        if extra:
            raise SceneError(field, f"unknown keys {sorted(str(k) for k in extra)}",
                             f"remove them or use the allowed keys {sorted(allowed)}")
    for key in sorted(required or ()):
        if key not in value:
            given = sorted(str(k) for k in value)
            raise SceneError(f"{field}.{key}", f"missing (the keys given are {given})",
                             f"add {key} under {field}")
    return value


def kind(value: dict, field: str, kinds: Any, default: str | None = None) -> str:
    """The ``kind`` of a tagged mapping, one of ``kinds``."""
    k = value.get("kind", default)
    if not isinstance(k, str) or k not in kinds:
        raise SceneError(f"{field}.kind", f"unknown kind {show(k)}",
                         f"use one of {sorted(kinds)}")
    return str(k)


#: what a file of each kind is called in messages
_FILE_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISCHR, "a character device"),
               (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
               (stat.S_ISSOCK, "a socket"), (stat.S_ISREG, "a regular file"))


def file_kind(mode: int) -> str:
    """What an ``st_mode`` is, for messages: 'a folder', 'a FIFO (named pipe)', ..."""
    for test, name in _FILE_KINDS:
        if test(mode):
            return name
    return "not a regular file"
