"""The pictures of the scene gallery and of the README, each made from a run of its scene.

For every bundled scene (``sweep scenes``) this runs ``sweep run NAME`` (10 s simulated, dt
0.01, every step recorded, as a user would), times it, and draws ``docs/gallery/NAME.png``
from the recording: walls and obstacles (where they are at the snapshot), each agent's path
over the last seconds before the snapshot, and the disks at the snapshot with their radii,
coloured by group, and writes the page ``docs/gallery.md``. The README's picture
(``docs/crowd_at_door.png``) is the bundled ``room_door`` drawn the same way. The wall time of
each run is printed, not stored (it depends on the machine and its load):

    python docs/gallery.py
    python docs/gallery.py --only bottleneck     # one picture
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection, PatchCollection  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402

from sweep_core.analysis.frames import FrameReader  # noqa: E402
from sweep_core.analysis.robots import read_robot_topics  # noqa: E402
from sweep_core.analysis.run import load_run  # noqa: E402
from sweep_core.model.gallery import bundled_scenes  # noqa: E402
from sweep_core.model.yaml_files import load_yaml  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "docs" / "gallery"
#: the simulated time of every gallery run (s), as ``sweep scenes`` states
T_END = 10.0
#: snapshot time (s) per scene, and how long a trail each agent draws before it (s)
SNAPSHOT = {"room_door": 6.0, "corridor_groups": 8.0, "bottleneck": 6.0,
            "four_exit_hall": 3.5, "crossing_flows": 8.0, "moving_obstacle": 8.0,
            "map_two_rooms": 5.0}
TRAIL = 3.0
COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown")


def run_scene(name: str, work: Path) -> tuple[Path, float]:
    """``sweep run NAME`` in work: the recording and the wall time of the whole command (s)."""
    out = work / f"{name.replace('/', '_')}.mcap"
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "sweep_core.cli", "run", name, "--t-end",
                           str(T_END), "--out", str(out), "--quiet"], cwd=work,
                          capture_output=True, text=True, timeout=3600)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"sweep run {name} failed ({done.returncode}):\n{done.stderr}")
    status = json.loads(out.with_suffix(".summary.json").read_text())["status"]
    if status != "completed":
        raise SystemExit(f"sweep run {name}: {status}")
    return out, wall


def draw(recording: Path, png: Path, snapshot: float, title: str) -> None:
    """The picture of one run: geometry, trails over TRAIL s before ``snapshot``, disks then."""
    meta = load_run(recording)
    scene = meta.scene
    assert scene is not None
    times, frames, last = [], [], None
    for fr in FrameReader(meta, agents=True):
        t = fr.stamp_ns * 1e-9
        if snapshot - TRAIL - 1e-9 <= t <= snapshot + 1e-9:
            # agents by id (a scene with sinks or sources changes who is present)
            ids = (fr.agents["id"].astype(np.int64) if fr.agents is not None
                   else np.arange(len(fr.positions)))
            times.append(t)
            frames.append((ids, fr.positions))
            last = fr
    if not frames or last is None:
        raise SystemExit(f"{recording}: no frame before t = {snapshot} s")
    width = max(scene.n_agents, max(int(ids.max(initial=-1)) + 1 for ids, _ in frames))
    path = np.full((len(frames), width, 2), np.nan)  # (T, ids, 2), NaN where absent
    for k, (ids, q) in enumerate(frames):
        path[k, ids] = q
    t_snap = times[-1]
    present, _ = frames[-1]
    colour = np.full(width, COLOURS[0], dtype=object)
    groups: list[tuple[str, str]] = []
    members = getattr(scene.drift, "members", None)
    if members is not None:
        for k, (idx, gname) in enumerate(zip(members, scene.drift.names)):
            colour[np.asarray(idx)] = COLOURS[k % len(COLOURS)]
            groups.append((gname, COLOURS[k % len(COLOURS)]))

    geo = scene.geometry.at(t_snap)
    lo = np.minimum(np.nanmin(path.reshape(-1, 2), axis=0), _geometry_box(geo)[0]) - 0.5
    hi = np.maximum(np.nanmax(path.reshape(-1, 2), axis=0), _geometry_box(geo)[1]) + 0.5
    height = float(np.clip(7.0 * (hi[1] - lo[1]) / (hi[0] - lo[0]) + 1.2, 2.8, 7.5))
    fig, ax = plt.subplots(figsize=(8, height), dpi=110)
    if len(geo.segment_a):
        ax.add_collection(LineCollection(np.stack([geo.segment_a, geo.segment_b], axis=1),
                                         colors="black", linewidths=2))
    for c, r in zip(geo.circle_center, geo.circle_radius):
        ax.add_patch(Circle(c, r, color="0.45"))
    for i in range(width):
        ax.plot(path[:, i, 0], path[:, i, 1], color=colour[i], lw=0.6, alpha=0.5)
    radii = (last.agents["radius"].astype(np.float64) if last.agents is not None
             else scene.radii(t_snap))
    disks = [Circle(p, r) for p, r in zip(path[-1, present], radii)]
    ax.add_collection(PatchCollection(disks, facecolors=list(colour[present]),
                                      edgecolors="black", linewidths=0.3, alpha=0.9))
    _draw_robots(ax, meta, snapshot)
    for gname, c in groups:
        ax.plot([], [], "o", color=c, label=gname)
    if groups or scene.robots:
        ax.legend(loc="upper right", fontsize=8, framealpha=0.9)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{title}: t = {t_snap:.1f} s, paths over the last {TRAIL:g} s", fontsize=10)
    fig.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png)
    plt.close(fig)


def _draw_robots(ax, meta, snapshot: float) -> None:
    """Each robot of the scene: its path up to the snapshot and its disk then, with a heading
    tick (from the recorded /NAME/odom)."""
    robots = meta.scene.robots
    if not robots:
        return
    odom, _ = read_robot_topics(meta, [r.name for r in robots], [])
    for robot, track in zip(robots, odom):
        if not track:
            continue
        keys = sorted(track)
        t0 = keys[0]
        poses = np.array([track[k][:3] for k in keys if (k - t0) * 1e-9 <= snapshot + 1e-9])
        ax.plot(poses[:, 0], poses[:, 1], color="crimson", lw=1.2)
        x, y, yaw = poses[-1]
        ax.add_patch(Circle((x, y), robot.radius, facecolor="crimson", edgecolor="black",
                            lw=0.8, zorder=5, label=robot.name))
        ax.plot([x, x + robot.radius * np.cos(yaw)], [y, y + robot.radius * np.sin(yaw)],
                color="white", lw=1.5, zorder=6)


def _geometry_box(geo) -> tuple[np.ndarray, np.ndarray]:
    pts = [geo.segment_a, geo.segment_b, geo.circle_center]
    pts = [p for p in pts if len(p)]
    if not pts:
        return np.full(2, np.inf), np.full(2, -np.inf)
    allp = np.concatenate(pts)
    return allp.min(0), allp.max(0)


def page_text() -> str:
    """docs/gallery.md: each bundled scene with its picture, description, agents and model,
    from the index and the scene files."""
    out = ["# Scene gallery", "",
           "Every scene here is bundled with the package: `sweep scenes` lists them with their "
           "agent counts",
           "and models, `sweep run NAME` runs one, and `sweep scenes` prints the "
           "folder they are",
           "in, to copy one as the start of your own (the [schema reference](schema.md) lists "
           "every key).",
           "Each picture is drawn from a 10 s run of its scene by `docs/gallery.py`: the walls "
           "and",
           "obstacles, each agent's path over the three seconds before the snapshot, and the "
           "disks at the",
           "snapshot with their radii, coloured by group. Every scene runs in the test suite.",
           "",
           "People who walk to a goal or an exit walk with the speed law (`flows.headway: {}`, "
           "the csm law",
           "at the parameters `sweep verify` validates): their flows through doors and their "
           "speeds are",
           "those of the experiments ([What the defaults model](validation.md#what-the-"
           "defaults-model)).",
           "Each scene says which model it uses and why; deleting `headway` from a copy gives "
           "the pure",
           "model.", ""]
    for s in bundled_scenes():
        spec = load_yaml(s.path.read_text())
        desc = " ".join(str(spec.get("description", "")).split())
        out += [f"## {s.name}", "", f"![{s.name}](gallery/{s.name}.png)", "", desc, "",
                f"Model: {s.model}. Why: {s.why}.", "",
                f"`sweep run {s.name}`: {s.agents} agents.", ""]
    return "\n".join(out)


def write_page() -> None:
    """Writes docs/gallery.md (:func:`page_text`)."""
    (REPO / "docs" / "gallery.md").write_text(page_text())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="*", help="these scenes only")
    args = parser.parse_args(argv)
    scenes = [s for s in bundled_scenes() if not args.only or s.name in args.only]
    with tempfile.TemporaryDirectory() as tmp:
        for s in scenes:
            rec, wall = run_scene(s.name, Path(tmp))
            snap = SNAPSHOT.get(s.name, T_END)
            draw(rec, OUT / f"{s.name}.png", snap, s.name)
            if s.name == "room_door":
                draw(rec, REPO / "docs" / "crowd_at_door.png", snap, "200 agents leave a room")
            print(f"{s.name}: {wall:.1f} s, {OUT / (s.name + '.png')}")
    write_page()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
