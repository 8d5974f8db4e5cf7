"""The ``evacuation`` scene of ``sweep bench speed``: equal disks jammed at a door.

N disks of radius 0.25 m on a square lattice of spacing 0.62 m jittered by up to 4 cm, in a
square room (23 m wide for N <= 1000, wider in proportion to sqrt(N) above, so that the crowd
fits) with one 1.2 m door in the middle of its east wall; a geodesic drift (1.3 m/s) leads
everyone to a goal 3 m beyond the door; sigma 0.05 m/sqrt(s), dt 0.02 s. After about 8 s
(400 steps) the crowd presses against the door and the walls round it: equal radii pressed
against walls and each other give dependent active rows (more active rows than coordinates
locally), the degenerate case of the certified projection.
"""
from __future__ import annotations

import math

import numpy as np

from sweep_core.model.scene import Scene

#: radius (m), lattice spacing (m), jitter (m), door width (m), drift speed (m/s)
RADIUS, SPACING, JITTER, DOOR, SPEED = 0.25, 0.62, 0.04, 1.2, 1.3
#: time step of the scene (s)
DT = 0.02


def room_side(n: int) -> float:
    """Side (m) of the square room of n agents: 23 m up to 1000, then 23 sqrt(n / 1000)."""
    return 23.0 * max(1.0, math.sqrt(n / 1000.0))


def evacuation(n: int, seed: int = 0, mixed: bool = False) -> Scene:
    """The scene of the module docstring with n agents (seeded jitter); mixed: radii drawn
    uniformly in [0.20, 0.27] m instead (seeded), the polydisperse crowd the equal one is
    compared with."""
    rng = np.random.default_rng(seed)
    side = room_side(n)
    cols = int(math.ceil(math.sqrt(n)))
    width = (cols - 1) * SPACING
    start = 0.5 * (side - width)
    grid = np.array([(start + c * SPACING, start + r * SPACING)
                     for r in range(cols) for c in range(cols)][:n])
    pos = grid + rng.uniform(-JITTER, JITTER, grid.shape)
    radius = rng.uniform(0.20, 0.27, n).tolist() if mixed else RADIUS
    lo, hi = 0.5 * (side - DOOR), 0.5 * (side + DOOR)
    walls = [{"kind": "segment", "a": a, "b": b} for a, b in (
        ([0.0, 0.0], [side, 0.0]), ([side, 0.0], [side, lo]), ([side, hi], [side, side]),
        ([side, side], [0.0, side]), ([0.0, side], [0.0, 0.0]))]
    return Scene.from_dict({
        "agents": {"positions": pos.tolist(), "radius": radius},
        "walls": walls,
        "drift": {"kind": "geodesic", "goal": [side + 3.0, 0.5 * side], "speed": SPEED},
        "noise": {"sigma": 0.05}})
