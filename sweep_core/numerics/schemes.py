"""Time-stepping schemes, registered by name in :data:`SCHEMES`.

A scheme maps the state at t_n to the state at t_{n+1} = t_n + h. The base class owns the
template (prediction, projection, bookkeeping); a scheme subclass provides ``predict`` and may
override ``step``. What a subclass must provide:

* ``name``: the registry key;
* ``predict(t, q, h, dB, drift, sigma) -> (N, 2)``: the unconstrained update;
* optionally ``correct(t, q, h, dB, pred, sigma) -> (N, 2)``: a change of the prediction
  before the projection (default: none);
* optionally ``step`` for schemes that are not predict-then-project.

The schemes (``sweep bench accuracy`` measures their trade of accuracy against time):

``projected_euler`` (default)
    q_{n+1} = P_{C~(t_{n+1}, q_n)}[q_n + h U(t_n, q_n) + sigma (B_{n+1} - B_n)] (reference §4).
    Strong and weak order 1/2 at walls and contacts (reference §5).

``bridge``
    Projected Euler whose prediction is first corrected, row by row, for the wall and obstacle
    contacts that the Brownian path made *between* the grid times. For every (agent, wall or
    obstacle) row with sigma_i > 0, the gap along the row's unit normal n (taken at q_n) moves
    over the step as a 1-D Brownian motion with variance sigma_i^2 per second and a frozen
    drift, from a = g(t_n, q_n) to the linearised b = g(t_{n+1}, q_n) + <n, p - q_n>. Given its
    end points, its minimum m over the step is the minimum of a Brownian bridge, sampled exactly:
    P(m <= y) = exp(-2 (a - y)(b - y) / (sigma^2 h)) for y <= min(a, b) (Borodin and Salminen,
    Handbook of Brownian Motion, 2002). If m < 0 the path touched the wall, and the 1-D Skorokhod
    map of the step ends at b - m: the prediction is pushed out by -m along n. The usual
    projection then enforces every row, agent-agent contacts included (those are *not*
    corrected: order 1/2 as for projected Euler).
    Exact in law, for any h, for one agent at a flat wall (half-plane, fixed or moving at
    constant speed) with constant drift, sigma and radius, and for two orthogonal flat walls
    (the normal components are independent); the weak order 1 claim (drift frozen over a step,
    as in Euler's scheme) is for flat walls with a Lipschitz drift. At curved obstacles and
    segment ends the normal is frozen at q_n; ``sweep bench accuracy`` measures all of these.
    With sigma = 0 it is projected Euler bit for bit.

``adaptive``
    Sub-steps by bisection (the bridge scheme on each piece, Brownian midpoints drawn from the
    Brownian bridge, so the sum of the sub-increments is the step's increment) wherever an agent
    that ends the piece in contact (positive multiplier) was predicted to move more than
    ``tolerance`` x the smallest radius, or where the piece's linearised set is empty, down to
    2^-max_depth of the step. Agents in free flight never trigger a sub-step. ``adaptive(tol)``
    makes the class with another tolerance.

Randomness inside a step (bridge minima, Brownian midpoints) is drawn from a generator seeded
by a hash of the step's time and Brownian increments: a seeded run stays reproducible bit for
bit, and runs on the same Brownian path draw the same corrections.
"""
from __future__ import annotations

import hashlib
import math
import struct
from dataclasses import dataclass

import numba
import numpy as np

from sweep_core.errors import InfeasibleError, SceneError
from sweep_core.model.elementary import log
from sweep_core.model.fields import Field
from sweep_core.model.geometry import single_values
from sweep_core.model.scene import Scene
from sweep_core.numerics.projection import Projection, SolverOptions, project


@dataclass(frozen=True)
class StepResult:
    """One step: q_new (N, 2) m, prediction (N, 2) m, projection details.

    ``prediction - q_new`` is the reaction of the step (the increment of K)."""

    q_new: np.ndarray
    prediction: np.ndarray
    projection: Projection


def step_generator(t: float, dB: np.ndarray | None, salt: int) -> np.random.Generator:
    """A generator that is a deterministic function of (t, dB, salt) (see the module doc)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(struct.pack("<dq", float(t), int(salt)))
    if dB is not None:
        h.update(np.ascontiguousarray(dB, dtype=np.float64).tobytes())
    return np.random.Generator(np.random.PCG64(np.frombuffer(h.digest(), dtype=np.uint64)))


class Scheme:
    """Base class of the schemes; see the module docstring."""

    name = ""

    def __init__(self, scene: Scene, solver: SolverOptions) -> None:
        self.scene = scene
        self.solver = solver
        #: the last projection, whose multipliers warm-start the next one
        self.warm: Projection | None = None

    def reset(self) -> None:
        """Forget what carries over between steps (the warm start): called by
        ``Simulator.reset``, so a run after a reset is the run from the start."""
        self.warm = None

    @property
    def label(self) -> str:
        """Name with the settings that distinguish it (for tables and plots)."""
        return self.name

    def predict(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None,
                drift: Field, sigma: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def correct(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None,
                pred: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """Change of the prediction before the projection; none by default."""
        return pred

    def step(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None, drift: Field,
             sigma: np.ndarray) -> StepResult:
        """Advance from (t, q) by h with Brownian increments dB (N, 2) or None (sigma = 0)."""
        pred = self.correct(t, q, h, dB, self.predict(t, q, h, dB, drift, sigma), sigma)
        t1 = t + h
        proj = project(self.scene.geometry, t1, q, pred, self.scene.radii(t1), self.solver,
                       warm=self.warm)
        self.warm = proj
        return StepResult(proj.y, pred, proj)


class ProjectedEuler(Scheme):
    """q_{n+1} = P_{C~(t_{n+1}, q_n)}[q_n + h U(t_n, q_n) + sigma (B_{n+1} - B_n)] (reference §4)."""

    name = "projected_euler"

    def predict(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None, drift: Field,
                sigma: np.ndarray) -> np.ndarray:
        pred = q.copy() if drift.is_zero else q + h * drift(t, q)
        if dB is not None:
            pred += sigma[:, None] * dB
        return pred


#: bridge minima with 2ab / (sigma^2 h) above this are never negative in practice
#: (probability exp(-40) < 5e-18), so those rows are not sampled
_BRIDGE_SKIP = 40.0


class BridgeReflection(ProjectedEuler):
    """Projected Euler with the Brownian-bridge correction of wall and obstacle contacts."""

    name = "bridge"

    def correct(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None,
                pred: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        geom = self.scene.geometry
        if dB is None or geom.is_empty or len(q) == 0 or not np.any(sigma):
            return pred
        t1 = t + h
        now = single_values(geom, t, q, self.scene.radii(t))
        then = single_values(geom, t1, q, self.scene.radii(t1))
        var = (sigma * sigma * h)[:, None]
        move = pred - q
        rng = None
        out = pred
        for (g0, nrm, _), (g1, _, _) in zip(now, then):
            if g0.size == 0:
                continue
            a = np.maximum(g0, 0.0)
            b = g1 + np.einsum("nkc,nc->nk", nrm, move)
            # rows of noisy agents whose bridge can reach the wall
            live = (var > 0) & ((b < 0) | (2.0 * a * np.maximum(b, 0.0) < _BRIDGE_SKIP * var))
            agent, item = np.nonzero(live)
            if len(agent) == 0:
                continue
            if rng is None:
                rng = step_generator(t, dB, 1)
                out = pred.copy()
            aa, bb, vv = a[agent, item], b[agent, item], var[agent, 0]
            u = 1.0 - rng.random(len(agent))  # (0, 1]
            m = 0.5 * (aa + bb - np.sqrt((aa - bb) ** 2 - 2.0 * vv * log_each(u)))
            push = np.maximum(-m, 0.0)
            np.add.at(out, agent, push[:, None] * nrm[agent, item])
        return out


#: a multiplier (m) above this marks a contact for the adaptive scheme (interior-point solvers
#: leave tiny positive multipliers on rows that are not touching)
_CONTACT_REACTION = 1e-9


class AdaptiveSubstep(BridgeReflection):
    """Bridge steps, bisected where a contacting agent moves far against the radii."""

    name = "adaptive"
    #: largest predicted displacement of an agent in contact per sub-step, in smallest radii
    tolerance = 0.5
    #: at most 2**max_depth sub-steps per step
    max_depth = 5

    def __init__(self, scene: Scene, solver: SolverOptions) -> None:
        super().__init__(scene, solver)
        self.last_substeps = 0
        self.total_substeps = 0

    @property
    def label(self) -> str:
        return f"adaptive({self.tolerance:g})"

    def step(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None, drift: Field,
             sigma: np.ndarray) -> StepResult:
        self.last_substeps = 0
        res, reaction = self._piece(t, q, h, dB, drift, sigma, 0)
        self.total_substeps += self.last_substeps
        return StepResult(res.q_new, res.q_new + reaction, res.projection)

    def _needs_split(self, q: np.ndarray, res: StepResult, t1: float) -> bool:
        proj = res.projection
        rows = proj.rows
        pair = proj.lam_pair > _CONTACT_REACTION
        touching = np.concatenate([rows.pair_i[pair], rows.pair_j[pair],
                                   rows.single_a[proj.lam_single > _CONTACT_REACTION]])
        if len(touching) == 0:
            return False
        d = res.prediction[touching] - q[touching]
        disp = float(np.sqrt(np.einsum("ij,ij->i", d, d)).max())
        return disp > self.tolerance * float(self.scene.radii(t1).min())

    def _piece(self, t: float, q: np.ndarray, h: float, dB: np.ndarray | None, drift: Field,
               sigma: np.ndarray, depth: int) -> tuple[StepResult, np.ndarray]:
        """Advance one piece; returns its result and its summed reaction."""
        try:
            res = super().step(t, q, h, dB, drift, sigma)
            split = depth < self.max_depth and self._needs_split(q, res, t + h)
        except InfeasibleError:
            if depth >= self.max_depth:
                raise
            split = True
        if not split:
            self.last_substeps += 1
            return res, res.prediction - res.q_new
        half = 0.5 * h
        dB1 = dB2 = None
        if dB is not None:
            z = step_generator(t, dB, 2).standard_normal(dB.shape)
            dB1 = 0.5 * dB + math.sqrt(0.25 * h) * z  # Brownian bridge at mid-step
            dB2 = dB - dB1
        r1, k1 = self._piece(t, q, half, dB1, drift, sigma, depth + 1)
        r2, k2 = self._piece(t + half, r1.q_new, half, dB2, drift, sigma, depth + 1)
        return r2, k1 + k2


def adaptive(tolerance: float, max_depth: int = 5) -> type[AdaptiveSubstep]:
    """The adaptive scheme with another tolerance (in smallest radii, > 0) and depth (>= 0),
    to pass as ``Simulator(..., scheme=adaptive(0.25))``."""
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise SceneError("scheme.tolerance", f"must be a number > 0, got {tolerance!r}")
    if isinstance(max_depth, bool) or not isinstance(max_depth, int) or max_depth < 0:
        raise SceneError("scheme.max_depth", f"must be an integer >= 0, got {max_depth!r}")
    return type(f"AdaptiveSubstep_{tolerance:g}_{max_depth}", (AdaptiveSubstep,),
                {"tolerance": float(tolerance), "max_depth": max_depth})


#: registry of schemes by name
SCHEMES: dict[str, type[Scheme]] = {
    cls.name: cls for cls in (ProjectedEuler, BridgeReflection, AdaptiveSubstep)}


@numba.njit(cache=True, nogil=True)
def log_each(u: np.ndarray) -> np.ndarray:
    """log(u) of each entry (K,) with the same bits on every CPU (:mod:`.elementary`'s; numpy's
    and the C library's logs differ in the last bit between CPU variants, and it decides
    positions here)."""
    out = np.empty_like(u)
    for k in range(u.shape[0]):
        out[k] = log(u[k])
    return out
