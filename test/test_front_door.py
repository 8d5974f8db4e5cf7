"""The command's front door: its help is fast to get (it imports none of the engine), complete
(every option says what it does), plain text (no RST markup), and it tells its version."""
from __future__ import annotations

import argparse
import re
import subprocess
import sys
from pathlib import Path

import pytest

from sweep_core.cli import build_parser, main
from sweep_core.version import __version__

REPO = Path(__file__).resolve().parents[1]


def _parsers(parser: argparse.ArgumentParser, path: tuple[str, ...] = ("sweep",)):
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, (*path, name))


def test_version_is_the_package_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"sweep {__version__}"
    assert f'version="{__version__}"' in (REPO / "setup.py").read_text()
    assert f"<version>{__version__}</version>" in (REPO / "package.xml").read_text()


def test_help_imports_none_of_the_engine() -> None:
    """``sweep --help`` lists every command from their one-line helps alone: numpy, numba and
    the engine's modules are not imported (they take about a second)."""
    code = ("import sys\nfrom sweep_core.cli import main\ntry:\n    main(['--help'])\n"
            "except SystemExit:\n    pass\n"
            "print('LOADED', sorted(m for m in sys.modules if m.split('.')[0] in "
            "('numpy', 'numba', 'scipy', 'matplotlib') or m.startswith('sweep_core.model') "
            "or m.startswith('sweep_core.numerics')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=REPO, check=True).stdout
    assert "LOADED []" in out, out.splitlines()[-1]
    for name in ("run", "scenes", "analyze", "replay", "compare", "render", "export"):
        assert re.search(rf"^\s+{name}\s+\S", out, re.M), name


def test_every_option_has_help_in_plain_text() -> None:
    missing, markup = [], []
    for path, parser in _parsers(build_parser()):
        if parser.description and "``" in parser.description:
            markup.append(" ".join(path))
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            if not action.help:
                missing.append(f"{' '.join(path)} {action.option_strings or action.dest}")
            elif "``" in action.help:
                markup.append(f"{' '.join(path)} {action.dest}")
    assert not missing, missing
    assert not markup, markup


def test_a_command_gets_its_own_options_alone(capsys: pytest.CaptureFixture[str]) -> None:
    """``sweep replay --help`` registers replay's module only; its options are all there."""
    with pytest.raises(SystemExit):
        main(["replay", "--help"])
    out = capsys.readouterr().out
    assert "usage: sweep replay" in out and "--json" in out


def test_bench_startup_times_each_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import csv

    out = tmp_path / "startup.csv"
    assert main(["bench", "startup", "--repeat", "1", "--csv", str(out)]) == 0
    rows = {r["command"]: r for r in csv.DictReader(out.open())}
    assert set(rows) == {"python -c pass", "sweep --help", "sweep --version", "sweep run --help"}
    assert float(rows["python -c pass"]["over_python"]) == 1.0
    assert all(float(r["median_s"]) > 0 for r in rows.values())
    assert "sweep --help" in capsys.readouterr().out


def test_run_never_replaces_a_recording_unasked(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    """A second sweep run on the same --out is refused in one line and leaves the first
    recording as it was; --overwrite replaces it; a missing folder is made."""
    import yaml

    scene = tmp_path / "s.yaml"
    scene.write_text(yaml.safe_dump({"agents": {"positions": [[1.0, 1.0], [2.0, 2.0]],
                                                "radius": 0.2}}))
    out = tmp_path / "tour" / "one.mcap"
    assert main(["run", str(scene), "--t-end", "0.05", "--out", str(out), "--quiet"]) == 0
    before = out.read_bytes()
    capsys.readouterr()
    assert main(["run", str(scene), "--t-end", "0.1", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{out}: exists" in err and "--overwrite" in err, err
    assert out.read_bytes() == before
    assert main(["run", str(scene), "--t-end", "0.1", "--out", str(out), "--quiet",
                 "--overwrite"]) == 0
    assert out.read_bytes() != before


def test_an_obstacle_centre_is_spelt_either_way() -> None:
    """``centre`` (the docs' spelling) and ``center`` give the same obstacle; both at once is
    a one-line error naming the obstacle."""
    from sweep_core.errors import SceneError
    from sweep_core.model.scene import Scene

    base = {"agents": {"positions": [[0.0, 0.0]], "radius": 0.2}}
    british = Scene.from_dict({**base, "obstacles": [
        {"kind": "circle", "centre": [2.0, 1.0], "radius": 0.5}]})
    american = Scene.from_dict({**base, "obstacles": [
        {"kind": "circle", "center": [2.0, 1.0], "radius": 0.5}]})
    assert british.geometry.circle_center.tolist() == american.geometry.circle_center.tolist()
    assert british.geometry.circle_center.tolist() == [[2.0, 1.0]]
    with pytest.raises(SceneError, match=r"obstacles\[0\]: has both centre and center"):
        Scene.from_dict({**base, "obstacles": [
            {"kind": "circle", "centre": [2.0, 1.0], "center": [2.0, 1.0], "radius": 0.5}]})
