"""The figure of ``sweep analyze``: its panels exist with their titles and labels, the room
keeps its aspect with the legends outside it, groups and exits have their own curves, the time
axes mark the node's commands, resets and maps, and the minimum gap is a distribution with
rounding-level frames counted apart. Read from matplotlib's objects (axes, legends, lines),
not pixels."""
from __future__ import annotations

import dataclasses

import matplotlib
import numpy as np
import pytest
from matplotlib.collections import LineCollection

from sweep_core.analysis import crowd, metrics, plots
from sweep_core.analysis.run import Command, MapChange
from sweep_core.cli import main

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

SCENE = """
name: figure test
agents:
  positions: [[1, 0.8], [1.7, 0.8], [2.4, 0.8], [8, 2.2], [7.3, 2.2], [5, 1.5]]
  radius: 0.25
  groups:
    - {name: east, agents: [0, 1, 2], speed: 1.3, drift: {kind: geodesic, goal: [9.5, 0.8]}}
    - {name: west, agents: [3, 4], speed: 1.0, drift: {kind: geodesic, goal: [0.5, 2.2]}}
walls:
  - {kind: polyline, closed: true, points: [[0, 0], [10, 0], [10, 3], [0, 3]]}
noise: {sigma: 0.05}
"""

TITLES = ("trajectories", "density", "arrivals and flow per group and exit",
          "fundamental diagram", "speed and contacts over time",
          "minimum gap: distribution over frames")


@pytest.fixture(scope="module")
def analysis(tmp_path_factory):
    d = tmp_path_factory.mktemp("figure")
    (d / "scene.yaml").write_text(SCENE)
    rec = d / "run.mcap"
    assert main(["run", str(d / "scene.yaml"), "--t-end", "2", "--dt", "0.02", "--out",
                 str(rec), "--quiet"]) == 0
    return metrics.analyze(rec, line=(5.0, 0.0, 5.0, 3.0))


@pytest.fixture
def figure(analysis):
    an = analysis
    # the node's records, as load_run reads them: a command at 0.5 s, a reset at 1 s, a map
    t0 = an.t0_ns
    meta = dataclasses.replace(
        an.meta, commands=[Command(0, "goal", 25, t0 + 500_000_000, {"kind": "none"}, 0)],
        resets=[t0 + 1_000_000_000],
        maps=[MapChange(0, "map", 10, t0 + 1_500_000_000, {}, 1)])
    fig = plots.analysis_figure(dataclasses.replace(an, meta=meta))
    yield fig
    plt.close(fig)


def panel(fig, words):
    (ax,) = [a for a in fig.axes if a.get_title().startswith(words)]
    return ax


def legend_texts(ax):
    return [t.get_text() for t in ax.get_legend().get_texts()] if ax.get_legend() else []


def test_every_panel_is_there_with_its_labels(figure):
    for words in TITLES:
        panel(figure, words)
    assert panel(figure, "fundamental diagram").get_xlabel().startswith("local density (1/m²")
    assert panel(figure, "fundamental diagram").get_ylabel() == "speed over 0.625 s (m/s)"
    for words in ("arrivals", "speed and contacts"):
        assert panel(figure, words).get_xlabel() == "t (s)"
    assert panel(figure, "arrivals").get_ylabel() == "agents (cumulative)"


def test_the_room_keeps_its_aspect_and_its_legends_stay_outside(figure):
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    for words in ("trajectories", "density"):
        ax = panel(figure, words)
        assert ax.get_aspect() == 1.0 and ax.get_xlabel() == "x (m)"
        box = ax.get_window_extent(renderer)
        legend = ax.get_legend().get_window_extent(renderer)
        assert legend.y1 <= box.y0  # below the room, covering none of it
    assert legend_texts(panel(figure, "trajectories")) == ["east", "west", "others"]
    assert [t.split(":")[0] for t in legend_texts(panel(figure, "density"))] == ["east", "west"]
    lines = [c for c in panel(figure, "trajectories").collections
             if isinstance(c, LineCollection) and c.get_label().startswith("trajectories")]
    assert len(lines) == 3 and sum(len(c.get_segments()) for c in lines) == 6


def test_arrivals_and_flow_are_drawn_per_group(figure):
    texts = legend_texts(panel(figure, "arrivals"))
    for name in ("arrived, all", "arrived, east", "arrived, west", "line: net crossings",
                 "line: east crossed", "line: west crossed"):
        assert name in texts


def test_time_axes_mark_commands_resets_and_maps(figure):
    for words in ("arrivals", "speed and contacts"):
        ax = panel(figure, words)
        assert {"commands", "resets", "maps"} <= set(legend_texts(ax))
        marks = sorted(float(ln.get_xdata()[0]) for ln in ax.get_lines()
                       if ln.get_label() in ("commands", "resets", "maps"))
        assert marks == [0.5, 1.0, 1.5]


def test_minimum_gap_is_a_distribution_with_touching_frames_apart(figure, analysis):
    ax = panel(figure, "minimum gap")
    assert ax.get_ylabel() == "fraction of frames (bars sum to 1)"
    touching, overlap, positive = crowd.gap_distribution(analysis.table[:, 2])
    heights = [p.get_height() for p in ax.patches]
    # every frame counted once: touching, overlapping and the gaps above rounding level
    assert sum(heights) == pytest.approx(1.0)
    total = touching + overlap + len(positive)
    labels = [t.get_text() for t in ax.get_xticklabels()]
    k = next(i for i, lab in enumerate(labels) if lab.startswith("touching"))
    assert heights[k] == pytest.approx(touching / total)
    # rounding-level gaps are counted as touching, not drawn as distances
    gaps = np.array([5e-15, -4e-15, 0.0, 2e-9, -3e-9, 0.01])
    t, o, p = crowd.gap_distribution(gaps)
    assert (t, o, p.tolist()) == (3, 1, [2e-9, 0.01])
    names, frac = plots.gap_classes(gaps)
    assert frac.sum() == pytest.approx(1.0) and names[0].startswith("overlap")
    assert frac[:3].tolist() == pytest.approx([1 / 6, 3 / 6, 1 / 6])  # overlap, touching, 2e-9
    assert names[-1] == "1 to\n10 mm" and frac[-1] == pytest.approx(1 / 6)  # 0.01 m


def test_the_counting_line_is_drawn_in_both_rooms(figure):
    for words in ("trajectories", "density"):
        (line,) = [ln for ln in panel(figure, words).get_lines()
                   if ln.get_label() == "counting line"]
        assert line.get_linewidth() >= 3 and line.get_xydata().tolist() == [[5, 0], [5, 3]]


def test_the_fundamental_diagram_stands_beside_weidmanns(figure):
    ax = panel(figure, "fundamental diagram")
    assert "Weidmann 1993 (free speed 1.34 m/s)" in legend_texts(ax)


def test_a_goal_command_in_a_scene_without_navigation_gets_its_contours(analysis):
    """A node recording whose scene drifts uniformly and whose goal command built a geodesic
    field round the walls: the density panel draws that field's travel time."""
    from sweep_core.model.scene import Scene
    scene = Scene.from_dict({**analysis.meta.scene.spec, "agents": {
        "positions": analysis.meta.scene.spec["agents"]["positions"], "radius": 0.25},
        "drift": {"kind": "uniform", "velocity": [0.2, 0.0]}})
    goal = {"kind": "geodesic", "goal": [9.5, 1.5], "speed": 1.0}
    meta = dataclasses.replace(analysis.meta, scene=scene, commands=[
        Command(3, "goal", 25, analysis.t0_ns + 500_000_000, goal, 0)])
    an = dataclasses.replace(analysis, meta=meta)
    assert plots.commanded_navigation(an)[0] == 3
    fig = plots.analysis_figure(an)
    try:
        ax = panel(fig, "density")
        assert ax.get_title().startswith("density and travel time")
        assert ax.get_legend().get_title().get_text() == (
            "travel time to the goal (the field of command 3)")
        # without the command, no contours
        plain = dataclasses.replace(an, meta=dataclasses.replace(meta, commands=[]))
        assert plots.commanded_navigation(plain) is None
    finally:
        plt.close(fig)


def test_every_exit_has_its_arrivals_curve_even_unreached(tmp_path):
    (tmp_path / "exits.yaml").write_text("""
agents: {positions: [[2, 2], [2.6, 2], [2, 3]], radius: 0.2}
walls:
  - {kind: polyline, points: [[0, 0], [6, 0], [6, 2.5]]}
  - {kind: polyline, points: [[6, 3.5], [6, 6], [0, 6], [0, 0]]}
drift: {kind: exits, speed: 1.2, exits: [{goal: [7, 3]},
        {region: {kind: rectangle, min: [2, 6.5], max: [3, 7]}}]}
""")
    rec = tmp_path / "exits.mcap"
    assert main(["run", str(tmp_path / "exits.yaml"), "--t-end", "0.5", "--dt", "0.05",
                 "--out", str(rec), "--quiet"]) == 0
    fig = plots.analysis_figure(metrics.analyze(rec))
    try:
        texts = legend_texts(panel(fig, "arrivals"))
        assert "arrived at exits[0]" in texts and "arrived at exits[1]" in texts
    finally:
        plt.close(fig)


def test_each_group_has_its_mean_windowed_speed(analysis):
    pedpy = pytest.importorskip("pedpy")
    from sweep_core.analysis.pedpy_export import read_trajectories
    # dt 0.02 s: the 0.625 s window's ends are the frames 16 either side (0.32 s nearest 0.3125)
    ped = pedpy.compute_individual_speed(
        traj_data=read_trajectories(analysis.meta.path).to_pedpy(), frame_step=16,
        speed_calculation=pedpy.SpeedCalculation.BORDER_SINGLE_SIDED)
    groups = analysis.summary["per_group"]
    for name, ids in (("east", [0, 1, 2]), ("west", [3, 4])):
        want = float(ped[ped["id"].isin(ids)]["speed"].mean())
        assert groups[name]["speed_mean_m_per_s"] == pytest.approx(want, rel=1e-9)
        assert groups[name]["speed_window_s"] == 0.625
