"""User constraints: g(t, q_i) >= r_i(t) on each agent's centre, written in Python
(the reference's general C(t) = {q : g_k(t, q) >= 0}, §4).

A constraint is any object with

    value(t, q)    -> (N,)   g at the centres q (N, 2), m
    gradient(t, q) -> (N, 2) its gradient in q

and optionally ``name`` (for messages). Assumptions, which the engine relies on:

* g is 1-Lipschitz in q (|grad g| <= 1, as a distance is): an agent moving by d changes g
  by at most d, which is what proves rows outside the cutoff unnecessary;
* g is convex in q (the complement of a convex obstacle, e.g. a distance to it or a lower
  bound of that distance): then the linearised row g(q) + <grad g, y - q> >= r lies inside
  {g >= r} and the step's answer is feasible. For a g that is not convex the row may let a
  step through that breaks the true constraint; the post-step check then refuses that step
  (InfeasibleError), it is never accepted.

Rows are normalised to a unit normal n = grad g / |grad g| (the solver's rows have
|a_k| = 1): <n, y - q> >= (r - g) / |grad g|. User constraints live only in the Python
scene (``Scene.with_constraints``); a recording says which were used (by name) but cannot
replay them.
"""
from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from sweep_core.errors import SceneError


class Constraint(Protocol):
    """g(t, q) >= r on each centre (see the module docstring)."""

    def value(self, t: float, q: np.ndarray) -> np.ndarray: ...

    def gradient(self, t: float, q: np.ndarray) -> np.ndarray: ...


def constraint_name(c: Any, k: int) -> str:
    return str(getattr(c, "name", None) or type(c).__name__ or f"constraint {k}")


def check_constraint(c: Any, k: int) -> None:
    """Refuse an object without callable value and gradient."""
    for attr in ("value", "gradient"):
        if not callable(getattr(c, attr, None)):
            raise SceneError(f"constraints[{k}]", f"{constraint_name(c, k)} has no method {attr}"
                             "(t, q)", "give an object with value(t, q) -> (N,) and "
                             "gradient(t, q) -> (N, 2)")


def evaluate(c: Any, k: int, t: float, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """g (N,) and its gradient (N, 2) at (t, q), checked for shape and finiteness."""
    n = len(q)
    field = f"constraints[{k}]"
    g = np.asarray(c.value(t, q), dtype=float)
    grad = np.asarray(c.gradient(t, q), dtype=float)
    if g.shape != (n,):
        raise SceneError(f"{field}.value", f"{constraint_name(c, k)}.value returned shape "
                         f"{list(g.shape)} for {n} centres", "return one value per centre, (N,)")
    if grad.shape != (n, 2):
        raise SceneError(f"{field}.gradient", f"{constraint_name(c, k)}.gradient returned shape"
                         f" {list(grad.shape)} for {n} centres", "return (N, 2)")
    if not (np.all(np.isfinite(g)) and np.all(np.isfinite(grad))):
        bad = int(np.flatnonzero(~np.isfinite(g) | ~np.isfinite(grad).all(axis=1))[0])
        raise SceneError(field, f"{constraint_name(c, k)} is not finite at agent {bad}, "
                         f"t = {t:g} s", "return finite values and gradients everywhere")
    return g, grad
