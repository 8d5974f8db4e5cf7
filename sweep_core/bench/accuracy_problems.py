"""The problems of the accuracy study (see :mod:`sweep_core.bench.accuracy`): reflected Brownian
motion and Ornstein-Uhlenbeck at a wall, a moving wall, sliding round a circle (exact answers),
a crowd against a fine-dt reference, and the per-feature cost of a free-flowing crowd."""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy import stats

from sweep_core.bench.accuracy import (
    Z95,
    Measurement,
    StudyConfig,
    bridge_min,
    coarse,
    levels,
    run_variant,
    summary,
    variants,
    wall_scene,
)
from sweep_core.model.scene import Scene
from sweep_core.numerics.noise import generator
from sweep_core.numerics.simulator import Simulator


# -- problems (a) -----------------------------------------------------------------------------
def study_rbm_wall(cfg: StudyConfig, log=print) -> list[Measurement]:
    """Reflected BM from the wall: strong and weak errors against the exact Skorokhod map."""
    m, r, t_end, dt0 = cfg.wall_paths, 0.1, 1.0, 0.1
    dts = levels(dt0, cfg.levels)
    n_f = int(round(t_end / dts[-1]))
    rng = generator(cfg.seed)
    fine = math.sqrt(dts[-1]) * rng.standard_normal((n_f, m, 2))
    # exact reference on the finest grid: Skorokhod map of the continuous path (bridge minima)
    path = np.vstack([np.zeros((1, m)), np.cumsum(fine[:, :, 0], axis=0)])  # x0 = 0
    mins = bridge_min(path[:-1], path[1:], dts[-1], 1.0 - rng.random((n_f, m)))
    local = np.vstack([np.zeros((1, m)), np.maximum.accumulate(np.maximum(-mins, 0.0), axis=0)])
    ref = path + local                                   # (n_f + 1, m)
    exact_mean = math.sqrt(2.0 / math.pi)
    mean, ci = float(ref[-1].mean()), Z95 * float(ref[-1].std(ddof=1)) / math.sqrt(m)
    log(f"  rbm_wall: reference E X_1 = {mean:.4f} +- {ci:.4f}, exact sqrt(2/pi) = {exact_mean:.4f}")
    scene = wall_scene(m, r, 0.0, 1.0)
    out = []
    for v in variants(cfg, False):
        for k, dt in enumerate(dts):
            factor = 2 ** (cfg.levels - 1 - k)
            dB = coarse(fine, factor)
            steps = len(dB)
            worst, last = np.zeros(m), np.zeros(m)

            def observe(sim: Simulator, worst=worst, last=last, factor=factor) -> None:
                last[:] = sim.positions[:, 0] - r
                np.maximum(worst, np.abs(last - ref[sim.n_steps * factor]), out=worst)

            wall, sub = run_variant(scene, v, dt, dB, steps, observe)
            weak = last - ref[-1]
            for metric, vals in (("strong", np.abs(weak)), ("sup", worst.copy()),
                                 ("weak", weak)):
                err, c = summary(vals)
                out.append(Measurement("rbm_wall", metric, v.label, dt, v.tol, err, c,
                                       wall / t_end, sub, m, vals))
        log(f"  rbm_wall: {v.label} done")
    return out


def study_rbm_ou(cfg: StudyConfig, log=print) -> list[Measurement]:
    """Reflected OU at a wall (drift -kappa * gap): weak error against the closed form."""
    m, r, t_end, dt0, kappa, x0 = cfg.wall_paths, 0.1, 1.0, 0.1, 2.0, 0.3
    dts = levels(dt0, cfg.levels)
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
            mn = bridge_min(y, b, h_f, 1.0 - rng.random(m))
            y = b + np.maximum(-mn, 0.0)
    mu = x0 * math.exp(-kappa * t_end)
    s = math.sqrt((1.0 - math.exp(-2.0 * kappa * t_end)) / (2.0 * kappa))
    exact = s * math.sqrt(2 / math.pi) * math.exp(-mu * mu / (2 * s * s)) + mu * (
        1.0 - 2.0 * stats.norm.cdf(-mu / s))
    mean, ci = float(y.mean()), Z95 * float(y.std(ddof=1)) / math.sqrt(m)
    log(f"  rbm_ou: reference E X_1 = {mean:.4f} +- {ci:.4f}, closed form {exact:.4f}")
    scene = wall_scene(m, r, x0, 1.0, {"kind": "linear", "matrix": [[-kappa, 0.0], [0.0, 0.0]],
                                        "offset": [kappa * r, 0.0]})
    out = []
    for v in variants(cfg, False):
        for k, dt in enumerate(dts):
            dB = coarse(fine, 2 ** (cfg.levels - 1 - k))
            holder = {}
            wall, sub = run_variant(scene, v, dt, dB, len(dB),
                             lambda s_: holder.__setitem__("x", s_.positions[:, 0] - r))
            vals = holder["x"] - y
            err, c = summary(vals)
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
        for dt in levels(dt0, cfg.levels):
            worst = [0.0]
            wall, sub = run_variant(scene, v, dt, None, int(round(t_end / dt)),
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


def crowd_path(cfg: StudyConfig, p: int) -> dict[tuple, tuple[float, float, float]]:
    """Path p of the crowd study (its own seed, cfg.seed + 100 + p): for each variant and dt,
    the mean error over agents against the fine reference, the wall time per simulated second
    and the sub-steps. A pure function of (cfg, p), so paths can run anywhere (a Dask
    worker) and give the same errors."""
    scene = crowd_scene()
    n, t_end = scene.n_agents, cfg.crowd_t
    dts = levels(cfg.crowd_dt0, cfg.levels)
    h_ref = dts[-1] / cfg.crowd_ref_factor
    n_f = int(round(t_end / h_ref))
    rng = generator(cfg.seed + 100 + p)
    fine = math.sqrt(h_ref) * rng.standard_normal((n_f, n, 2))
    ref = Simulator(scene, dt=h_ref, seed=0)
    ref.step(n_f, dB=fine)
    q_ref = ref.positions
    out = {}
    for v in variants(cfg, True):
        for k, dt in enumerate(dts):
            factor = cfg.crowd_ref_factor * 2 ** (cfg.levels - 1 - k)
            dB = coarse(fine, factor)
            holder = {}
            wall, sub = run_variant(scene, v, dt, dB, len(dB),
                                    lambda s: holder.__setitem__("q", s.positions))
            d = holder["q"] - q_ref
            out[(v.label, v.tol, dt)] = (float(np.sqrt(np.einsum("ij,ij->i", d, d)).mean()),
                                         wall / t_end, float(sub))
    return out


def study_crowd(cfg: StudyConfig, log=print, client: Any = None) -> list[Measurement]:
    """The crowd's strong error against dt and variant over ``cfg.crowd_paths`` paths; with a
    ``distributed.Client`` the paths run on its workers (same errors; the wall times are those
    of the workers, which may share cores)."""
    dts = levels(cfg.crowd_dt0, cfg.levels)
    vs = variants(cfg, True)
    per = {(v.label, v.tol, dt): ([], [], []) for v in vs for dt in dts}
    if client is None:
        paths = []
        for p in range(cfg.crowd_paths):
            paths.append(crowd_path(cfg, p))
            log(f"  crowd: path {p + 1}/{cfg.crowd_paths} done")
    else:
        futures = client.map(crowd_path, [cfg] * cfg.crowd_paths, range(cfg.crowd_paths),
                             pure=False)
        paths = client.gather(futures)
        log(f"  crowd: {cfg.crowd_paths} paths done on the cluster")
    for result in paths:  # in path order, whatever finished first
        for key, (e, w, sub) in result.items():
            per[key][0].append(e)
            per[key][1].append(w)
            per[key][2].append(sub)
    out = []
    for v in vs:
        for dt in dts:
            e, w, s_ = per[(v.label, v.tol, dt)]
            vals = np.array(e)
            err, c = summary(vals, student=True)
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
