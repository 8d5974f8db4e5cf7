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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np
from scipy import stats

from .bench import write_csv
from .noise import generator
from .projection import SolverOptions
from .scene import Scene
from .schemes import SCHEMES, Scheme, adaptive
from .simulator import Simulator

Z95 = 1.959963984540054

PROBLEMS = ("rbm_wall", "rbm_ou", "moving_wall", "circle", "crowd", "features")


# -- configuration --------------------------------------------------------------------------
@dataclass(frozen=True)
class Variant:
    """One scheme with one solver setting, as a row group of the study."""

    label: str
    scheme: type[Scheme]
    tol: str = ""
    solver: SolverOptions = field(default_factory=SolverOptions)

    def __post_init__(self) -> None:
        if not self.tol:
            backend = getattr(self.solver, "backend", "solver")
            object.__setattr__(self, "tol", f"{backend}:{self.solver.eps_abs:g}")


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
    def make(cls, quick: bool, seed: int = 0) -> "StudyConfig":
        if quick:
            return cls(quick=True, seed=seed, wall_paths=2000, crowd_paths=3, crowd_t=0.32,
                       crowd_dt0=0.08, crowd_ref_factor=4, feature_steps=15, det_dt0=0.2,
                       adaptive_tols=(0.5,), solver_tols=(1e-3,))
        return cls(seed=seed)


def solver_variant(tol: float) -> SolverOptions | None:
    """proxsuite at tolerance tol (its rows tightened by tol, so no overlap at any tol), or
    None if this build's SolverOptions has no such setting."""
    try:
        return dataclasses.replace(SolverOptions(), eps_abs=float(tol), backend="proxsuite")
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


def _summary(values: np.ndarray, student: bool = False) -> tuple[float, float]:
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
def _levels(dt0: float, n: int) -> list[float]:
    return [dt0 / 2 ** k for k in range(n)]


def _coarse(fine: np.ndarray, factor: int) -> np.ndarray:
    """Sum consecutive groups of ``factor`` increments: (n, ...) -> (n / factor, ...)."""
    if fine.shape[0] % factor:
        raise ValueError(f"{fine.shape[0]} fine steps do not split into groups of {factor}")
    return fine.reshape((fine.shape[0] // factor, factor) + fine.shape[1:]).sum(axis=1)


def _bridge_min(a: np.ndarray, b: np.ndarray, var: float, u: np.ndarray) -> np.ndarray:
    """Minimum of a Brownian bridge from a to b with variance var over the step, drawn with u."""
    return 0.5 * (a + b - np.sqrt((a - b) ** 2 - 2.0 * var * np.log(u)))


def _run(scene: Scene, v: Variant, dt: float, dB: np.ndarray | None, steps: int,
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


def _wall_scene(m: int, r: float, x0: float, sigma: float, drift: dict | None = None) -> Scene:
    return Scene.from_dict({
        "agents": {"positions": [[r + x0, 40.0 * k] for k in range(m)], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0}],
        "noise": {"sigma": sigma}, "drift": drift or {"kind": "none"}})


# -- problems (a) -----------------------------------------------------------------------------
def study_rbm_wall(cfg: StudyConfig, log=print) -> list[Measurement]:
    """Reflected BM from the wall: strong and weak errors against the exact Skorokhod map."""
    m, r, t_end, dt0 = cfg.wall_paths, 0.1, 1.0, 0.1
    dts = _levels(dt0, cfg.levels)
    n_f = int(round(t_end / dts[-1]))
    rng = generator(cfg.seed)
    fine = math.sqrt(dts[-1]) * rng.standard_normal((n_f, m, 2))
    # exact reference on the finest grid: Skorokhod map of the continuous path (bridge minima)
    path = np.vstack([np.zeros((1, m)), np.cumsum(fine[:, :, 0], axis=0)])  # x0 = 0
    mins = _bridge_min(path[:-1], path[1:], dts[-1], 1.0 - rng.random((n_f, m)))
    local = np.vstack([np.zeros((1, m)), np.maximum.accumulate(np.maximum(-mins, 0.0), axis=0)])
    ref = path + local                                   # (n_f + 1, m)
    exact_mean = math.sqrt(2.0 / math.pi)
    mean, ci = float(ref[-1].mean()), Z95 * float(ref[-1].std(ddof=1)) / math.sqrt(m)
    log(f"  rbm_wall: reference E X_1 = {mean:.4f} +- {ci:.4f}, exact sqrt(2/pi) = {exact_mean:.4f}")
    scene = _wall_scene(m, r, 0.0, 1.0)
    out = []
    for v in variants(cfg, False):
        for k, dt in enumerate(dts):
            factor = 2 ** (cfg.levels - 1 - k)
            dB = _coarse(fine, factor)
            steps = len(dB)
            worst, last = np.zeros(m), np.zeros(m)

            def observe(sim: Simulator, worst=worst, last=last, factor=factor) -> None:
                last[:] = sim.positions[:, 0] - r
                np.maximum(worst, np.abs(last - ref[sim.n_steps * factor]), out=worst)

            wall, sub = _run(scene, v, dt, dB, steps, observe)
            weak = last - ref[-1]
            for metric, vals in (("strong", np.abs(weak)), ("sup", worst.copy()),
                                 ("weak", weak)):
                err, c = _summary(vals)
                out.append(Measurement("rbm_wall", metric, v.label, dt, v.tol, err, c,
                                       wall / t_end, sub, m, vals))
        log(f"  rbm_wall: {v.label} done")
    return out


def study_rbm_ou(cfg: StudyConfig, log=print) -> list[Measurement]:
    """Reflected OU at a wall (drift -kappa * gap): weak error against the closed form."""
    m, r, t_end, dt0, kappa, x0 = cfg.wall_paths, 0.1, 1.0, 0.1, 2.0, 0.3
    dts = _levels(dt0, cfg.levels)
    n_f = int(round(t_end / dts[-1]))
    sub_f = 16
    h_f = dts[-1] / sub_f
    rng = generator(cfg.seed + 1)
    fine = math.sqrt(dts[-1]) * rng.standard_normal((n_f, m, 2))
    # reference: bridge-corrected Euler at dts[-1] / 16 on the same path (sub-increments drawn
    # from the Brownian bridge given each finest increment)
    y = np.full(m, x0)
    for k in range(n_f):
        z = rng.standard_normal((sub_f, m))
        inc = fine[k, :, 0] / sub_f + (z - z.mean(axis=0)) * math.sqrt(h_f)
        for j in range(sub_f):
            b = y - h_f * kappa * y + inc[j]
            mn = _bridge_min(y, b, h_f, 1.0 - rng.random(m))
            y = b + np.maximum(-mn, 0.0)
    mu = x0 * math.exp(-kappa * t_end)
    s = math.sqrt((1.0 - math.exp(-2.0 * kappa * t_end)) / (2.0 * kappa))
    exact = s * math.sqrt(2 / math.pi) * math.exp(-mu * mu / (2 * s * s)) + mu * (
        1.0 - 2.0 * stats.norm.cdf(-mu / s))
    mean, ci = float(y.mean()), Z95 * float(y.std(ddof=1)) / math.sqrt(m)
    log(f"  rbm_ou: reference E X_1 = {mean:.4f} +- {ci:.4f}, closed form {exact:.4f}")
    scene = _wall_scene(m, r, x0, 1.0, {"kind": "linear", "matrix": [[-kappa, 0.0], [0.0, 0.0]],
                                        "offset": [kappa * r, 0.0]})
    out = []
    for v in variants(cfg, False):
        for k, dt in enumerate(dts):
            dB = _coarse(fine, 2 ** (cfg.levels - 1 - k))
            holder = {}
            wall, sub = _run(scene, v, dt, dB, len(dB),
                             lambda s_: holder.__setitem__("x", s_.positions[:, 0] - r))
            vals = holder["x"] - y
            err, c = _summary(vals)
            out.append(Measurement("rbm_ou", "weak", v.label, dt, v.tol, err, c, wall / t_end,
                                   sub, m, vals))
        log(f"  rbm_ou: {v.label} done")
    return out


def _deterministic_sup(cfg: StudyConfig, problem: str, scene: Scene, t_end: float, dt0: float,
                       log, error: Callable[[Simulator], float]) -> list[Measurement]:
    """Sup over the grid of error(sim) (m) for every variant and dt level of a sigma = 0
    problem with an exact solution."""
    out = []
    for v in variants(cfg, False):
        for dt in _levels(dt0, cfg.levels):
            worst = [0.0]
            wall, sub = _run(scene, v, dt, None, int(round(t_end / dt)),
                             lambda s: worst.__setitem__(0, max(worst[0], error(s))))
            out.append(Measurement(problem, "sup", v.label, dt, v.tol, worst[0], 0.0,
                                   wall / t_end, sub, 1))
    log(f"  {problem}: done")
    return out


def study_moving_wall(cfg: StudyConfig, log=print) -> list[Measurement]:
    x0, r, c0, vel, t_end, dt0 = 0.5, 0.25, -1.0, 0.5, 3.5, cfg.det_dt0
    scene = Scene.from_dict({
        "agents": {"positions": [[x0, 0.0]], "radius": r},
        "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": c0, "velocity": vel}]})
    return _deterministic_sup(cfg, "moving_wall", scene, t_end, dt0, log, lambda s: abs(
        s.positions[0, 0] - max(x0, c0 + vel * s.t + r)))


def circle_exact(t: np.ndarray, rho: float, speed: float, theta0: float) -> np.ndarray:
    """Centre of a disk sliding around a circle of contact radius rho (closed form, §5)."""
    t = np.asarray(t, dtype=float)
    t_r = rho / speed * math.log(math.tan(theta0 / 2))
    th = 2.0 * np.arctan(math.tan(theta0 / 2) * np.exp(-speed * np.minimum(t, t_r) / rho))
    on = np.stack([rho * np.cos(th), rho * np.sin(th)], axis=-1)
    off = np.stack([speed * (t - t_r), np.full_like(t, rho)], axis=-1)
    return np.where((t <= t_r)[..., None], on, off)


def study_circle(cfg: StudyConfig, log=print) -> list[Measurement]:
    big_r, r, speed, theta0, t_end, dt0 = 1.0, 0.25, 1.0, math.pi - 0.4, 3.0, cfg.det_dt0
    rho = big_r + r
    start = circle_exact(np.array(0.0), rho, speed, theta0)
    scene = Scene.from_dict({
        "agents": {"positions": [start.tolist()], "radius": r},
        "obstacles": [{"kind": "circle", "center": [0.0, 0.0], "radius": big_r}],
        "drift": {"kind": "uniform", "velocity": [speed, 0.0]}})
    return _deterministic_sup(cfg, "circle", scene, t_end, dt0, log, lambda s: float(
        np.hypot(*(s.positions[0] - circle_exact(np.array(s.t), rho, speed, theta0)))))


# -- problem (b) ------------------------------------------------------------------------------
def crowd_scene(walls: bool = True, sigma: float = 0.2, radius_law: dict | None = None,
                obstacle: bool = True, far_walls: bool = False) -> Scene:
    """120 agents (radii 0.18-0.22 m) in an 8 x 4.6 m room heading for (7.6, 2.3)."""
    pos = [[0.3 + 0.45 * c, 0.3 + 0.45 * k] for k in range(10) for c in range(12)]
    radii = [0.18 + 0.04 * ((7 * i) % 11) / 10 for i in range(len(pos))]
    spec = {"agents": {"positions": pos, "radius": radii,
                       "radius_law": radius_law or {"kind": "constant"}},
            "drift": {"kind": "goal", "goal": [7.6, 2.3], "speed": 1.0, "slow_radius": 0.5},
            "noise": {"sigma": sigma}}
    if walls:
        lo, hi = (-50.0, 50.0) if far_walls else (0.0, 8.0)
        lo_y, hi_y = (-50.0, 50.0) if far_walls else (0.0, 4.6)
        spec["walls"] = [{"kind": "halfplane", "normal": [1, 0], "offset": lo},
                         {"kind": "halfplane", "normal": [-1, 0], "offset": -hi},
                         {"kind": "halfplane", "normal": [0, 1], "offset": lo_y},
                         {"kind": "halfplane", "normal": [0, -1], "offset": -hi_y}]
    if obstacle:
        spec["obstacles"] = [{"kind": "circle", "center": [6.2, 2.3], "radius": 0.4}]
    return Scene.from_dict(spec)


def study_crowd(cfg: StudyConfig, log=print) -> list[Measurement]:
    scene = crowd_scene()
    n, t_end = scene.n_agents, cfg.crowd_t
    dts = _levels(cfg.crowd_dt0, cfg.levels)
    h_ref = dts[-1] / cfg.crowd_ref_factor
    n_f = int(round(t_end / h_ref))
    vs = variants(cfg, True)
    per = {(v.label, v.tol, dt): ([], [], []) for v in vs for dt in dts}
    for p in range(cfg.crowd_paths):
        rng = generator(cfg.seed + 100 + p)
        fine = math.sqrt(h_ref) * rng.standard_normal((n_f, n, 2))
        ref = Simulator(scene, dt=h_ref, seed=0)
        ref.step(n_f, dB=fine)
        q_ref = ref.positions
        for v in vs:
            for k, dt in enumerate(dts):
                factor = cfg.crowd_ref_factor * 2 ** (cfg.levels - 1 - k)
                dB = _coarse(fine, factor)
                holder = {}
                wall, sub = _run(scene, v, dt, dB, len(dB),
                                 lambda s: holder.__setitem__("q", s.positions))
                d = holder["q"] - q_ref
                e, w, s_ = per[(v.label, v.tol, dt)]
                e.append(float(np.sqrt(np.einsum("ij,ij->i", d, d)).mean()))
                w.append(wall / t_end)
                s_.append(sub)
        log(f"  crowd: path {p + 1}/{cfg.crowd_paths} done")
    out = []
    for v in vs:
        for dt in dts:
            e, w, s_ = per[(v.label, v.tol, dt)]
            vals = np.array(e)
            err, c = _summary(vals, student=True)
            out.append(Measurement("crowd", "strong", v.label, dt, v.tol, err, c,
                                   float(np.mean(w)), float(np.mean(s_)), len(vals), vals))
    return out


# -- features ---------------------------------------------------------------------------------
def free_crowd(walls: bool = False, sigma: float = 0.0, radius_law: dict | None = None) -> Scene:
    """120 agents (radii 0.18-0.22 m) 0.7 m apart in free flow (one uniform velocity), walls
    optional but 50 m away: nobody touches anybody, so a step costs bookkeeping only."""
    pos = [[0.7 * c, 0.7 * k] for k in range(10) for c in range(12)]
    radii = [0.18 + 0.04 * ((7 * i) % 11) / 10 for i in range(len(pos))]
    spec = {"agents": {"positions": pos, "radius": radii,
                       "radius_law": radius_law or {"kind": "constant"}},
            "drift": {"kind": "uniform", "velocity": [1.0, 0.2]}, "noise": {"sigma": sigma}}
    if walls:
        spec["walls"] = [{"kind": "halfplane", "normal": [1, 0], "offset": -50.0},
                         {"kind": "halfplane", "normal": [-1, 0], "offset": -50.0},
                         {"kind": "halfplane", "normal": [0, 1], "offset": -50.0},
                         {"kind": "segment", "a": [-50.0, 50.0], "b": [50.0, 50.0]}]
        spec["obstacles"] = [{"kind": "circle", "center": [-20.0, -20.0], "radius": 1.0}]
    return Scene.from_dict(spec)


def study_features(cfg: StudyConfig, log=print) -> list[dict]:
    """Median ms per step of a free-flowing crowd without walls, noise and radius law, against
    the same crowd with each feature switched on. Nobody touches anybody in any variant (walls
    50 m away, noise too weak to close 0.26 m gaps), so the differences are what each feature
    costs to model, and the bare scene shows what it pays for them: nothing."""
    sine = {"kind": "sine", "amplitude": 0.001, "period": 2.0}
    cases = [("none", free_crowd()),
             ("walls + obstacle (far)", free_crowd(walls=True)),
             ("noise (sigma = 0.01)", free_crowd(sigma=0.01)),
             ("radius law (sine, 1 mm)", free_crowd(radius_law=sine)),
             ("all three", free_crowd(walls=True, sigma=0.01, radius_law=sine))]
    sims = [Simulator(s, dt=0.01, seed=cfg.seed) for _, s in cases]
    times: list[list[float]] = [[] for _ in cases]
    for sim in sims:
        sim.step(3)  # warm-up
    for _ in range(cfg.feature_steps):   # interleaved, so load from elsewhere hits all alike
        for sim, tl in zip(sims, times):
            t0 = time.perf_counter()
            sim.step()
            tl.append(time.perf_counter() - t0)
    base = float(np.median(times[0]))
    rows = []
    for (name, scene), tl, sim in zip(cases, times, sims):
        med = float(np.median(tl))
        rows.append({"scene": name, "agents": scene.n_agents, "ms_per_step": 1e3 * med,
                     "ratio_to_none": med / base, "contacts": sim.contacts})
    log("  features: done")
    return rows


# -- the study --------------------------------------------------------------------------------
STUDIES = {"rbm_wall": study_rbm_wall, "rbm_ou": study_rbm_ou,
           "moving_wall": study_moving_wall, "circle": study_circle, "crowd": study_crowd}


def group_slopes(ms: list[Measurement], seed: int = 0) -> list[Slope]:
    groups: dict[tuple, list[Measurement]] = {}
    for m in ms:
        groups.setdefault((m.problem, m.metric, m.scheme, m.tol), []).append(m)
    return [fit_slope(sorted(g, key=lambda m: -m.dt), seed) for g in groups.values()]


def format_table(ms: list[Measurement]) -> str:
    head = (f"{'problem':<12}{'metric':<7}{'scheme':<17}{'tol':<17}{'dt':>10}{'error':>11}"
            f"{'+-95%':>10}{'wall s/s':>10}{'sub':>6}")
    lines = [head, "-" * len(head)]
    for m in ms:
        lines.append(f"{m.problem:<12}{m.metric:<7}{m.scheme:<17}{m.tol:<17}{m.dt:>10.3g}"
                     f"{m.error:>11.3e}{m.ci:>10.2e}{m.wall_per_s:>10.3g}{m.substeps:>6.2f}")
    return "\n".join(lines)


def format_slopes(slopes: list[Slope]) -> str:
    head = f"{'problem':<12}{'metric':<7}{'scheme':<17}{'tol':<17}{'slope':>7}  {'95% interval':<17}note"
    lines = [head, "-" * len(head)]
    for s in slopes:
        shown = f"{s.slope:>7.2f}  [{s.lo:.2f}, {s.hi:.2f}]" if np.isfinite(s.slope) else (
            f"{'-':>7}  {'':<15}")
        lines.append(f"{s.problem:<12}{s.metric:<7}{s.scheme:<17}{s.tol:<17}{shown:<26}{s.note}")
    return "\n".join(lines)


def format_features(rows: list[dict]) -> str:
    lines = [f"{'free-flow crowd, 120 agents':<30}{'ms/step':>9}{'x none':>8}{'contacts':>10}",
             "-" * 57]
    for r in rows:
        lines.append(f"{r['scene']:<30}{r['ms_per_step']:>9.3f}{r['ratio_to_none']:>8.2f}"
                     f"{r['contacts']:>10}")
    return "\n".join(lines)


def _mrow(m: Measurement) -> dict:
    return {"problem": m.problem, "metric": m.metric, "scheme": m.scheme, "tol": m.tol,
            "dt": m.dt, "error": m.error, "ci95": m.ci, "wall_s_per_sim_s": m.wall_per_s,
            "substeps_per_step": m.substeps, "samples": m.samples}


def plot(ms: list[Measurement], out: Path) -> list[Path]:
    """error_vs_dt.png and pareto.png (error against wall time per simulated second)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    default_tol = Variant("", SCHEMES["projected_euler"]).tol
    panels: dict[tuple[str, str], list[Measurement]] = {}
    for m in ms:
        panels.setdefault((m.problem, m.metric), []).append(m)
    keys = list(panels)
    cols = min(3, math.ceil(math.sqrt(len(keys))))
    rows = max(1, math.ceil(len(keys) / cols))
    written = []
    for name, xkey, xlabel in (("error_vs_dt.png", "dt", "dt (s)"),
                               ("pareto.png", "wall_per_s", "wall time per simulated second (s)")):
        fig, axes = plt.subplots(rows, cols, figsize=(4.0 * cols, 3.1 * rows), squeeze=False)
        for ax, key in zip(axes.flat, keys):
            lines: dict[tuple[str, str], list[Measurement]] = {}
            for m in panels[key]:
                lines.setdefault((m.scheme, m.tol), []).append(m)
            drawn = 0
            for (scheme, tol), g in lines.items():
                g = [m for m in sorted(g, key=lambda m: -m.dt) if m.error > 1e-13]
                if not g:
                    continue
                drawn += 1
                x = np.array([getattr(m, xkey) for m in g])
                y = np.array([m.error for m in g])
                ci = np.array([m.ci for m in g])
                label = scheme if tol == default_tol else f"{scheme} {tol}"
                ax.errorbar(x, y, yerr=[np.minimum(ci, 0.9 * y), ci], marker="o", ms=3, lw=1,
                            capsize=2, label=label)
            if xkey == "dt":
                dts = np.array(sorted({m.dt for m in panels[key]}))
                ref = [m.error for m in panels[key] if m.error > 1e-13]
                if ref and len(dts) > 1:
                    y0 = float(np.median(ref))
                    for p, style in ((0.5, ":"), (1.0, "--")):
                        ax.plot(dts, y0 * (dts / dts[len(dts) // 2]) ** p, "k" + style, lw=0.7,
                                label=f"slope {p:g}")
            ax.set_title(f"{key[0]} ({key[1]})", fontsize=9)
            if not drawn:
                ax.text(0.5, 0.5, "exact to rounding\n(every error < 1e-13 m)",
                        ha="center", va="center", transform=ax.transAxes, fontsize=8)
                ax.set_xticks([])
                ax.set_yticks([])
                continue
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())
            ax.set_xlabel(xlabel, fontsize=8)
            ax.set_ylabel("error (m)", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.legend(fontsize=6)
        for ax in list(axes.flat)[len(keys):]:
            ax.axis("off")
        fig.tight_layout()
        path = out / name
        fig.savefig(path, dpi=72)
        plt.close(fig)
        written.append(path)
    return written


def run_study(cfg: StudyConfig, out: Path, problems: tuple[str, ...] = PROBLEMS,
              log=print) -> tuple[list[Measurement], list[Slope], list[dict]]:
    """Run the chosen problems, print the tables, write CSVs and plots into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    ms: list[Measurement] = []
    start = time.perf_counter()
    for name in problems:
        if name in STUDIES:
            t0 = time.perf_counter()
            ms.extend(STUDIES[name](cfg, log))
            log(f"  {name}: {time.perf_counter() - t0:.1f} s")
    features = study_features(cfg, log) if "features" in problems else []
    slopes = group_slopes(ms, cfg.seed)
    if ms:
        log(format_table(ms))
        log("")
        log(format_slopes(slopes))
        write_csv(out / "accuracy.csv", [_mrow(m) for m in ms])
        write_csv(out / "slopes.csv", [dataclasses.asdict(s) for s in slopes])
        for p in plot(ms, out):
            log(f"wrote {p}")
    if features:
        log("")
        log(format_features(features))
        write_csv(out / "features.csv", features)
    log(f"study took {time.perf_counter() - start:.1f} s; CSV and PNG in {out}")
    return ms, slopes, features
