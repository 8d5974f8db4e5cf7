"""Options of `sweep run` and `sweep bench social` refused in one line naming the option,
before any run starts, with a fix that can be followed."""
from __future__ import annotations

import copy
from pathlib import Path

import pytest
from robot_scenes import small_scene

from sweep_core.cli import main
from sweep_core.model.yaml_files import dump_yaml


def _refused(capsys: pytest.CaptureFixture[str], args: list[str]) -> str:
    rc = main(args)
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert rc == 2 and err.startswith("sweep: error: ") and "\n" not in err, err
    assert "runs on" not in captured.out, captured.out
    return err


@pytest.mark.parametrize("extra, option, words", [
    (["--scenes", "crowdnav", "crowdnav"], "--scenes", ["'crowdnav' twice", "once"]),
    (["--controllers", "orca", "orca"], "--controllers", ["'orca' twice", "once"]),
    (["--seed", "-5"], "--seed", [">= 0", "-5", "--seed 0"]),
])
def test_bench_social_options_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                      extra: list[str], option: str, words: list[str]) -> None:
    err = _refused(capsys, ["bench", "social", "--seeds", "2", "--t-end", "0.3",
                            "--out", str(tmp_path / "out"), *extra])
    assert err.startswith(f"sweep: error: {option}: "), err
    for word in words:
        assert word in err, err


def test_bench_social_refuses_a_scene_whose_robot_has_no_goal(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    data = copy.deepcopy(small_scene())
    del data["robots"][0]["goal"]
    scene = tmp_path / "nogoal.yaml"
    scene.write_text(dump_yaml(data))
    err = _refused(capsys, ["bench", "social", "--scenes", str(scene), "--seeds", "1",
                            "--t-end", "0.1", "--out", str(tmp_path / "out")])
    assert err.startswith("sweep: error: --scenes: robots[0] of "), err
    assert "no goal" in err and "controller: none" not in err, err


def test_sweep_run_refuses_a_negative_seed(capsys: pytest.CaptureFixture[str],
                                           tmp_path: Path) -> None:
    err = _refused(capsys, ["run", "robot_crowd", "--t-end", "0.1", "--seed", "-5",
                            "--out", str(tmp_path / "r.mcap")])
    assert err.startswith("sweep: error: --seed: ") and "--seed 0" in err, err


def test_sweep_run_too_long_suggests_a_t_end_that_fits(capsys: pytest.CaptureFixture[str],
                                                        tmp_path: Path) -> None:
    err = _refused(capsys, ["run", "robot_crowd", "--t-end", "1e300",
                            "--out", str(tmp_path / "r.mcap")])
    assert "--t-end" in err and "larger --dt" not in err and "1e+06 s" in err, err


@pytest.mark.parametrize("rate", ["1e-300", "1e-9", "-1"])
def test_live_rate_refused_before_serving(capsys: pytest.CaptureFixture[str], tmp_path: Path,
                                          rate: str) -> None:
    out = tmp_path / "r.mcap"
    err = _refused(capsys, ["run", "crowdnav", "--t-end", "0.05", "--out", str(out), "--quiet",
                            "--live", "0", "--live-rate", rate])
    assert err.startswith("sweep: error: --live-rate: ") and "0.001" in err, err
    assert not out.exists()
    assert main(["run", "crowdnav", "--t-end", "0.05", "--out", str(out), "--quiet"]) == 0
    capsys.readouterr()
    err = _refused(capsys, ["replay", str(out), "--quiet", "--live", "0", "--live-rate", rate])
    assert err.startswith("sweep: error: --live-rate: ") and "0.001" in err, err


def test_bench_social_refuses_more_workers_than_the_machine_holds(
        capsys: pytest.CaptureFixture[str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    from sweep_core.bench import social

    def no_pool(max_workers: int) -> None:  # the pool would fork them all at once
        raise AssertionError(f"a pool of {max_workers} processes was started")

    monkeypatch.setattr(social, "ProcessPoolExecutor", no_pool)
    err = _refused(capsys, ["bench", "social", "--seeds", "1", "--t-end", "0.1",
                            "--workers", "100000", "--out", str(tmp_path / "out")])
    assert err.startswith("sweep: error: --workers: 100000 is more than "), err
    assert "per core" in err and not (tmp_path / "out").exists()


def test_bench_social_starts_no_more_processes_than_runs(
        capsys: pytest.CaptureFixture[str], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch) -> None:
    from sweep_core.bench import social

    def no_pool(max_workers: int) -> None:
        raise AssertionError(f"a pool of {max_workers} processes was started")

    monkeypatch.setattr(social, "ProcessPoolExecutor", no_pool)
    assert main(["bench", "social", "--seeds", "1", "--scenes", "crowdnav", "--controllers",
                 "pursuit", "--t-end", "0.05", "--workers", "8",
                 "--out", str(tmp_path / "out")]) == 0
    assert "1 runs on 1 processes" in capsys.readouterr().out


def test_bench_social_refuses_an_empty_out_naming_it(capsys: pytest.CaptureFixture[str],
                                                      tmp_path: Path) -> None:
    err = _refused(capsys, ["bench", "social", "--seeds", "1", "--t-end", "0.1",
                            "--out", ""])
    assert err.startswith("sweep: error: '': is an empty path"), err
    assert "(fix: --out OTHERDIR, a folder's path)" in err, err


def test_bench_social_out_refusal_names_another_folder(capsys: pytest.CaptureFixture[str],
                                                       tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    err = _refused(capsys, ["bench", "social", "--seeds", "1", "--t-end", "0.1",
                            "--out", str(blocker / "sub")])
    assert "cannot be made as a folder" in err and err.endswith("(fix: --out OTHERDIR)"), err


def test_bench_social_refuses_a_t_end_shorter_than_a_step(capsys: pytest.CaptureFixture[str],
                                                          tmp_path: Path) -> None:
    err = _refused(capsys, ["bench", "social", "--seeds", "1", "--t-end", "0.001",
                            "--dt", "0.01", "--out", str(tmp_path / "out")])
    assert err.startswith("sweep: error: --t-end: 0.001 s at dt = 0.01 s is no step"), err
    assert "(fix: --t-end 0.01 or more)" in err and not (tmp_path / "out").exists(), err


def test_bench_social_refuses_a_dt_too_long_for_a_robot_before_any_run(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """crowdnav's robot (radius 0.3 m, 1 m/s) would cover its radius in a step of 0.5 s: refused
    naming --dt and the scene before any run starts or the folder is made."""
    err = _refused(capsys, ["bench", "social", "--scenes", "crowdnav", "--controllers",
                            "pursuit", "--seeds", "1", "--workers", "1", "--t-end", "2",
                            "--dt", "0.5", "--out", str(tmp_path / "out")])
    assert err.startswith("sweep: error: --dt: 0.5 s is too long for 'crowdnav'"), err
    assert "--dt below 0.3" in err and not (tmp_path / "out").exists()


@pytest.mark.parametrize("t_end", ["0.001", "0.005", "0"])
def test_sweep_run_refuses_a_t_end_shorter_than_half_a_step(capsys: pytest.CaptureFixture[str],
                                                            tmp_path: Path, t_end: str) -> None:
    """round(t_end / dt) steps: none below half a step; refused before anything is written."""
    out = tmp_path / "r.mcap"
    err = _refused(capsys, ["run", "crowdnav", "--t-end", t_end, "--dt", "0.01",
                            "--out", str(out), "--quiet"])
    assert err.startswith(f"sweep: error: --t-end: {float(t_end):g} s at dt = 0.01 s is no "
                          "step: the recording would hold the start only"), err
    assert err.endswith("(fix: --t-end 0.01 or more)"), err
    assert list(tmp_path.iterdir()) == []


def test_sweep_run_refuses_a_horizon_shorter_than_half_a_step(capsys: pytest.CaptureFixture[str],
                                                              tmp_path: Path) -> None:
    """Without --t-end a robot scene runs to its horizon: one shorter than half a step is
    refused naming --t-end and saying the horizon was its value."""
    data = copy.deepcopy(small_scene())
    data["horizon"] = 0.002
    data["robots"][0]["controller"] = "pursuit"
    scene = tmp_path / "short.yaml"
    scene.write_text(dump_yaml(data))
    out = tmp_path / "r.mcap"
    err = _refused(capsys, ["run", str(scene), "--out", str(out), "--quiet"])
    assert err.startswith("sweep: error: --t-end: 0.002 s at dt = 0.01 s is no step: "), err
    assert "the scene's horizon, 0.002 s" in err and "(fix: --t-end 0.01 or more)" in err, err
    assert not out.exists()


@pytest.mark.parametrize("command", ["analyze", "replay"])
def test_a_missing_recording_is_refused_before_the_kernels_are_compiled(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        command: str) -> None:
    """A recording that cannot be opened is said at once, in one line, exit 2: not after
    compiling the engine's kernels (minutes on a machine's first run)."""
    from sweep_core.numerics import kernels

    warmed: list[bool] = []
    monkeypatch.setattr(kernels, "warm_up", lambda *a, **k: warmed.append(True))
    missing = tmp_path / "missing.mcap"
    assert main([command, str(missing), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(missing) in err[0] and "cannot open" in err[0]
    assert warmed == []


@pytest.mark.parametrize("study", [["accuracy", "--quick", "--problems", "rbm_wall", "--out"],
                                   ["walking", "--agents", "2", "--t-end", "2", "--csv"]])
def test_bench_seed_below_zero_refused_naming_the_option(capsys: pytest.CaptureFixture[str],
                                                         tmp_path: Path,
                                                         study: list[str]) -> None:
    """`sweep bench accuracy` and `walking` refuse a negative --seed in one line naming the
    option, before any run (numpy's generators take seeds >= 0 only)."""
    err = _refused(capsys, ["bench", *study, str(tmp_path / "b"), "--seed", "-1"])
    assert err.startswith("sweep: error: --seed: ") and ">= 0" in err and "-1" in err, err
    assert "--seed 0" in err, err
    assert not (tmp_path / "b").exists()


def test_bench_accuracy_out_that_is_a_file_refused_before_the_study(
        capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    """--out names the folder of the CSVs and plots: a file there is refused in one line
    before any problem runs (not a traceback from mkdir after the study)."""
    taken = tmp_path / "taken"
    taken.write_text("mine\n")
    err = _refused(capsys, ["bench", "accuracy", "--quick", "--problems", "moving_wall",
                            "--out", str(taken)])
    assert err.startswith(f"sweep: error: {taken}: exists and is a regular file"), err
    assert "--out OTHERDIR" in err, err
    assert taken.read_text() == "mine\n"
