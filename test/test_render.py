"""``sweep render``: an animation of a short recording, read back with the encoder package's
own reader (imageio-ffmpeg) and, for GIF, with Pillow: frame count, size and duration match the
options; the recording is never overwritten."""
from __future__ import annotations

import os

import imageio_ffmpeg
import numpy as np
import pytest
from PIL import Image

from sweep_core.analysis import render
from sweep_core.cli import main
from sweep_core.errors import SweepError

SCENE = """
name: render test
agents:
  positions: [[1, 0.8], [1.7, 0.8], [19, 2.2], [18.3, 2.2], [10, 2.5]]
  radius: 0.25
  groups:
    - {name: east, agents: [0, 1], speed: 1.3, drift: {kind: geodesic, goal: [19.5, 0.8]}}
    - {name: west, agents: [2, 3], speed: 0.9, drift: {kind: geodesic, goal: [0.5, 2.2]}}
walls:
  - {kind: polyline, closed: true, points: [[0, 0], [20, 0], [20, 3], [0, 3]]}
obstacles:
  - {kind: circle, center: [10, 1.2], radius: 0.3, velocity: [0.5, 0.0]}
noise: {sigma: 0.05}
"""


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    d = tmp_path_factory.mktemp("render")
    scene = d / "scene.yaml"
    scene.write_text(SCENE)
    rec = d / "run.mcap"
    assert main(["run", str(scene), "--t-end", "1.5", "--dt", "0.02", "--out", str(rec),
                 "--quiet"]) == 0
    return rec


def test_frame_times_cover_the_window_at_the_frame_rate():
    t = render.frame_times(0.5, 2.0, 10.0, 1.0)
    assert len(t) == 16 and t[0] == 0.5 and abs(t[-1] - 2.0) < 1e-12
    assert len(render.frame_times(0.0, 2.0, 10.0, 2.0)) == 11  # twice as fast: half the frames


def test_mp4_has_the_frames_size_and_duration_asked_for(recording, capsys):
    out = recording.with_name("window.mp4")
    before = recording.read_bytes()
    assert main(["render", str(recording), "--out", str(out), "--fps", "10", "--from", "0.2",
                 "--to", "1.2", "--size", "320x160", "--quiet"]) == 0
    assert f"{out}: 11 frames" in capsys.readouterr().out
    frames, secs = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert frames == 11 and secs == pytest.approx(1.1, abs=0.01)
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = reader.__next__()
    assert tuple(meta["size"]) == (320, 160) and meta["fps"] == pytest.approx(10.0)
    pixels = [np.frombuffer(f, np.uint8).reshape(160, 320, 3) for f in reader]
    assert len(pixels) == 11
    # the agents and the obstacle move: the first and last frames differ
    assert np.abs(pixels[0].astype(int) - pixels[-1].astype(int)).max() > 100
    assert recording.read_bytes() == before
    assert not any(p.name.endswith(".partial") for p in recording.parent.iterdir())


def test_gif_read_back_with_pillow(recording):
    out = recording.with_name("clip.gif")
    path, n = render.render(str(recording), str(out),
                            render.RenderOptions(fps=20, start=0.5, end=1.0, width=240,
                                                 height=180, colour="speed"),
                            progress=False)
    assert (path, n) == (str(out), 11)
    with Image.open(out) as im:
        assert im.format == "GIF" and im.size == (240, 180) and im.n_frames == 11
        durations = []
        for k in range(im.n_frames):
            im.seek(k)
            durations.append(im.info["duration"])
    assert durations == [50] * 11  # 11 frames of 1 / 20 s: 0.55 s


def test_without_an_encoder_the_default_output_is_a_gif(recording):
    path, n = render.render(str(recording), None,
                            render.RenderOptions(fps=5, end=0.4, width=160, height=160,
                                                 colour="none"),
                            progress=False, encoder=False)
    assert path == os.path.splitext(str(recording))[0] + ".gif" and n == 3
    with Image.open(path) as im:
        assert im.n_frames == 3 and im.size == (160, 160)
    with pytest.raises(SweepError, match=r"3001 GIF frames of 960 x 540 px need 3.1 GB"):
        render.render(str(recording), str(recording.with_name("long.gif")),
                      render.RenderOptions(fps=2000, width=960, height=540), progress=False)
    assert not recording.with_name("long.gif").exists()
    with pytest.raises(SweepError, match=r"no MP4 encoder .* name the output NAME.gif"):
        render.render(str(recording), str(recording.with_name("x.mp4")), progress=False,
                      encoder=False)


def test_bad_options_and_the_recording_as_output_are_refused(recording, capsys):
    before = recording.read_bytes()
    assert main(["render", str(recording), "--out", str(recording), "--quiet"]) == 2
    assert main(["render", str(recording), "--fps", "0", "--quiet"]) == 2
    assert main(["render", str(recording), "--size", "big", "--quiet"]) == 2
    assert main(["render", str(recording), "--from", "99", "--quiet"]) == 2
    assert main(["render", str(recording), "--size", "100x100", "--quiet"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 5 and all(e.startswith("sweep: error: ") for e in err)
    assert "--size: width 100 px is outside 160 .. 8192" in err[4]
    assert "--fps 0 is not a positive number" in err[1] and "--size 'big'" in err[2]
    assert "--from 99 s is after the recording's last state at 1.5 s" in err[3]
    assert recording.read_bytes() == before


@pytest.mark.parametrize("option, value", [("--to", "nan"), ("--to", "inf"),
                                           ("--from", "nan"), ("--from", "inf"),
                                           ("--from", "-1")])
def test_a_time_that_is_not_finite_is_refused_by_name(recording, capsys, option, value):
    assert main(["render", str(recording), option, value, "--quiet"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err == [f"sweep: error: {option} {value} s is not a finite time >= 0 (fix: give "
                   f"{option} in seconds since the first recorded state, e.g. 1)"]


def test_the_recorded_navigation_field_is_read_per_group(recording):
    from sweep_core.analysis.run import load_run
    meta = load_run(recording)
    messages = render.navigation_messages(meta)
    assert len(messages) == 1  # no update_every: the field is computed and recorded once
    grids = render.field_grids(messages[0][1])
    assert [g for g, *_ in grids] == [0, 1]  # east, west
    for _, x, y, t in grids:
        assert t.shape == (len(y), len(x)) and np.all(np.diff(x) > 0) and np.all(np.diff(y) > 0)
        assert np.nanmax(t) > 9.0  # from one end of the 20 m corridor to the other goal


def test_speed_colours_show_the_windowed_speed(recording):
    from sweep_core.analysis import metrics
    from sweep_core.analysis.run import load_run
    meta = load_run(str(recording))
    sv = render.survey(meta, progress=False, window=0.2)
    an = metrics.analyze(recording, speed_window=0.2)
    # the colour scale's top is the largest windowed speed sweep analyze reports
    assert sv.window == 0.2 and sv.max_speed == pytest.approx(an.summary["speed"]["max_m_per_s"])
    frames = list(render.with_speeds(meta, 0.2))
    assert len(frames) == an.summary["frames"]
    assert np.allclose([np.nanmean(s) for _, s in frames], an.table[:, 6])
    with pytest.raises(SweepError, match="--speed-window: must be a positive number"):
        render.render(str(recording), str(recording.with_name("x.gif")),
                      render.RenderOptions(colour="speed", speed_window=-1.0), progress=False)
