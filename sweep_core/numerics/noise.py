"""Brownian increments: independent 2-D Brownian motions, one per agent.

Increments are drawn as sqrt(h) * standard normals from a seeded numpy Generator (PCG64), so
a seed fixes the whole path and runs that differ only in sigma share the same path (the
sigma -> 0 study). A scene with sigma = 0 everywhere draws nothing.
"""
from __future__ import annotations

import numpy as np


def generator(seed: int) -> np.random.Generator:
    """The project's random generator for a seed."""
    return np.random.Generator(np.random.PCG64(seed))


def increments(rng: np.random.Generator, h: float, n: int) -> np.ndarray:
    """Increments of n independent 2-D standard Brownian motions over a step h (s): shape
    (n, 2), each component N(0, h). The scheme multiplies them by sigma (m / sqrt(s))."""
    return np.sqrt(h) * rng.standard_normal((n, 2))
