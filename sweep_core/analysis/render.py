"""``sweep render``: an animation of a recording (:func:`render`).

Each video frame shows the disks with their radii, coloured by group, by speed or alike; the
walls and obstacles (moving ones where they are at that time; a map the node received from the
step it took effect); the navigation field recorded on ``/navigation_field`` (contours of the
travel distance, one colour per group); and, as text, the time, the step, the segment, the last
command, reset or map, and the run's status.

Time: seconds since the first recorded state, on the recording's clock (for ``sweep run``, the
simulation time; for the node, its log time, pauses included). Video frame k (0-based) shows
the last recorded state at or before ``start + k * speed / fps``; a window [start, end] gives
``floor((end - start) * fps / speed) + 1`` frames, so the video lasts that many / fps seconds.

MP4 (H.264) through imageio-ffmpeg, whose wheel ships the ffmpeg binary; GIF through Pillow
when the output name ends in ``.gif`` or, for the default name, when no ffmpeg is available.
Outputs go through :mod:`sweep_core.io.outputs` (never over the recording, written to a
temporary file and renamed).

Longer than the usual module: the frame's drawing, its colour modes (speeds over the
analysis's window among them) share one figure's state; the writers and their memory
estimates are apart, in :mod:`sweep_core.analysis.animation`."""
from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from sweep_core.analysis.animation import FrameWriter, open_writer
from sweep_core.analysis.drawing import (
    agent_groups,
    draw_geometry,
    group_colour,
    group_colours,
    pyplot,
    view_of,
)
from sweep_core.analysis.frames import Frame, progress_bar
from sweep_core.analysis.run import RunMeta, Schedule, load_run, scene_with_map
from sweep_core.analysis.speed import choose_window, fits, with_speeds
from sweep_core.errors import SweepError
from sweep_core.io import cdr
from sweep_core.io.recording import read_recording, scan_recording
from sweep_core.io.topics import NAVIGATION
from sweep_core.model.scene import Scene

#: the colourings of ``--colour``
COLOURINGS = ("group", "speed", "none")
#: contour lines of a navigation field's travel distance
CONTOURS = 12
#: the most video frames one render makes
MAX_FRAMES = 100_000
#: pixels per inch of the figure (sizes are given in pixels)
DPI = 100
#: margins round the room (px): left (y ticks and label), right, top (title, legend), bottom
#: (x ticks and label, two lines of text), and the colour bar's strip (speed colouring)
LEFT, RIGHT, TOP, BOTTOM, BAR = 56, 12, 30, 78, 72
#: the smallest width and height (px)
MIN_SIZE = 160
#: the lowest frame rate (1/s), a frame every 100 s: ffmpeg takes the rate as a fraction of
#: denominator at most 1e6, so a rate below 5e-7 reached it as 0 and the encoder failed
MIN_FPS = 0.01
@dataclass(frozen=True)
class RenderOptions:
    """fps: video frames per second; start, end: the window (s on the recording's clock, None:
    its end); speed: recorded seconds per video second; width, height: pixels (even; None:
    from the scene's aspect); colour: one of :data:`COLOURINGS`; speed_window: the window (s)
    of the speeds the speed colouring shows (:mod:`sweep_core.analysis.speed`; None: its
    default)."""

    fps: float = 10.0
    start: float = 0.0
    end: float | None = None
    speed: float = 1.0
    width: int = 960
    height: int | None = None
    colour: str = "group"
    speed_window: float | None = None

    def check(self) -> None:
        """SweepError naming the option, its value and the fix."""
        for name, value in (("--fps", self.fps), ("--speed", self.speed)):
            if not (math.isfinite(value) and value > 0):
                raise SweepError(f"{name} {value:g} is not a positive number (fix: give e.g. "
                                 f"{name} 10)")
        if self.fps < MIN_FPS:
            raise SweepError(f"--fps {self.fps:g} is below {MIN_FPS:g}, a frame every "
                             f"{1 / MIN_FPS:g} s (fix: give --fps {MIN_FPS:g} or more, and "
                             "--speed to show more recorded time per frame)")
        for name, t in (("--from", self.start), ("--to", self.end)):
            if t is not None and not (math.isfinite(t) and t >= 0):
                raise SweepError(f"{name} {t:g} s is not a finite time >= 0 (fix: give {name} "
                                 "in seconds since the first recorded state, e.g. 1)")
        if self.end is not None and self.end < self.start:
            raise SweepError(f"--to {self.end:g} s is before --from {self.start:g} s (fix: give "
                             "--to after --from)")
        for name, px in (("width", self.width), ("height", self.height)):
            if px is not None and not MIN_SIZE <= px <= 8192:
                raise SweepError(f"--size: {name} {px} px is outside {MIN_SIZE} .. 8192 (fix: "
                                 "give e.g. --size 960x540)")
        if self.colour not in COLOURINGS:
            raise SweepError(f"--colour {self.colour!r} is not one of {', '.join(COLOURINGS)} "
                             "(fix: give --colour group)")


def frame_times(start: float, end: float, fps: float, speed: float) -> np.ndarray:
    """The times (s) the video frames show: start + k speed / fps, k = 0 .. n - 1 (n below)."""
    n = int(math.floor((end - start) * fps / speed + 1e-9)) + 1
    if n > MAX_FRAMES:
        raise SweepError(f"the window {start:g} .. {end:g} s at --fps {fps:g} and --speed "
                         f"{speed:g} makes {n} frames, more than {MAX_FRAMES} (fix: shorten "
                         "it with --from/--to, or raise --speed)")
    return start + np.arange(n) * (speed / fps)


@dataclass
class Survey:
    """A first pass over the frames: their log times (ns), the box the agents and the scene
    take, the largest speed (m/s) over ``window`` s (None, 0: speeds not shown)."""

    log_ns: np.ndarray
    view: tuple[float, float, float, float]
    max_speed: float
    window: float | None = None


def survey(meta: RunMeta, progress: bool, window: float | None = None,
           problems: list[str] | None = None) -> Survey:
    """The first pass: frame times, extents, largest speed (over ``window`` s); skips go to
    ``problems``, one line each."""
    times: list[int] = []
    lo, hi, vmax = np.full(2, np.inf), np.full(2, -np.inf), 0.0
    bar = progress_bar(meta.frames or None, "frame", progress)
    bar.set_description("reading")
    for fr, speed in with_speeds(meta, window, problems):
        times.append(fr.log_ns)
        q = fr.positions[np.all(np.isfinite(fr.positions), axis=1)]
        if len(q):
            r = float(np.max(fr.agents["radius"])) if fr.agents is not None else 0.0
            lo, hi = np.minimum(lo, q.min(axis=0) - r), np.maximum(hi, q.max(axis=0) + r)
        if speed is not None and np.any(np.isfinite(speed)):
            vmax = max(vmax, float(np.nanmax(speed)))
        bar.update()
    bar.close()
    if not times:
        raise SweepError(f"{meta.path}: no frame could be read (fix: sweep recover it, or "
                         "record again)")
    pts = np.array([lo, hi]) if np.all(np.isfinite(lo)) else np.zeros((0, 2))
    return Survey(np.array(times, dtype=np.int64), view_of(meta.scene, pts), vmax, window)


def navigation_messages(meta: RunMeta) -> list[tuple[int, dict[str, np.ndarray]]]:
    """The recorded navigation fields, (log time ns, PointCloud2 fields), in file order (a
    message that cannot be decoded is not drawn)."""
    topics = [t for t, c in scan_recording(meta.path).channels.items()
              if t.endswith("/" + NAVIGATION) and c.msgtype == cdr.POINT_CLOUD2]
    if not topics:
        return []
    reader = read_recording(meta.path, sorted(topics, key=len)[:1])
    out = []
    try:
        for msg in reader:
            if msg.encoding == "cdr":
                try:
                    out.append((msg.log_time_ns, cdr.decode_point_cloud2(msg.data).fields))
                except Exception:  # noqa: BLE001, S112 - an undecodable field is not drawn
                    continue
    finally:
        reader.close()
    return out


def field_grids(fields: dict[str, np.ndarray]) -> list[tuple[int, np.ndarray, np.ndarray,
                                                             np.ndarray]]:
    """(group, x (W,), y (H,), T (H, W)) per navigation field of a ``navigation_field`` cloud."""
    out = []
    if not len(fields.get("x", ())):
        return out
    for g in np.unique(fields["group"]):
        on = fields["group"] == g
        x, y, t = (fields[k][on].astype(float) for k in ("x", "y", "T"))
        ux, uy = np.unique(x), np.unique(y)
        if len(ux) < 2 or len(uy) < 2 or len(ux) * len(uy) != len(x):
            continue
        grid = np.full((len(uy), len(ux)), np.nan)
        grid[np.searchsorted(uy, y), np.searchsorted(ux, x)] = t
        grid[~np.isfinite(grid)] = np.nan
        out.append((int(g), ux, uy, grid))
    return out


class Painter:
    """The figure of one video frame: axes, text and the artists redrawn each frame."""

    def __init__(self, meta: RunMeta, sv: Survey, opts: RenderOptions, size: tuple[int, int]
                 ) -> None:
        self.plt = pyplot()
        self.meta, self.opts, self.view = meta, opts, sv.view
        self.fig = self.plt.figure(figsize=(size[0] / DPI, size[1] / DPI), dpi=DPI)
        w, h = size
        right = RIGHT + (BAR if opts.colour == "speed" else 0)
        self.ax = self.fig.add_axes((LEFT / w, BOTTOM / h, (w - LEFT - right) / w,
                                     (h - TOP - BOTTOM) / h))
        x0, x1, y0, y1 = sv.view
        self.ax.set_xlim(x0, x1)
        self.ax.set_ylim(y0, y1)
        self.ax.set_aspect("equal", adjustable="box")
        self.ax.set_xlabel("x (m)")
        self.ax.set_ylabel("y (m)")
        self.ax.tick_params(labelsize=8)
        scene = meta.scene
        name = scene.name if scene is not None else Path(meta.path).name
        self.fig.text(0.01, (h - TOP / 2) / h, name, ha="left", va="center", fontsize=11)
        self.text = self.fig.text(0.01, 4 / h, "", ha="left", va="bottom", fontsize=9,
                                  family="monospace")
        self.vmax = max(sv.max_speed, 1e-9)
        self.dynamic: list[Any] = []
        self.walls: list[Any] = []
        self.nav: list[Any] = []
        self.scene_key: Any = None
        self.nav_key: Any = None
        self.groups, self.names = agent_groups(scene, scene.n_agents if scene else 0)
        if opts.colour == "speed":
            from matplotlib.cm import ScalarMappable
            from matplotlib.colors import Normalize
            self.norm = Normalize(0.0, self.vmax)
            bar = self.fig.add_axes(((w - BAR + 8) / w, BOTTOM / h, 12 / w,
                                     (h - TOP - BOTTOM) / h))
            self.fig.colorbar(ScalarMappable(self.norm, "viridis"), cax=bar,
                              label=f"speed over {sv.window or 0:g} s (m/s)")
        elif opts.colour == "group" and isinstance(self.names, list) and self.names:
            from matplotlib.patches import Patch
            handles = [Patch(color=group_colour(k), label=n) for k, n in enumerate(self.names)]
            n = scene.n_agents if scene is not None else 0
            if np.any(agent_groups(scene, n)[0] < 0):
                handles.append(Patch(color=group_colour(-1), label="others"))
            self.fig.legend(handles=handles, loc="upper right", bbox_to_anchor=(0.99, 0.995),
                            fontsize=8, ncol=len(handles), frameon=False)

    def draw_scene(self, scene: Scene | None, t: float, key: Any) -> None:
        """Walls and obstacles (posed at t when some move)."""
        moving = scene is not None and scene.geometry.is_moving
        if key == self.scene_key and not moving:
            return
        for a in self.walls:
            a.remove()
        self.walls = [] if scene is None else draw_geometry(self.ax, scene.geometry, t,
                                                            self.view)
        self.scene_key = key

    def draw_navigation(self, key: int, fields: dict[str, np.ndarray] | None) -> None:
        """Contours of the travel distance of each recorded navigation field."""
        if key == self.nav_key:
            return
        for a in self.nav:
            a.remove()
        self.nav = []
        self.nav_key = key
        for g, x, y, t in field_grids(fields or {}):
            finite = t[np.isfinite(t)]
            if finite.size < 4 or float(finite.max()) <= 0:
                continue
            levels = np.linspace(0.0, float(finite.max()), CONTOURS + 1)[1:]
            cs = self.ax.contour(x, y, np.ma.masked_invalid(t), levels=levels,
                                 colors=group_colour(g) if g >= 0 else "0.6", linewidths=0.6,
                                 alpha=0.5, zorder=1)
            self.nav.append(cs)

    def draw_agents(self, fr: Frame, speed: np.ndarray | None = None) -> None:
        from matplotlib.collections import EllipseCollection
        for a in self.dynamic:
            a.remove()
        q = fr.positions
        n = len(q)
        scene = self.meta.scene
        if fr.agents is not None:
            r = fr.agents["radius"].astype(float)
        elif scene is not None and scene.n_agents == n:  # no /agents: the scene's radius law
            r = scene.radii(fr.stamp_ns / 1e9)
        else:  # no radius known: small dots, 1 % of the view's width
            r = np.full(n, 0.01 * (self.view[1] - self.view[0]))
        if self.opts.colour == "speed" and speed is not None:
            from matplotlib import colormaps
            faces: Any = colormaps["viridis"](self.norm(speed))  # NaN (no window): grey
            faces[~np.isfinite(speed)] = (0.75, 0.75, 0.75, 1.0)
        elif self.opts.colour == "group" and self.names:
            if len(self.groups) != n:
                self.groups, self.names = agent_groups(self.meta.scene, n)
            faces = group_colours(self.groups)
        else:
            faces = ["#1f77b4"] * n
        disks = EllipseCollection(2 * r, 2 * r, np.zeros(n), units="xy", offsets=q,
                                  offset_transform=self.ax.transData, facecolors=faces,
                                  edgecolors="k", linewidths=0.4, zorder=3)
        self.dynamic = [self.ax.add_collection(disks)]

    def pixels(self) -> np.ndarray:
        """The frame as (H, W, 3) uint8 RGB."""
        self.fig.canvas.draw()
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        self.plt.close(self.fig)


def _events(meta: RunMeta) -> list[tuple[int, str]]:
    """(log time ns, text) of the commands, resets and maps, in time order."""
    out = [(c.log_time_ns, f"command {c.index} ({c.spec.get('kind', '?')}) at step {c.step}")
           for c in meta.commands]
    out += [(ns, f"reset {k + 1}") for k, ns in enumerate(meta.resets)]
    out += [(m.log_time_ns, f"map {m.index} at step {m.step}") for m in meta.maps]
    return sorted(out)


def render(recording: str, out: str | None = None, opts: RenderOptions | None = None,
           progress: bool = True, encoder: bool | None = None,
           problems: list[str] | None = None) -> tuple[str, int]:
    """Writes the animation of ``recording``; returns its path and its number of frames.
    encoder: whether MP4 can be written (None: look for imageio-ffmpeg's ffmpeg); problems:
    gets one line per chunk or message skipped (damaged, undecodable)."""
    from sweep_core.analysis.animation import check_memory, has_encoder, output_path
    opts = opts or RenderOptions()
    opts.check()
    meta = load_run(recording)
    path, fmt = output_path(meta.path, out, has_encoder() if encoder is None else encoder)
    speeds = opts.colour == "speed"
    window = choose_window(opts.speed_window, meta.frame_interval) if speeds else None
    sv = survey(meta, progress, window, problems)
    if window is not None and opts.speed_window is not None:
        fits(window, (sv.log_ns - sv.log_ns[0]) / 1e9)
    clock = (sv.log_ns - sv.log_ns[0]) / 1e9
    end = float(clock[-1]) if opts.end is None else opts.end
    if opts.start > float(clock[-1]):
        raise SweepError(f"--from {opts.start:g} s is after the recording's last state at "
                         f"{float(clock[-1]):g} s (fix: give --from at most that)")
    times = frame_times(opts.start, end, opts.fps, opts.speed)
    size = _size(opts, sv.view)
    check_memory(path, fmt, len(times), size)
    painter = Painter(meta, sv, opts, size)
    try:
        with open_writer(path, fmt, size, opts.fps, [meta.path]) as writer:
            _paint(meta, sv, times, painter, writer, progress)
    finally:
        painter.close()
    return path, len(times)


def _size(opts: RenderOptions, view: tuple[float, float, float, float]) -> tuple[int, int]:
    """(width, height) px, both even (H.264 needs it); the height, when not given, such that
    the room fills the width between the margins."""
    w = opts.width
    h = opts.height
    if h is None:
        x0, x1, y0, y1 = view
        inner = w - LEFT - RIGHT - (BAR if opts.colour == "speed" else 0)
        h = TOP + BOTTOM + int(round(max(inner, 32) * (y1 - y0) / (x1 - x0)))
        h = min(max(h, TOP + BOTTOM + 64), 4096)
    return w - w % 2, h - h % 2


def _frames_at(meta: RunMeta, sv: Survey, times: np.ndarray
               ) -> Iterator[tuple[int, Frame, np.ndarray | None]]:
    """(video frame index, the recorded frame it shows, its speeds or None), in order."""
    clock = (sv.log_ns - sv.log_ns[0]) / 1e9
    # the recorded frame each video frame shows: the last at or before its time
    pick = np.searchsorted(clock, times + 1e-9, side="right") - 1
    pick = np.maximum(pick, 0)
    k = 0
    last: tuple[Frame, np.ndarray | None] | None = None
    for j, (fr, speed) in enumerate(with_speeds(meta, sv.window)):
        last = (fr, speed)
        while k < len(pick) and pick[k] == j:
            yield k, fr, speed
            k += 1
        if k == len(pick):
            return
    while last is not None and k < len(pick):  # past the readable end: the last state
        yield k, last[0], last[1]
        k += 1


def _paint(meta: RunMeta, sv: Survey, times: np.ndarray, painter: Painter,
           writer: FrameWriter, progress: bool) -> None:
    schedule = Schedule(meta)
    nav = navigation_messages(meta)
    nav_ns = [ns for ns, _ in nav]
    events = _events(meta)
    event_ns = [ns for ns, _ in events]
    scenes: dict[int, Scene | None] = {}
    last_ns = int(sv.log_ns[-1])
    bar = progress_bar(len(times), "frame", progress)
    bar.set_description("rendering")
    for _, fr, speed in _frames_at(meta, sv, times):
        segment = meta.segment_of(fr.log_ns)
        step = meta.step_of(fr.stamp_ns) if meta.dt else 0
        t = fr.stamp_ns / 1e9
        packed = schedule.map_at(segment, step) if meta.maps else None
        key = id(packed) if packed is not None else 0
        if key not in scenes:
            scenes[key] = (scene_with_map(meta.scene, packed)
                           if packed is not None and meta.scene is not None else meta.scene)
        painter.draw_scene(scenes[key], t, key)
        j = int(np.searchsorted(nav_ns, fr.log_ns, side="right")) - 1
        painter.draw_navigation(j, nav[j][1] if j >= 0 else None)
        painter.draw_agents(fr, speed)
        e = int(np.searchsorted(event_ns, fr.log_ns, side="right")) - 1
        status = meta.status if fr.log_ns >= last_ns else "running"
        line = f"t = {t:8.2f} s   step {step}"
        if meta.resets:
            line += f"   segment {segment}"
        line += f"   {len(fr.positions)} agents   {status}"
        if e >= 0:
            line += f"\nlast event: {events[e][1]}"
        painter.text.set_text(line)
        writer.write(painter.pixels())
        bar.update()
    bar.close()
