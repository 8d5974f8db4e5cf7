"""The accuracy study behind ``sweep bench accuracy``: error against time step, scheme and solver
tolerance, on problems with exact answers and on a crowd against a fine-dt reference.

Every run of a problem, at every dt, is driven by the *same* Brownian path: increments are drawn
once at the finest level and summed into the coarser ones (reference §5). Errors carry a 95 %
confidence interval; log-log slopes are fitted on the levels whose error is resolved (larger
than its interval) with an interval from a bootstrap over the independent paths.

Problems (a), exact answers:

``rbm_wall``   reflected Brownian motion at a flat wall (sigma = 1, no drift, from the wall, T = 1),
    M agents far apart along one wall, one path each. The reference is the Skorokhod map of the
    continuous Brownian path: between the points of the finest grid the path's minimum is drawn
    from the Brownian bridge law, so the reference is exact, X(t) = h(t) + max(0, max -h).
    strong: E|X^h_T - X_T|; sup: E max_n |X^h(t_n) - X(t_n)| (the maximum over the grid adds a
    log factor, like the modulus of continuity of B: its fitted slope sits below 1/2);
    weak: E X^h_T - E|x + B_T| = E[X^h_T - X_T] (the reference has exactly the law of
    |x + B_T|, so the paired difference estimates the weak error with a small variance).
``rbm_ou``     reflected Ornstein-Uhlenbeck at a flat wall, U = -kappa * gap, from gap x0: the
    odd drift makes the reflected process |Y| with Y the free OU, so
    E X_T = E|N(x0 e^{-kappa T}, (1 - e^{-2 kappa T}) / (2 kappa))| in closed form. Weak error
    paired against a reference on the same path (bridge-corrected Euler at dt_min / 16, whose own
    mean is checked against the closed form and printed).
``moving_wall`` sigma = 0, a half-plane moving at constant speed pushes a disk:
    x(t) = max(x0, c0 + v t + r). sup-norm error over the grid.
``circle``     sigma = 0, a disk of radius r driven at speed V along +x slides around a circular
    obstacle of radius R (rho = R + r): tan(theta/2) = tan(theta0/2) e^{-V t / rho} while in
    contact, then a straight line from (0, rho) once theta = pi/2. sup-norm error over the grid.

Problem (b): ``crowd``, 120 agents of radii 0.18-0.22 m in a walled room with a round obstacle,
goal drift and sigma = 0.2, against projected Euler at dt_min / ref_factor on the same path;
error = mean over agents of |q^h(T) - q_ref(T)|, interval over independent paths (Student t).

``features`` times a step of a free-flowing 120-agent crowd without walls, noise and radius law
against the same crowd with each of them (model only what a scene requires); nobody touches
anybody in any variant, so the differences are the cost of modelling each feature.
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from sweep_core.model.scene import Scene
from sweep_core.numerics.projection import SolverOptions
from sweep_core.numerics.schemes import SCHEMES, Scheme, adaptive
from sweep_core.numerics.simulator import Simulator

Z95 = 1.959963984540054

PROBLEMS = ("rbm_wall", "rbm_ou", "moving_wall", "circle", "crowd", "features")


# -- configuration --------------------------------------------------------------------------
@dataclass(frozen=True)
class Variant:
    """One scheme with one solver setting, as a row group of the study."""

    label: str
    scheme: type[Scheme]
    tol: str = ""
    #: the scheme's own error is measured with the projection certified to 1e-12 m, far below
    #: it (the solver_tols variants show what a looser projection adds)
    solver: SolverOptions = field(default_factory=lambda: SolverOptions(tol=1e-12))

    def __post_init__(self) -> None:
        if not self.tol:
            object.__setattr__(self, "tol", f"{self.solver.method}:{self.solver.tol:g}")


@dataclass(frozen=True)
class StudyConfig:
    quick: bool = False
    seed: int = 0
    levels: int = 6
    wall_paths: int = 20000       # agents (independent paths) of rbm_wall and rbm_ou
    crowd_paths: int = 4
    crowd_t: float = 1.0
    crowd_dt0: float = 0.04
    crowd_ref_factor: int = 8
    feature_steps: int = 40
    det_dt0: float = 0.1          # coarsest dt of the deterministic problems
    adaptive_tols: tuple[float, ...] = (0.5, 0.25)
    solver_tols: tuple[float, ...] = (1e-9, 1e-6, 1e-3)

    @classmethod
    def make(cls, quick: bool, seed: int = 0) -> StudyConfig:
        if quick:
            return cls(quick=True, seed=seed, wall_paths=2000, crowd_paths=3, crowd_t=0.32,
                       crowd_dt0=0.08, crowd_ref_factor=4, feature_steps=15, det_dt0=0.2,
                       adaptive_tols=(0.5,), solver_tols=(1e-3,))
        return cls(seed=seed)


def solver_variant(tol: float) -> SolverOptions | None:
    """The certified projection at tolerance tol (m; no overlap at any tol), or None if this
    build's SolverOptions has no such setting."""
    try:
        return dataclasses.replace(SolverOptions(), tol=float(tol))
    except (TypeError, ValueError):
        return None


def variants(cfg: StudyConfig, with_solver_tols: bool) -> list[Variant]:
    out = [Variant("projected_euler", SCHEMES["projected_euler"]),
           Variant("bridge", SCHEMES["bridge"])]
    for tol in cfg.adaptive_tols:
        out.append(Variant(f"adaptive({tol:g})", adaptive(tol)))
    if with_solver_tols:
        for tol in cfg.solver_tols:
            opts = solver_variant(tol)
            if opts is not None:
                out.append(Variant("projected_euler", SCHEMES["projected_euler"], "", opts))
    return out


# -- results --------------------------------------------------------------------------------
@dataclass
class Measurement:
    problem: str
    metric: str
    scheme: str
    dt: float
    tol: str
    error: float
    ci: float                       # 95 % half-width
    wall_per_s: float               # wall seconds per simulated second (the batch as run)
    substeps: float                 # mean (sub-)steps per step
    samples: int
    values: np.ndarray | None = None  # per-path values, error = |mean(values)|

    @property
    def resolved(self) -> bool:
        return self.error > max(self.ci, 1e-12)


@dataclass
class Slope:
    problem: str
    metric: str
    scheme: str
    tol: str
    slope: float
    lo: float
    hi: float
    used: int
    levels: int
    note: str = ""


def summary(values: np.ndarray, student: bool = False) -> tuple[float, float]:
    """|mean| and the 95 % half-width of the mean (normal quantile, or Student t for few)."""
    n = len(values)
    mean = float(np.mean(values))
    if n < 2:
        return abs(mean), math.nan
    q = float(stats.t.ppf(0.975, n - 1)) if student else Z95
    return abs(mean), q * float(np.std(values, ddof=1)) / math.sqrt(n)


def fit_slope(ms: list[Measurement], seed: int = 0, boot: int = 400) -> Slope:
    """Log-log least-squares slope of error against dt over the resolved levels.

    Interval: the union of the Student-t interval of the regression (model misfit) and, when
    per-path values are kept, the 2.5-97.5 % percentiles of the slope refitted on bootstrap
    resamples of the paths (the same resample at every level: the paths are common)."""
    m0 = ms[0]
    use = [m for m in ms if m.resolved]
    base = Slope(m0.problem, m0.metric, m0.scheme, m0.tol, math.nan, math.nan, math.nan,
                 len(use), len(ms))
    if all(m.error <= 1e-12 for m in ms):
        base.note = "exact to rounding"
        return base
    if len(use) < 3:
        base.note = f"unresolved: error within its CI at {len(ms) - len(use)}/{len(ms)} levels"
        return base
    x = np.log([m.dt for m in use])
    y = np.log([m.error for m in use])
    res = stats.linregress(x, y)
    slope = float(res.slope)
    if len(use) > 2 and np.isfinite(res.stderr):
        half = float(stats.t.ppf(0.975, len(use) - 2)) * float(res.stderr)
    else:
        half = 0.0
    lo, hi = slope - half, slope + half
    if all(m.values is not None for m in use):
        n = len(use[0].values)
        rng = np.random.default_rng(seed)
        vals = np.stack([m.values for m in use])
        fits = []
        for _ in range(boot):
            idx = rng.integers(0, n, n)
            e = np.abs(vals[:, idx].mean(axis=1))
            if np.all(e > 0):
                fits.append(np.polyfit(x, np.log(e), 1)[0])
        if fits:
            blo, bhi = np.percentile(fits, [2.5, 97.5])
            lo, hi = min(lo, float(blo)), max(hi, float(bhi))
    base.slope, base.lo, base.hi = slope, lo, hi
    if len(use) < len(ms):
        base.note = f"{len(ms) - len(use)} unresolved level(s) left out"
    return base


# -- helpers --------------------------------------------------------------------------------
def levels(dt0: float, n: int) -> list[float]:
    return [dt0 / 2 ** k for k in range(n)]


def coarse(fine: np.ndarray, factor: int) -> np.ndarray:
    """Sum consecutive groups of ``factor`` increments: (n, ...) -> (n / factor, ...)."""
    if fine.shape[0] % factor:
        raise ValueError(f"{fine.shape[0]} fine steps do not split into groups of {factor}")
    return fine.reshape((fine.shape[0] // factor, factor) + fine.shape[1:]).sum(axis=1)


def bridge_min(a: np.ndarray, b: np.ndarray, var: float, u: np.ndarray) -> np.ndarray:
    """Minimum of a Brownian bridge from a to b with variance var over the step, drawn with u."""
    return 0.5 * (a + b - np.sqrt((a - b) ** 2 - 2.0 * var * np.log(u)))


def run_variant(scene: Scene, v: Variant, dt: float, dB: np.ndarray | None, steps: int,
         observe: Callable[[Simulator], None] | None = None) -> tuple[float, float]:
    """Step a fresh simulator; returns (wall seconds, mean sub-steps per step)."""
    sim = Simulator(scene, dt=dt, seed=0, scheme=v.scheme, solver=v.solver)
    wall = 0.0
    for k in range(steps):
        t0 = time.perf_counter()
        sim.step(1, None if dB is None else dB[k])
        wall += time.perf_counter() - t0
        if observe is not None:
            observe(sim)
    sub = getattr(sim.scheme, "total_substeps", steps)
    return wall, sub / max(steps, 1)


def wall_scene(m: int, r: float, x0: float, sigma: float, drift: dict | None = None) -> Scene:
    return Scene.from_dict({
        "agents": {"positions": [[r + x0, 40.0 * k] for k in range(m)], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0}],
        "noise": {"sigma": sigma}, "drift": drift or {"kind": "none"}})


def group_slopes(ms: list[Measurement], seed: int = 0) -> list[Slope]:
    groups: dict[tuple, list[Measurement]] = {}
    for m in ms:
        groups.setdefault((m.problem, m.metric, m.scheme, m.tol), []).append(m)
    return [fit_slope(sorted(g, key=lambda m: -m.dt), seed) for g in groups.values()]
