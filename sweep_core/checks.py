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
        got = show(value)
        if isinstance(value, (float, np.floating)) and float(value).is_integer():
            # 2e1 or 20.0 reads as a float: say so, since it prints as 20
            got = f"{float(value)!r}, written with a decimal point or an exponent"
        raise SceneError(field, f"must be an integer >= {low}, got {got}",
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


#: largest |coordinate| (m) accepted for positions, wall ends, obstacles, spawn regions, goals
#: and map origins, and largest length (m) for radii.
#:
#: Why 1e4 m: with every coordinate within L, one ulp of a coordinate is at most L * 2^-52 and
#: each float operation rounds by at most u = 2^-53 of its result. The distance from a centre
#: q to a wall segment [a, b] goes through the foot p = a + s (b - a): the product s (b - a)
#: (size up to 2 L) and the sum (size up to L) round each component by up to 3 L u, so the
#: distance |q - p| is off by up to sqrt(2) * 3 L u (about 4.2 L u); the linearised row
#: <e, y> >= <e, p> + r adds the rounding of the products <e, p> and <e, y> (about 2 L u
#: each): about 10 L u in all (on random segments the distance error measures 0.87 L * 2^-52,
#: typically). The feasibility check accepts 1e-9 m; keeping the arithmetic's own error a
#: hundred times below it, 10 L u <= 1e-11 m, gives L <= 9e3 m: 1e4 m, where 10 L u is
#: 1.1e-11 m. At 1e16 m one ulp is 2 m, and a wall's distance is meaningless.
COORDINATE_BOUND = 1e4

#: largest |coordinate| (m) of an agent's position. Agents need not share the walls' bound: a
#: centre within a radius of a wall segment lies within COORDINATE_BOUND + r of the origin
#: anyway, a half-plane's value <n, q> - c rounds by about 2 |q| u, and pair distances are
#: differences of nearby floats. What bounds a position is its own resolution: one ulp at
#: 1e6 m is 1.2e-10 m, and <n, q> rounds by 2.2e-10 m there, still below the 1e-9 m tolerance
#: (rows of agents spread along a wall, 40 m apart, reach 1e5 m).
POSITION_BOUND = 1e6

#: the largest speed (m/s) a scene gives (drift speeds, agents' and groups' preferred
#: speeds): one step of the longest time step, 1 s (io/limits.py), moves an agent at most the
#: coordinate bound; at 1e20 m/s a goal drift's first step was refused as "infeasible" (rows
#: broken by 1e18 m), which named the radii and not the speed
MAX_SPEED = COORDINATE_BOUND / 1.0


def speed(value: Any, field: str, *, positive: bool = False, fix: str = "") -> float:
    """A speed (m/s): a finite number >= 0 (> 0 when ``positive``), at most MAX_SPEED."""
    v = number(value, field, positive=positive, nonnegative=not positive, fix=fix)
    if v > MAX_SPEED:
        raise SceneError(field, f"{show(v)} m/s is above {MAX_SPEED:g} m/s, where a step of 1 s "
                         "would leave the scene's coordinate bound",
                         fix or f"set {field} to at most {MAX_SPEED:g} m/s (walking: about 1.3)")
    return v


def velocities(v: np.ndarray, field: str, each: bool = False) -> np.ndarray:
    """The velocities v (K, 2) m/s, refused naming ``field`` (``field[k]`` when ``each``) when
    one is faster than MAX_SPEED, as every speed is."""
    fast = np.flatnonzero(np.hypot(v[:, 0], v[:, 1]) > MAX_SPEED)
    if len(fast):
        k = int(fast[0])
        name = f"{field}[{k}]" if each else field
        raise SceneError(name, f"{show(v[k])} is {show(float(np.hypot(*v[k])))} m/s, above "
                         f"{MAX_SPEED:g} m/s, where a step of 1 s would leave the "
                         "scene's coordinate bound",
                         f"give {name} a speed of at most {MAX_SPEED:g} m/s")
    return v


def within_bound(arr: np.ndarray, field: str, what: str = "coordinate",
                 bound: float = COORDINATE_BOUND, magnitude: bool = False) -> np.ndarray:
    """``arr`` (finite floats) unchanged, or SceneError naming the first entry whose
    magnitude exceeds ``bound`` (:data:`COORDINATE_BOUND`, or :data:`POSITION_BOUND` for
    agents' positions). ``magnitude``: the values are sizes (radii, ranges), which no shift
    of the scene's origin changes, and the fix says so."""
    if arr.size and float(np.max(np.abs(arr))) > bound:
        bad = tuple(int(b) for b in np.argwhere(np.abs(arr) > bound)[0])
        where = f"[{', '.join(str(b) for b in bad)}]" if bad else ""
        holds = ("distances to walls hold to 1e-11 m" if bound == COORDINATE_BOUND
                 else "positions hold to 2.2e-10 m")
        plural = what[:-2] + "i" if what.endswith("us") else what + "s"
        raise SceneError(f"{field}{where}", f"{what} {show(arr[bad])} m is beyond the bound "
                         f"{bound:g} m within which float64 {holds}",
                         f"set {field}{where} to at most {bound:g} m" if magnitude else
                         f"use {plural} within +-{bound:g} m (shift the scene's origin near "
                         "its centre)")
    return arr


def point(value: Any, field: str) -> np.ndarray:
    """A finite 2-vector [x, y] (m) within +-COORDINATE_BOUND."""
    return within_bound(vec2(value, field), field)


def points(value: Any, field: str) -> np.ndarray:
    """Finite points (n, 2) [[x, y], ...] (m) within +-COORDINATE_BOUND."""
    return within_bound(array(value, field, (None, 2), "as [[x, y], ...]"), field)


def length(value: Any, field: str, *, positive: bool = False, nonnegative: bool = False,
           what: str = "length") -> float:
    """A finite length or coordinate (m), as :func:`number`, of magnitude at most
    COORDINATE_BOUND; ``what`` names it in the message."""
    x = number(value, field, positive=positive, nonnegative=nonnegative)
    within_bound(np.array(x), field, what, magnitude=positive or nonnegative)
    return x


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


def items(value: Any, field: str, fix: str) -> list:
    """A scene's optional list: [] when absent (None), the list itself, else SceneError naming
    the field, the value (with its type) and ``fix``."""
    if value is None:
        return []
    if not isinstance(value, list):
        raise SceneError(field, f"must be a list, got {type(value).__name__} {show(value)}", fix)
    return value


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


def text(value: Any, field: str, most: int) -> str:
    """Free text: a string (a number is written as text) of at most ``most`` characters."""
    if isinstance(value, bool) or not isinstance(value, (str, int, float)):
        raise SceneError(field, f"must be text, got {type(value).__name__} {show(value)}",
                         f"write {field} as one string (quote it if it holds ':' or '[')")
    out = str(value)
    if len(out) > most:
        raise SceneError(field, f"has {len(out)} characters, more than {most}",
                         f"write {field} in at most {most} characters")
    return out
