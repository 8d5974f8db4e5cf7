"""Two runs side by side (``sweep compare``).

Compare aligns two recordings on their common times (log time, i.e. simulation time for
``sweep run``) and reports the sup-distance max_i |q_i^A(t) - q_i^B(t)| over time and, per
agent, over time. It first says what the two runs share (:func:`sameness`): the scene (their
normalised specs, the name and description aside, and the node's commands and parameters),
the seed, and the Brownian path (seed, the resolution it was drawn at, the agent count). The
distance is called the pathwise error only when they share the scene and the path (the
deterministic case: the scene alone): two approximations, by two dt or two schemes, of one
solution. Otherwise it is a distance between two runs, and the statistics of each
(``sweep analyze``) are what can be compared.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.drawing import pyplot, save_figure
from sweep_core.analysis.frames import Frame, FrameReader, progress_bar
from sweep_core.analysis.report import OTHER, jsonable, output_paths, write_table
from sweep_core.analysis.roster import Roster, agent_ids, grow, id_bound
from sweep_core.analysis.run import NS, RunMeta, load_run
from sweep_core.errors import RecordingError, SweepError
from sweep_core.io.outputs import check_output


@dataclass
class Comparison:
    a: str
    b: str
    common_frames: int
    t_first_s: float
    t_last_s: float
    sup_m: float
    sup_t_s: float
    sup_agent: int
    final_max_m: float
    final_mean_m: float
    #: by agent (id, or row without flows): the sup over the common times (NaN: never in
    #: both runs at one time) and when; ``present_in`` says where it was seen: "A and B",
    #: "A", "B" (in one run only) or "A and B, never at one time"
    per_agent_sup_m: list[float]
    per_agent_t_s: list[float]
    shared_path: str
    same_scene: str
    same_seed: str
    pathwise: bool
    distance: str
    truncated: list[str]
    notes: list[str]
    table: np.ndarray  # t, max over agents, mean over agents
    present_in: list[str] = field(default_factory=list)
    #: skipped chunks and messages of either file, one line each
    problems: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        d = {k: v for k, v in self.__dict__.items() if k != "table"}
        d["agents_compared"] = self.agents_compared
        d["agents_in_one_run"] = {"A": self.present_in.count("A"),
                                  "B": self.present_in.count("B")}
        return jsonable(d)

    @property
    def agents_compared(self) -> int:
        """The agents found in both runs at some common time (the per-agent statistics)."""
        return int(np.count_nonzero(np.isfinite(self.per_agent_sup_m)))


#: keys of a scene that do not change its dynamics
LABELS = ("name", "description")


def spec_differences(a: Any, b: Any, where: str = "", depth: int = 2) -> list[str]:
    """The dotted keys where two specs differ (down to ``depth`` levels; a list compared
    whole)."""
    if isinstance(a, dict) and isinstance(b, dict) and depth > 0:
        out = []
        for key in sorted(set(a) | set(b), key=str):
            if not where and key in LABELS:
                continue
            name = f"{where}.{key}" if where else str(key)
            if key not in a or key not in b:
                out.append(name)
            else:
                out += spec_differences(a[key], b[key], name, depth - 1)
        return out
    return [] if a == b else [where or "scene"]


@dataclass
class Sameness:
    """What two runs share: ``scene`` (the differing keys, [] when the same; None when a
    recording carries no scene), ``seed`` and ``path`` (one line each), ``noisy`` (either run
    has noise), ``shared_path`` (the same Brownian path: seed, resolution, agents) and
    ``pathwise`` (the distance is the pathwise error: same scene and, with noise, path)."""

    scene: list[str] | None
    seed: str
    path: str
    noisy: bool
    shared_path: bool
    pathwise: bool

    def scene_line(self) -> str:
        if self.scene is None:
            return "unknown (a recording carries no scene that loads)"
        if not self.scene:
            return "same (normalised specs equal, name and description aside)"
        shown = ", ".join(self.scene[:6]) + (f", ... ({len(self.scene)} keys)"
                                             if len(self.scene) > 6 else "")
        return f"DIFFERENT: {shown}"

    def distance_line(self) -> str:
        if self.pathwise:
            return ("the pathwise error: one scene" + (", one Brownian path" if self.noisy
                                                       else ", no noise"))
        why = []
        if self.scene is None:
            why.append("the scenes are unknown")
        elif self.scene:
            why.append("the scenes differ")
        if self.noisy and not self.shared_path:
            why.append("the noise paths differ")
        return ("NOT a pathwise error (" + ", ".join(why) + "): a distance between two runs; "
                "compare their statistics instead (sweep analyze on each)")


def _noise(m: RunMeta) -> bool:
    """Whether a run has noise (the scene's sigma, or the node's noise_sigma parameter)."""
    sigma = m.parameters.get("noise_sigma", -1.0)
    live = any(c.name == "noise_sigma" for c in m.parameter_changes)
    return bool(m.scene is None or np.any(m.scene.sigma) or live
                or (isinstance(sigma, (int, float)) and sigma > 0))


def _settings(m: RunMeta) -> dict:
    """What besides the scene sets a run's dynamics (what replay applies): the node's
    noise_sigma and its changes, its commands and maps, with their steps (dt and seed are
    compared as the path's)."""
    return {"noise_sigma": m.parameters.get("noise_sigma", -1.0),
            "commands": [(c.segment, c.step, c.spec) for c in m.commands],
            "noise_sigma_changes": [(c.segment, c.step, c.value) for c in m.parameter_changes
                                    if c.name == "noise_sigma"],
            "maps": [(c.segment, c.step, c.spec) for c in m.maps]}


def sameness(ma: RunMeta, mb: RunMeta) -> Sameness:
    """What two recorded runs share (module docstring)."""
    scene = None
    if ma.scene is not None and mb.scene is not None:
        scene = spec_differences(ma.scene.spec, mb.scene.spec)
        scene += spec_differences(_settings(ma), _settings(mb), "", 1)
    if ma.seed is None or mb.seed is None:
        seed = "unknown (missing from the metadata)"
    else:
        seed = f"same: {ma.seed}" if ma.seed == mb.seed else f"DIFFERENT: {ma.seed} / {mb.seed}"
    noisy = _noise(ma) or _noise(mb)
    n = [m.scene.n_agents if m.scene is not None else None for m in (ma, mb)]
    if ma.seed is None or mb.seed is None or ma.dt is None or mb.dt is None:
        shared, path = False, "unknown (seed or dt missing from the metadata)"
    else:
        res_a, res_b = ma.path_dt or ma.dt, mb.path_dt or mb.dt
        shared = (ma.seed == mb.seed and math.isclose(res_a, res_b, rel_tol=1e-9)
                  and n[0] == n[1] and n[0] is not None)
        if shared:
            path = f"shared: seed {ma.seed}, drawn at {res_a:g} s, {n[0]} agents in both"
        else:
            path = (f"NOT shared: seeds {ma.seed} / {mb.seed}, drawn at {res_a:g} / {res_b:g} s, "
                    f"{n[0]} / {n[1]} agents (one path needs the same seed, resolution and "
                    "agents; fix for a pathwise error: sweep run --path-dt FINE on the coarse "
                    "run with the fine run's dt and seed)")
        if not noisy:
            path = "no noise (sigma = 0 in both): deterministic runs"
    pathwise = scene == [] and (shared or not noisy)
    return Sameness(scene, seed, path, noisy, shared, pathwise)


def _ids(fr: Frame, meta: RunMeta, t: float, top: int) -> np.ndarray:
    """A frame's agent ids (from /agents), or a RecordingError saying they are missing or
    are no ids below ``top`` (:func:`agent_ids`)."""
    return agent_ids(fr.agents, len(fr.positions), t, meta.path, top)


def compare(a: str | Path, b: str | Path, progress: bool = False) -> Comparison:
    """Aligns two recordings on their common log times and measures |q^A - q^B|."""
    ma, mb = load_run(a), load_run(b)
    notes = []
    same = sameness(ma, mb)
    for m in (ma, mb):
        if not m.frames:
            raise RecordingError(f"{m.path}: holds no recorded state (no /poses message), so "
                                 "there is nothing to compare (fix: compare recordings of at "
                                 "least one recorded step)")
    # with flows the agents two frames share are matched by id
    by_id = any(m.scene is not None and m.scene.flows is not None for m in (ma, mb))
    # the ids a run of either recorded scene can give
    most = max((id_bound(m.scene) for m in (ma, mb) if m.scene is not None), default=0)
    if by_id:
        moving = any(m.scene is not None and m.scene.flows is not None
                     and m.scene.flows.changes_population for m in (ma, mb))
        notes.append("agents matched by their /agents ids"
                     + (" (flows: agents enter and leave)" if moving else ""))
    ra, rb = FrameReader(ma, agents=by_id), FrameReader(mb, agents=by_id)
    ia, ib = iter(ra), iter(rb)
    fa, fb = next(ia, None), next(ib, None)
    rows: list[tuple[float, float, float]] = []
    n = None
    sup_agent = sup_t = None
    per = arg = None
    seen = np.zeros((2, 0), dtype=bool)  # by agent: seen in A, in B (at the common times)
    bar = progress_bar(min(ma.frames, mb.frames) or None, "frame", progress)
    with bar:
        while fa is not None and fb is not None:
            if fa.log_ns < fb.log_ns:
                fa = next(ia, None)
                continue
            if fb.log_ns < fa.log_ns:
                fb = next(ib, None)
                continue
            if n is None:
                n = len(fa.positions)
                per, arg = np.full(n, np.nan), np.full(n, np.nan)
                seen = np.full((2, n), not by_id)
            t = fa.log_ns / NS
            qa, qb, who = fa.positions, fb.positions, None
            if by_id:
                ids_a, ids_b = _ids(fa, ma, t, most), _ids(fb, mb, t, most)
                who, qa, qb = Roster.common(ids_a, qa, ids_b, qb)
                top = max(int(ids_a.max(initial=-1)), int(ids_b.max(initial=-1))) + 1
                if top > len(per):
                    per, arg = grow(per, top), grow(arg, top)
                    seen = np.hstack([seen, np.zeros((2, top - seen.shape[1]), dtype=bool)])
                seen[0, ids_a] = seen[1, ids_b] = True
                n = len(per)
            elif len(qa) != n or len(qb) != n:
                raise RecordingError(f"{ma.path} and {mb.path} have different agent counts "
                                     f"({len(fa.positions)} and {len(fb.positions)})")
            d = np.hypot(*(qa - qb).T)
            who = np.arange(len(d)) if who is None else who
            worse = ~(d <= per[who])  # NaN: not yet compared
            per[who[worse]] = d[worse]
            arg[who[worse]] = t
            # no agent in both runs at t: no distance (NaN, empty in the CSV), never 0 m
            rows.append((t, float(d.max()) if len(d) else math.nan,
                         float(d.mean()) if len(d) else math.nan))
            bar.update()
            fa, fb = next(ia, None), next(ib, None)
    ia.close()  # type: ignore[attr-defined]  # generators: closing one fills its problems
    ib.close()  # type: ignore[attr-defined]
    if not rows:
        raise SweepError(f"{ma.path} and {mb.path} have no recorded time in common "
                         "(fix: compare runs of the same scene whose recorded times overlap, "
                         "e.g. dt = 0.01 and dt = 0.001)")
    table = np.array(rows)
    held = np.isfinite(table[:, 1])  # the common times with an agent in both runs
    k = int(np.nanargmax(table[:, 1])) if held.any() else 0
    sup_t = float(table[k, 0]) if held.any() else math.nan
    compared = np.isfinite(per)
    sup_agent = int(np.nanargmax(per)) if np.any(compared) else -1
    present = [("A and B" if ok else "A and B, never at one time") if a and b else
               ("A" if a else "B" if b else "neither") for ok, a, b in zip(compared, *seen)]
    truncated = [m.path for m in (ma, mb) if m.truncated]
    return Comparison(
        a=ma.path, b=mb.path, common_frames=len(rows), t_first_s=float(table[0, 0]),
        t_last_s=float(table[-1, 0]), sup_m=float(table[k, 1]), sup_t_s=sup_t,
        sup_agent=sup_agent, final_max_m=float(table[-1, 1]),
        final_mean_m=float(table[-1, 2]), per_agent_sup_m=per.tolist(),
        per_agent_t_s=arg.tolist(), shared_path=same.path, same_scene=same.scene_line(),
        same_seed=same.seed, pathwise=same.pathwise, distance=same.distance_line(),
        truncated=truncated,
        notes=notes, table=table, problems=ra.problems + rb.problems, present_in=present)


def format_comparison(c: Comparison) -> str:
    per = np.asarray(c.per_agent_sup_m)
    lines = [
        f"A                  {c.a}",
        f"B                  {c.b}",
        f"scene              {c.same_scene}",
        f"seed               {c.same_seed}",
        f"noise path         {c.shared_path}",
        f"distance           {c.distance}",
        f"common times       {c.common_frames} (t = {c.t_first_s:.6g} .. {c.t_last_s:.6g} s)",
        f"sup distance       {c.sup_m:.6g} m (t = {c.sup_t_s:.6g} s)" if math.isfinite(c.sup_m)
        else "sup distance       none: no agent is in both runs at a common time",
        f"final distance     max {c.final_max_m:.6g} m, mean {c.final_mean_m:.6g} m"
        if math.isfinite(c.final_max_m) else
        f"final distance     none: no agent is in both runs at t = {c.t_last_s:.6g} s",
    ]
    only = {k: c.present_in.count(k) for k in ("A", "B")}
    lines.append(f"agents compared    {c.agents_compared} (in both runs at a common time)"
                 + (f"; in one run only: {only['A']} in A, {only['B']} in B, no distance"
                    if only["A"] or only["B"] else ""))
    if c.agents_compared:
        lines.append(f"per agent sup      median {np.nanmedian(per):.6g} m, max "
                     f"{np.nanmax(per):.6g} m (agent {c.sup_agent} at t = "
                     f"{c.per_agent_t_s[c.sup_agent]:.6g} s; over the agents compared)")
    lines += [f"truncated          {p} (read up to its last complete chunk)" for p in c.truncated]
    lines += [f"note               {n}" for n in c.notes]
    return "\n".join(lines)


def write_comparison(c: Comparison, plots: bool = True) -> dict[str, str]:
    """``A_vs_B.compare.csv`` (t, max and mean distance over agents), ``A_vs_B.agents.csv``
    (per agent sup, empty for an agent never in both runs at one time, and ``present_in``),
    ``A_vs_B.compare.png``, next to A."""
    pa, pb = Path(c.a), Path(c.b)
    base = pa.with_name(f"{pa.stem}_vs_{pb.stem}.mcap")
    out = output_paths(base, ".compare")
    agents_csv = output_paths(base, ".agents")["csv"]
    inputs = [c.a, c.b]
    for p in (out["csv"], agents_csv) + ((out["png"],) if plots else ()):
        check_output(p, inputs, other=OTHER)  # all checked before any is written
    write_table(out["csv"], ("t_s", "max_distance_m", "mean_distance_m"), c.table, inputs)
    per = [[k, d, t, where] for k, (d, t, where) in
           enumerate(zip(c.per_agent_sup_m, c.per_agent_t_s, c.present_in))]
    write_table(agents_csv, ("agent", "sup_distance_m", "t_of_sup_s", "present_in"), per, inputs)
    files = {"csv": str(out["csv"]), "agents_csv": str(agents_csv)}
    if plots:
        plt = pyplot()
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 3.6), dpi=72)
        ax1.plot(c.table[:, 0], c.table[:, 1], lw=1, label="max over agents")
        ax1.plot(c.table[:, 0], c.table[:, 2], lw=1, label="mean over agents")
        ax1.set_xlabel("t (s)")
        ax1.set_ylabel("|q_A - q_B| (m)")
        ax1.legend(fontsize=8)
        ax1.set_title(f"{pa.name} vs {pb.name}")
        ax2.bar(np.arange(len(c.per_agent_sup_m)), c.per_agent_sup_m, width=1.0)
        ax2.set_xlabel("agent")
        ax2.set_ylabel("sup over time (m)")
        ax2.set_title("per agent")
        fig.tight_layout()
        save_figure(fig, out["png"], inputs)
        plt.close(fig)
        files["png"] = str(out["png"])
    return files
