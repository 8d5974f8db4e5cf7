"""Small scene builders shared by the tests (dicts in the public scene schema)."""
from __future__ import annotations

import copy

import numpy as np

#: a valid scene with one item of each kind, for tests that break it one key at a time
GOOD = {
    "agents": {"positions": [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], "radius": 0.2},
    "walls": [{"kind": "halfplane", "normal": [0, 1], "offset": -1.0},
              {"kind": "segment", "a": [-2, 3], "b": [2, 3]}],
    "obstacles": [{"kind": "circle", "center": [3, 3], "radius": 0.5}],
    "drift": {"kind": "goal", "goal": [5, 5], "speed": 1.0},
    "noise": {"sigma": 0.1},
}

#: the value :func:`variant` takes to remove a key
MISSING = object()


def variant(path: str, value) -> dict:
    """GOOD with the item at a dotted path (list items by index) replaced by value, or removed
    when value is MISSING."""
    d = copy.deepcopy(GOOD)
    *keys, last = path.split(".")
    node = d
    for k in keys:
        node = node[int(k)] if isinstance(node, list) else node[k]
    if isinstance(node, list):
        node[int(last)] = value
    elif value is MISSING:
        del node[last]
    else:
        node[last] = value
    return d


def hex_jam(rows: int, cols: int, radius: float = 0.24, spacing: float = 0.5,
            sigma: float = 0.1) -> dict:
    """rows x cols agents on a hexagonal lattice, all heading for its centre."""
    pos = [(c * spacing + (r % 2) * spacing / 2, r * spacing * np.sqrt(3) / 2)
           for r in range(rows) for c in range(cols)]
    pos = np.array(pos)
    centre = pos.mean(axis=0)
    return {"agents": {"positions": pos.tolist(), "radius": radius},
            "drift": {"kind": "goal", "goal": centre.tolist(), "speed": 1.0, "slow_radius": 0.5},
            "noise": {"sigma": sigma}}


def wall_agent(x0: float = 0.5, radius: float = 0.5, sigma: float = 1.0) -> dict:
    """One agent beside the wall x >= radius (half-plane of normal (1, 0) at offset 0)."""
    return {"agents": {"positions": [[x0, 0.0]], "radius": radius},
            "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0}],
            "noise": {"sigma": sigma}}
