"""The ring corridor: the boundary for measuring a fundamental diagram (speed against density)
with no change to the engine. An annulus between an inner circle obstacle and an outer wall
(a regular polygon of ``sides`` sides round the circle of radius ``outer``) closes a corridor
of width outer - inner on itself, so the density N / area stays fixed for as long as the run
lasts, as in a periodic corridor, while every contact is the engine's ordinary pair and wall
geometry. The drift is a grid field of speed v0 along the circles (counter-clockwise).

Curvature: over a headway distance s the tangent leaves the circle of radius R by s^2 / (2 R)
(0.1 m at s = 1 m, R = 5 m), which the inner radius bounds.
"""
from __future__ import annotations

import math

import numpy as np

from sweep_core.model import elementary


def ring_corridor(density: float, inner: float = 3.0, outer: float = 5.0,
                  radius: float = 0.2, speed: float = 1.34, seed: int = 0,
                  time_gap: float | None = None, margin: float | None = None,
                  sides: int = 96, cell: float = 0.1) -> dict:
    """A scene dict: round(density x area) agents of ``radius`` (m) spawned at random (seed)
    in the annulus inner < |q| < outer (m), walking at ``speed`` (m/s) round it, with the
    speed law of ``flows.headway`` with time gap ``time_gap`` (s; None: the pure model): the
    default law (csm), or with a lateral ``margin`` (m) the lanes law. density in agents/m^2."""
    area = math.pi * (outer * outer - inner * inner)
    n = int(round(density * area))
    ang = 2.0 * math.pi * np.arange(sides) / sides
    # the polygon's edges lie outside the circle of radius outer (its inscribed circle)
    rim = outer / elementary.cos(math.pi / sides)
    wall = np.stack([rim * elementary.cos_of(ang), rim * elementary.sin_of(ang)], axis=1)
    nodes = np.arange(-outer - 2 * cell, outer + 2 * cell + cell / 2, cell)
    X, Y = np.meshgrid(nodes, nodes)
    norm = np.maximum(np.hypot(X, Y), 1e-9)
    scene: dict = {
        "name": f"ring_{density:g}",
        "description": f"ring corridor {inner:g}-{outer:g} m, {n} agents, {density:g} per m^2",
        "agents": {"spawn": {"region": {"kind": "polygon", "points": wall.tolist()},
                             "count": n, "radius": radius, "seed": seed},
                   "speed": speed},
        "walls": [{"kind": "polyline", "points": wall.tolist(), "closed": True}],
        "obstacles": [{"kind": "circle", "center": [0.0, 0.0], "radius": inner}],
        "drift": {"kind": "grid", "x": nodes.tolist(), "y": nodes.tolist(),
                  "vx": (-speed * Y / norm).tolist(), "vy": (speed * X / norm).tolist()},
    }
    if time_gap is not None:
        scene["flows"] = {"headway": {"time_gap": time_gap,
                                      **({} if margin is None else {"margin": margin})}}
    return scene


def tangential_speed(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Speed (N,) m/s along the ring (counter-clockwise) of velocities v (N, 2) at q (N, 2)."""
    r = np.maximum(np.hypot(q[:, 0], q[:, 1]), 1e-12)
    return (-q[:, 1] * v[:, 0] + q[:, 0] * v[:, 1]) / r


def weidmann(density: np.ndarray | float) -> np.ndarray:
    """Weidmann's (1993) speed (m/s) at a density (agents/m^2):
    1.34 [1 - exp(-1.913 (1/rho - 1/5.4))]."""
    rho = np.asarray(density, dtype=np.float64)
    return 1.34 * (1.0 - elementary.exp_of(-1.913 * (1.0 / rho - 1.0 / 5.4)))
