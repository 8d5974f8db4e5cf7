"""The grid of an ensemble: ``--vary KEY=V1,V2,...`` over scene keys and run options.

A key is a run option (``dt`` in s, ``scheme``) or a dotted path into the scene's normalised
dict (``Scene.spec``, docs/schema.md), list items by index: ``noise.sigma``,
``agents.radius``, ``agents.radius_law.rate``, ``walls.0.velocity``. The grid is the product
of the value lists in the order given; a grid point is a dict key -> value.
"""
from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from sweep_core.ensemble import paired
from sweep_core.errors import SceneError
from sweep_core.io import limits
from sweep_core.numerics.schemes import SCHEMES

#: keys that are run options, not scene keys
RUN_OPTIONS = ("dt", "scheme")

Value = float | int | str | bool
Point = dict[str, Value]


def _leaves(obj: Any, prefix: str = "") -> Iterable[str]:
    """Dotted paths of the scalar leaves of a scene dict."""
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaves(v, f"{prefix}{k}.")
    elif isinstance(obj, list):
        if all(not isinstance(v, (dict, list)) for v in obj):
            yield prefix[:-1]
        else:
            for i, v in enumerate(obj):
                yield from _leaves(v, f"{prefix}{i}.")
    else:
        yield prefix[:-1]


def _container(spec: dict, key: str) -> tuple[Any, str | int] | None:
    """The dict or list holding ``key``'s last part and that part, or None if absent."""
    parts = key.split(".")
    node: Any = spec
    for part in parts[:-1]:
        node = _child(node, part)
        if node is None:
            return None
    last: str | int = parts[-1]
    if isinstance(node, list):
        if not str(last).isdigit() or int(last) >= len(node):
            return None
        last = int(last)
    elif not isinstance(node, dict) or last not in node:
        return None
    return node, last


def _child(node: Any, part: str) -> Any:
    if isinstance(node, dict):
        return node.get(part)
    if isinstance(node, list) and part.isdigit() and int(part) < len(node):
        return node[int(part)]
    return None


def check_key(key: str, spec: dict) -> None:
    """Refuse a key that is neither a run option nor present in the scene dict."""
    if key in RUN_OPTIONS:
        return
    if key == paired.KEY and not spec.get(key):
        raise SceneError("--vary", "robots: the scene has no robots to run with and without",
                         "add a robot to the scene's robots list, or drop --vary robots")
    if not key or _container(spec, key) is None:
        known = ", ".join(list(RUN_OPTIONS) + [k for k in _leaves(spec)
                                               if not k.startswith(("agents.positions",
                                                                    "name", "description"))][:8])
        raise SceneError("--vary", f"unknown key {key!r}",
                         f"use a run option or a dotted key of the scene, e.g. {known}")


def check_value(key: str, value: Any) -> Value:
    """A value of ``key``: a finite number (numpy's as Python's) or a string; dt > 0, scheme
    a known name."""
    if isinstance(value, (np.integer, np.floating)):
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise SceneError("--vary", f"{key}: value {value!r} is not a number or a name",
                         "give scalars, e.g. noise.sigma=0.05,0.1")
    if isinstance(value, float) and not math.isfinite(value):
        raise SceneError("--vary", f"{key}: value {value:g} is not finite", "give finite numbers")
    if key == "dt" and (isinstance(value, str) or value <= 0):
        raise SceneError("--vary", f"dt: value {value!r} is not a positive number of seconds",
                         "e.g. dt=0.02,0.01")
    if key == "dt":  # the range sweep run and sweep_node accept
        limits.check_dt(value, "--vary dt")
    if key == paired.KEY and value not in (paired.WITH, paired.WITHOUT):
        raise SceneError("--vary", f"robots: value {value!r} is neither with nor without",
                         "pair runs with and without the scene's robots: robots=with,without")
    if key == "scheme" and value not in SCHEMES:
        raise SceneError("--vary", f"scheme: unknown scheme {value!r}",
                         f"use names from {sorted(SCHEMES)}")
    return value


def _scalar(text: str) -> Value:
    """``"3"`` -> 3, ``"1e-2"`` -> 0.01, anything else stays a string (a name)."""
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


def _check_kind(key: str, spec: dict, values: list[Value]) -> None:
    """A scene key that holds numbers (or a list of numbers) takes numbers only."""
    found = _container(spec, key)
    if found is None:  # not a scene key: check_key refuses it
        return
    node, last = found
    current = node[last]
    numeric = (isinstance(current, (int, float)) and not isinstance(current, bool)) or (
        isinstance(current, list) and current
        and all(isinstance(v, (int, float)) for v in current))
    for v in values:
        if numeric and isinstance(v, str):
            raise SceneError("--vary", f"{key}: value {v!r} is not a number",
                             f"give numbers, e.g. {key}=0.05,0.1")


def parse_vary(texts: Sequence[str]) -> dict[str, list[Value]]:
    """``["noise.sigma=0.05,0.1", "dt=0.02,0.01"]`` -> ``{"noise.sigma": [0.05, 0.1], ...}``.

    A value that reads as an int or a float is a number (``0.1``, ``1e-2``), otherwise a name
    (``bridge``).
    """
    vary: dict[str, list[Value]] = {}
    for text in texts:
        key, sep, values = text.partition("=")
        key = key.strip()
        if not sep or not key:
            raise SceneError("--vary", f"{text!r} is not KEY=V1,V2,...", "e.g. noise.sigma=0.05,0.1")
        if key in vary:
            raise SceneError("--vary", f"key {key!r} given twice", "give all its values in one --vary")
        parts = [v.strip() for v in values.split(",")]
        if not values.strip() or any(not v for v in parts):
            raise SceneError("--vary", f"{key}: bad value list {values!r}",
                             "give comma-separated values without empty items, e.g. "
                             f"{key}=0.05,0.1")
        vary[key] = [check_value(key, _scalar(v)) for v in parts]
    return vary


def grid(vary: Mapping[str, Sequence[Any]] | None, spec: dict) -> list[Point]:
    """Every grid point (the product of the value lists, in the order given); one empty
    point if nothing varies. Checks every key and value."""
    if not vary:
        return [{}]
    keys = list(vary)
    lists = []
    for key in keys:
        check_key(key, spec)
        values = vary[key]
        if isinstance(values, np.ndarray) and values.ndim == 1:  # e.g. np.linspace(...)
            values = values.tolist()
        if isinstance(values, (str, bytes)) or not isinstance(values, Sequence) or not values:
            raise SceneError("--vary", f"{key}: {values!r} is not a non-empty list of values",
                             f"e.g. {key}=0.05,0.1")
        checked = [check_value(key, v) for v in values]
        # by value: 1 and 1.0 (or 0.1 and 1e-1) are one grid point, not two of the same runs
        if len(set(checked)) != len(checked):
            raise SceneError("--vary", f"{key}: repeated value in {checked!r}",
                             "give each value once")
        lists.append(checked)
        if key not in RUN_OPTIONS:
            _check_kind(key, spec, lists[-1])
    return [dict(zip(keys, combo)) for combo in itertools.product(*lists)]


def point_id(point: Point) -> str:
    """A short stable name of a grid point (hash of its sorted JSON), for file names."""
    text = json.dumps(point, sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:12]


def apply(spec: dict, point: Point) -> dict:
    """A copy of the scene dict with the point's scene keys set (run options ignored)."""
    out = copy.deepcopy(spec)
    for key, value in point.items():
        if key in RUN_OPTIONS:
            continue
        if key == paired.KEY:  # with / without the robots: paired.py
            out = paired.apply(out, value)
            continue
        found = _container(out, key)
        if found is None:  # checked by grid(); kept for direct callers
            raise SceneError("--vary", f"unknown key {key!r}", "use a dotted key of the scene")
        node, last = found
        node[last] = value
    return out
