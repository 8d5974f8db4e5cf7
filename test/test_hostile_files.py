"""Outputs never overwrite by surprise, and files from others are data, not instructions.

Writers (sweep run, recover, analyze, map, the Recorder) refuse an output that is one of their
inputs or that is not a regular file (a device, a FIFO, a folder), and two writers of one
recording cannot both write it. Readers (analyze, replay, compare, map files) never read a
local path a recording names, never open a FIFO or a device as a map, quote no file contents in
their errors, skip a message or chunk they cannot read (naming it) and report missing states.
"""
from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from test_faults import SCENE

from sweep_core.cli import main
from sweep_core.errors import OutputError
from sweep_core.io import cdr
from sweep_core.io.recording import BackgroundRecorder, Recorder, read_metadata
from sweep_core.model.json_text import dump_json
from sweep_core.model.scene import scene_data

REPO = Path(__file__).resolve().parents[1]
#: a line no error message may quote
SECRET = "SECRET-LINE-4711: do not print me"


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))


def _sweep(args: list[str], cwd: Path, timeout: float = 120.0) -> subprocess.CompletedProcess:
    """``sweep ARGS`` in a subprocess (a hang fails the test at ``timeout`` instead of
    blocking the suite)."""
    return subprocess.run([sys.executable, "-m", "sweep_core.cli", *args], cwd=cwd, env=_env(),
                          capture_output=True, text=True, timeout=timeout)


def _cli(args: list[str], capsys) -> subprocess.CompletedProcess:
    """``sweep ARGS`` in this process (for what cannot hang even on the old code)."""
    capsys.readouterr()
    code = main(args)
    cap = capsys.readouterr()
    return subprocess.CompletedProcess(args, code, cap.out, cap.err)


def _error_line(stderr: str) -> str:
    """The one ``sweep: error:`` line of a refused command (other lines, such as a first run
    compiling its kernels, may come before it); no traceback."""
    errors = [ln for ln in stderr.splitlines() if ln.startswith("sweep: error:")]
    assert len(errors) == 1 and "Traceback" not in stderr, stderr
    return errors[0]


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    p = tmp_path / "scene.yaml"
    p.write_text(SCENE)
    return p


@pytest.fixture
def run_file(tmp_path: Path, scene: Path) -> Path:
    """A 100-step recording (101 /poses messages) of the 3-agent scene."""
    out = tmp_path / "run.mcap"
    assert main(["run", str(scene), "--t-end", "1.0", "--dt", "0.01", "--out", str(out),
                 "--quiet"]) == 0
    return out


def _device(tmp_path: Path) -> Path:
    """A character device in tmp_path (/dev/full's numbers) when mknod is permitted, else a
    symlink to /dev/null."""
    p = tmp_path / "device"
    try:
        os.mknod(p, stat.S_IFCHR | 0o666, os.makedev(1, 7))
    except (PermissionError, OSError):
        p.symlink_to("/dev/null")
    assert stat.S_ISCHR(os.stat(p).st_mode)
    return p


def _fifo(tmp_path: Path, name: str = "fifo") -> Path:
    p = tmp_path / name
    os.mkfifo(p)
    return p


def _rewrite(src: Path, dst: Path, *, keep: Callable[[str, int], bool] = lambda t, i: True,
             data: Callable[[str, int, bytes], bytes] = lambda t, i, d: d,
             metadata: Callable[[str, dict], dict] = lambda n, m: m,
             encoding: Callable[[str], str] = lambda t: "cdr") -> None:
    """A copy of the recording ``src`` as another writer would make it: messages kept by
    ``keep(topic, index)`` (sequence numbers kept), payloads from ``data``, metadata records
    from ``metadata``, channel encodings from ``encoding``."""
    with open(src, "rb") as f, open(dst, "wb") as o:
        reader = make_reader(f)
        summary = reader.get_summary()
        w = Writer(o, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="test rewrite")
        schema_ids = {sid: w.register_schema(s.name, s.encoding, s.data)
                      for sid, s in summary.schemas.items()}
        channel_ids = {cid: w.register_channel(c.topic, encoding(c.topic),
                                               schema_ids[c.schema_id], dict(c.metadata))
                       for cid, c in summary.channels.items()}
        counts: dict[str, int] = {}
        for _, channel, m in reader.iter_messages(log_time_order=False):
            i = counts.get(channel.topic, 0)
            counts[channel.topic] = i + 1
            if keep(channel.topic, i):
                w.add_message(channel_ids[channel.id], m.log_time,
                              data(channel.topic, i, m.data), m.publish_time, m.sequence)
        for md in reader.iter_metadata():
            w.add_metadata(md.name, metadata(md.name, dict(md.metadata)))
        w.finish()


# -- outputs --------------------------------------------------------------------------------


def test_outputs_of_another_kind_are_refused_and_kept(tmp_path, scene, run_file, capsys):
    """Before: `sweep recover IN /dev/full` replaced the device with a regular file (rc 0) and
    a FIFO as --out blocked or was replaced."""
    dev, fifo = _device(tmp_path), _fifo(tmp_path)
    for out in (dev, fifo, tmp_path):
        for args in (["recover", str(run_file), str(out)],
                     ["run", str(scene), "--t-end", "0.05", "--out", str(out), "--quiet"]):
            # a FIFO in a subprocess: opening one to write could block this process
            done = _sweep(args, tmp_path, timeout=60) if out == fifo else _cli(args, capsys)
            assert done.returncode == 2, (args, done.stdout, done.stderr)
            err = _error_line(done.stderr)
            assert str(out) in err, err
            assert "only a regular file is overwritten" in err and "fix:" in err, err
            assert "recovered" not in done.stdout
    assert stat.S_ISCHR(os.stat(dev).st_mode) and stat.S_ISFIFO(os.stat(fifo).st_mode)
    # analyze: an output name taken by a folder is refused before anything is written
    (tmp_path / "run.density.csv").mkdir()
    done = _cli(["analyze", str(run_file), "--no-plots", "--quiet"], capsys)
    assert done.returncode == 2 and "run.density.csv: exists and is a folder" in done.stderr, \
        done.stderr
    assert not (tmp_path / "run.analysis.csv").exists()
    assert not list(tmp_path.glob(".*partial"))


def test_output_equal_to_an_input_is_refused(tmp_path, scene, capsys):
    """Before: `sweep run small.yaml --out small.yaml` ran (rc 0) and the scene was gone."""
    before = scene.read_bytes()
    link = tmp_path / "link.yaml"
    link.symlink_to(scene)
    for out in (scene, link):
        assert main(["run", str(scene), "--t-end", "0.05", "--out", str(out), "--quiet"]) == 2
        err = capsys.readouterr().err
        assert f"{out}: is also an input" in err and "fix: --out OTHER" in err, err
    assert scene.read_bytes() == before
    # sweep map: the starter scene may not be the map file
    (tmp_path / "m.pgm").write_bytes(b"P5 4 4 255\n" + bytes([254] * 16))
    map_yaml = tmp_path / "m.yaml"
    map_yaml.write_text("image: m.pgm\nresolution: 0.5\norigin: [0, 0, 0]\n")
    text = map_yaml.read_text()
    assert main(["map", str(map_yaml), "--scene", str(map_yaml)]) == 2
    assert "is also an input" in capsys.readouterr().err
    assert map_yaml.read_text() == text


def test_two_writers_of_one_recording(tmp_path, scene):
    """Before: two Recorders (and two `sweep run --out same.mcap`) both wrote one file; it was
    corrupt and the first run was lost."""
    path = tmp_path / "same.mcap"
    first = Recorder(path, metadata={"who": "first"})
    with pytest.raises(OutputError, match="same.mcap: another run is writing it right now"):
        Recorder(path, metadata={"who": "second"})
    with pytest.raises(OutputError, match="another run is writing it"):
        BackgroundRecorder(path)
    first.add_channel("/clock", cdr.CLOCK)
    first.write("/clock", 1, cdr.encode_clock(1))
    first.close()
    assert read_metadata(path)["sweep_ros"] == {"who": "first"}  # untouched by the loser
    # a running `sweep run` holds its recording; a second one on the same file is refused
    proc = subprocess.Popen([sys.executable, "-m", "sweep_core.cli", "run", str(scene),
                             "--t-end", "1000", "--dt", "0.001", "--out", "busy.mcap",
                             "--quiet"], cwd=tmp_path, env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        busy = tmp_path / "busy.mcap"
        import time
        deadline = time.monotonic() + 120
        while not (busy.exists() and busy.stat().st_size > 0):
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.05)
        done = _sweep(["run", str(scene), "--t-end", "0.05", "--out", "busy.mcap", "--quiet",
                       "--overwrite"], tmp_path)
        assert done.returncode == 2, done.stdout + done.stderr
        assert "busy.mcap: another run is writing it right now" in done.stderr
        assert "completed" not in done.stdout
    finally:
        proc.send_signal(2)
        out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert main(["analyze", str(tmp_path / "busy.mcap"), "--no-plots", "--quiet"]) == 0


def test_summary_json_is_strict_and_png_path_is_what_was_written(tmp_path, capsys):
    """Before: a one-agent run wrote "min_gap_m": Infinity; `sweep map --png /tmp` wrote
    /tmp.png and printed /tmp."""
    one = tmp_path / "one.yaml"
    one.write_text("agents: {positions: [[0, 0]], radius: 0.2}\n")
    assert main(["run", str(one), "--t-end", "0.05", "--out", str(tmp_path / "one.mcap"),
                 "--quiet"]) == 0

    def refuse(const: str) -> None:
        raise ValueError(f"not JSON: {const}")

    summary = json.loads((tmp_path / "one.summary.json").read_text(), parse_constant=refuse)
    assert summary["min_gap_m"] is None
    capsys.readouterr()
    (tmp_path / "m.pgm").write_bytes(b"P5 4 4 255\n" + bytes([254] * 16))
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.5\norigin: [0, 0, 0]\n")
    folder = tmp_path / "pics"
    folder.mkdir()
    assert main(["map", str(tmp_path / "m.yaml"), "--png", str(folder)]) == 2
    assert f"{folder}: exists and is a folder" in capsys.readouterr().err
    assert not Path(str(folder) + ".png").exists()
    bare = tmp_path / "walls"  # no .png suffix: written as named
    assert main(["map", str(tmp_path / "m.yaml"), "--png", str(bare)]) == 0
    printed = [ln.split()[-1] for ln in capsys.readouterr().out.splitlines()
               if ln.startswith("png")]
    assert printed == [str(bare)] and bare.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.fixture
def full_disk(tmp_path):
    """A 256 KiB tmpfs (root only; skipped where mounting is not permitted)."""
    d = tmp_path / "small"
    d.mkdir()
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(d)],
                          capture_output=True)
    if done.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here")
    yield d
    subprocess.run(["umount", "-l", str(d)], check=False)


def test_analyze_on_a_full_disk_is_one_line_and_leaves_no_partial_file(run_file, full_disk,
                                                                        tmp_path):
    """Before: an OSError traceback and 0-byte CSVs."""
    copy = full_disk / "run.mcap"
    copy.write_bytes(run_file.read_bytes())
    fd = os.open(full_disk / "filler", os.O_WRONLY | os.O_CREAT)
    try:  # fill the rest, unbuffered
        while True:
            os.write(fd, b"\0" * 4096)
    except OSError:
        pass
    finally:
        os.close(fd)
    done = _sweep(["analyze", str(copy), "--quiet"], tmp_path, timeout=300)
    assert done.returncode == 2, done.stdout + done.stderr
    err = done.stderr.strip().splitlines()
    assert "Traceback" not in done.stderr and "No space left on device" in err[-1], err
    assert [p.name for p in full_disk.iterdir() if p.suffix in (".csv", ".png")] == []
    assert not list(full_disk.glob(".*partial"))


# -- foreign recordings ---------------------------------------------------------------------


def test_a_recording_never_makes_replay_read_a_local_path(tmp_path, run_file, capsys):
    """Before: a recorded scene naming a map file made replay read that path (/dev/zero:
    4.7 GB then MemoryError; a FIFO: a hang)."""
    fifo = _fifo(tmp_path, "map.yaml")
    tampered = tmp_path / "tampered.mcap"

    def scene_with_map(name: str, md: dict) -> dict:
        if name == "sweep_ros":
            md = {**md, "scene": dump_json({**scene_data(md["scene"]),
                                            "map": {"yaml": str(fifo)}})}
        return md

    _rewrite(run_file, tampered, metadata=scene_with_map)
    done = _sweep(["replay", str(tampered), "--quiet"], tmp_path, timeout=120)
    assert done.returncode == 2, done.stdout + done.stderr
    err = _error_line(done.stderr)
    assert "map.yaml: names a map file" in err and "never read" in err, err
    # analyze reads the poses without the scene
    done = _cli(["analyze", str(tampered), "--no-plots", "--quiet", "--json"], capsys)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["frames"] == 101


def test_map_files_must_be_bounded_regular_files_and_are_never_quoted(tmp_path, capsys):
    """Before: a map error echoed the first line of the file it was pointed at; a /dev/zero
    or FIFO image read 4.7 GB then raised MemoryError, or hung."""
    secret = tmp_path / "secret.txt"
    secret.write_text(SECRET + "\nmore: [1, 2\n")
    assert main(["map", str(secret)]) == 2
    err = capsys.readouterr().err
    assert "secret.txt" in err and SECRET not in err and "SECRET" not in err, err
    secret.write_text(SECRET + "\n")  # a mapping of a key that is not a map_server key
    assert main(["map", str(secret)]) == 2
    err = capsys.readouterr().err
    assert "has 1 key(s) a map_server YAML file does not have" in err and "SECRET" not in err
    secret.write_text("root:x:0:0:SECRET:/root:/bin/bash\n")  # like /etc/passwd: a string
    assert main(["map", str(secret)]) == 2
    err = capsys.readouterr().err
    assert "is not a map_server YAML file" in err and "SECRET" not in err, err
    fifo = _fifo(tmp_path, "image.pgm")
    dev = _device(tmp_path)
    for image, kind in ((fifo, "a FIFO (named pipe)"), (dev, "a character device")):
        m = tmp_path / f"m_{image.name}.yaml"
        m.write_text(f"image: {image}\nresolution: 0.5\norigin: [0, 0, 0]\n")
        done = (_sweep(["map", str(m)], tmp_path, timeout=60) if image == fifo
                else _cli(["map", str(m)], capsys))
        assert done.returncode == 2, done.stdout + done.stderr
        assert f"is {kind}, not a regular file" in done.stderr, done.stderr
    huge = tmp_path / "huge.pgm"
    with open(huge, "wb") as f:
        f.truncate(200 << 20)  # sparse: 200 MB of zeros
    m = tmp_path / "huge.yaml"
    m.write_text(f"image: {huge}\nresolution: 0.5\norigin: [0, 0, 0]\n")
    assert main(["map", str(m)]) == 2
    assert "more than the limit of" in capsys.readouterr().err


def _one_line_each(stderr: str, expect: list[str]) -> None:
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert "Traceback" not in stderr
    for text in expect:
        assert any(text in ln for ln in lines), (text, lines)


def test_a_corrupt_poses_message_is_named_and_skipped(tmp_path, run_file, capsys):
    """Before: one garbled /poses message gave a traceback from analyze, replay and compare
    (ValueError: data: geometry_msgs/msg/PoseArray is truncated ...)."""
    bad = tmp_path / "bad.mcap"
    _rewrite(run_file, bad, data=lambda t, i, d: d[:30] if t == "/poses" and i == 7 else d)
    where = "topic /poses message 7 (sequence 8, t = 0.07 s) in the chunk at byte"
    done = _cli(["analyze", str(bad), "--no-plots", "--quiet", "--json"], capsys)
    assert done.returncode == 0, done.stderr
    _one_line_each(done.stderr, [where])
    summary = json.loads(done.stdout)
    assert summary["frames"] == 100 and summary["skipped_messages"] == 1
    done = _cli(["replay", str(bad), "--quiet"], capsys)
    assert done.returncode == 0, done.stdout + done.stderr
    _one_line_each(done.stderr, [where])
    assert "IDENTICAL on the 100 frames read; 1 recorded states were not compared" \
        in done.stdout, done.stdout
    done = _cli(["compare", str(run_file), str(bad), "--no-plots", "--quiet"], capsys)
    assert done.returncode == 0, done.stderr
    _one_line_each(done.stderr, [where])
    assert "common times       100" in done.stdout


def test_a_foreign_encoding_on_poses_is_one_line(tmp_path, run_file, capsys):
    """Before: JSON on /poses gave a traceback."""
    foreign = tmp_path / "foreign.mcap"
    _rewrite(run_file, foreign, data=lambda t, i, d: b'{"poses": []}' if t == "/poses" else d,
             encoding=lambda t: "json" if t == "/poses" else "cdr")
    for cmd in ("analyze", "replay"):
        done = _cli([cmd, str(foreign), "--quiet"], capsys)
        assert done.returncode == 2, done.stdout + done.stderr
        assert "topic /poses is recorded in the 'json' encoding, not cdr" in \
            _error_line(done.stderr)


def test_missing_poses_messages_are_reported_as_a_gap(tmp_path, run_file, capsys):
    """Before: a recording with 50 /poses messages removed replayed IDENTICAL with no word of
    the gap."""
    holed = tmp_path / "holed.mcap"
    _rewrite(run_file, holed, keep=lambda t, i: not (t in ("/poses", "/agents")
                                                      and 20 <= i < 70))
    done = _cli(["analyze", str(holed), "--no-plots", "--quiet", "--json"], capsys)
    assert done.returncode == 0, done.stderr
    gaps = json.loads(done.stdout)["gaps"]
    assert gaps["missing_messages"] == 50 and gaps["gaps"] == [[0, 19, 70, 50]]
    _one_line_each(done.stderr, ["50 /poses messages missing between the recorded steps 19 "
                                 "and 70"])
    done = _cli(["replay", str(holed), "--quiet"], capsys)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "50 recorded states were not compared (50 missing from the file" in done.stdout
    assert "not compared       50 states between the recorded steps 19 and 70" in done.stdout
