"""Hostile options of the commands and APIs the scene and recording probes leave out:
`sweep ensemble`, `sweep bench`, the gymnasium environment, and scene names too long for the
file system (the node's `scene` parameter, `sweep run`). Each is refused with one line naming
the option, the value and the fix (exit status 2 on the command line) before any work starts:
no traceback, no hang, no file written."""
from __future__ import annotations

import numpy as np
import pytest
from robot_scenes import small_scene

from sweep_core.cli import main
from sweep_core.errors import SceneError
from sweep_core.model.gallery import resolve_scene_path


def refused(capsys: pytest.CaptureFixture[str], argv: list[str], *words: str) -> str:
    """Runs ``sweep ARGV``; asserts exit status 2 and one error line holding ``words``."""
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert err.startswith("sweep: error: ") and "\n" not in err, err
    for word in words:
        assert word in err, err
    return err


# -- sweep ensemble ------------------------------------------------------------------------

@pytest.fixture
def no_cluster(monkeypatch: pytest.MonkeyPatch) -> None:
    """An ensemble that gets as far as compiling kernels or starting a cluster fails the test
    at once (instead of running, or hanging, on options it should have refused)."""
    from sweep_core.ensemble import cluster
    from sweep_core.numerics import kernels

    def started(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("the ensemble started instead of refusing its options")

    monkeypatch.setattr(cluster, "connect", started)
    monkeypatch.setattr(kernels, "warm_up", started)


@pytest.mark.parametrize("options, words", [
    # 1e5 runs of bookkeeping is the limit; above it the command built task lists for ever
    (["--runs", "100001"], ["--runs", "100001", "100000"]),
    (["--runs", "40000", "--vary", "noise.sigma=0.1,0.2,0.3"], ["120000 runs", "--runs 33333"]),
    # runs.parquet holds seeds as int64: a larger seed failed after every run had finished
    (["--runs", "2", "--seed0", str(2**64)], ["--seed0", str(2**64), "2^63 - 1"]),
    # the time steps sweep run accepts, and at most its step count per run
    (["--runs", "1", "--dt", "1e-9"], ["--dt", "1e-09", "[1e-05, 1]"]),
    (["--runs", "1", "--vary", "dt=0.01,5"], ["--vary dt", "5 s"]),
    (["--runs", "1", "--t-end", "1e12"], ["--t-end", "1e+14 steps", "at most 10000 s"]),
    (["--runs", "1", "--t-end", "100", "--vary", "dt=0.01,1e-5"],
     ["--vary dt", "1e+07 steps", "at least 0.0001 s"]),
])
def test_ensemble_options_refused(capsys: pytest.CaptureFixture[str], tmp_path: object,
                                  no_cluster: None, options: list[str],
                                  words: list[str]) -> None:
    out = tmp_path / "out"  # type: ignore[operator]
    refused(capsys, ["ensemble", "--out", str(out), "--quiet", "--no-plots", *options], *words)
    assert not out.exists()  # refused before the output folder is made


# -- sweep bench -----------------------------------------------------------------------------

#: the cheapest speed study: 20 agents of the hexagonal jam, one measured step, no baselines
SPEED = ["bench", "speed", "--sizes", "20", "--scenes", "hex", "--no-baseline", "--steps", "1",
         "--warmup", "0", "--backend-qps", "0"]


@pytest.mark.parametrize("argv, words", [
    (["bench", "speed", "--sizes", "0"], ["--sizes", "got 0"]),
    (["bench", "speed", "--sizes", "-1"], ["--sizes", "got -1"]),
    (["bench", "speed", "--sizes", "1000000000"], ["--sizes", "1000000000", "limit"]),
    ([*SPEED, "--tols", "0"], ["--tols", "got 0"]),
    ([*SPEED, "--tols", "-1"], ["--tols", "got -1"]),
    ([*SPEED, "--tols", "nan"], ["--tols", "got nan"]),
    ([*SPEED, "--tols", "5"], ["--tols", "5 m", "[1e-12, 1]"]),
    ([*SPEED, "--timeout", "0"], ["--timeout", "got 0"]),
    ([*SPEED, "--backend-timeout", "-1"], ["--backend-timeout", "got -1"]),
    ([*SPEED[:-4], "--warmup", "-1", "--backend-qps", "0"], ["--warmup", "got -1"]),
    (["bench", "robots", "--sizes", "50", "--beams", "0"], ["--beams", "got 0"]),
    (["bench", "robots", "--sizes", "50", "--beams", "100000"], ["--beams", "20000"]),
    (["bench", "robots", "--sizes", "50", "--beams", "8", "--repeat", "0"], ["--repeat"]),
    (["bench", "recording", "--sizes", "10", "--steps", "0"], ["--steps", "got 0"]),
    (["bench", "recording", "--sizes", "10", "--steps", "2", "--block", "0"], ["--block"]),
])
def test_bench_options_refused(capsys: pytest.CaptureFixture[str], tmp_path: object,
                               argv: list[str], words: list[str]) -> None:
    csv = tmp_path / "bench.csv"  # type: ignore[operator]
    refused(capsys, [*argv, "--csv", str(csv)], *words)
    assert not csv.exists()


@pytest.mark.parametrize("study", [SPEED, ["bench", "robots", "--sizes", "50", "--beams", "8"],
                                   ["bench", "recording", "--sizes", "10", "--steps", "2"]])
def test_bench_csv_folder_refused_before_measuring(capsys: pytest.CaptureFixture[str],
                                                   tmp_path: object, study: list[str]) -> None:
    """A --csv that is a folder is refused before the study runs (it used to fail with
    IsADirectoryError after the whole measurement)."""
    err = refused(capsys, [*study, "--csv", str(tmp_path)], "is a folder", "--csv OTHER.csv")
    assert "per scan" not in capsys.readouterr().out  # nothing was measured
    assert str(tmp_path) in err


# -- scene names -----------------------------------------------------------------------------

def test_scene_name_too_long_for_the_file_system() -> None:
    """A name longer than a file name may be (ENAMETOOLONG) is refused naming the scene; it
    used to escape as an OSError quoting the whole name (sweep run, the node's parameter)."""
    with pytest.raises(SceneError, match=r"^scene: 'a+\.\.\.' \(5000 characters\) cannot"):
        resolve_scene_path("a" * 5000)
    params = pytest.importorskip("sweep_ros.params")
    problem = params.check_value("scene", "b" * 100_000)
    assert problem is not None and problem.startswith("scene: ") and len(problem) < 400


def test_sweep_run_scene_name_too_long(capsys: pytest.CaptureFixture[str], tmp_path: object
                                       ) -> None:
    out = tmp_path / "run.mcap"  # type: ignore[operator]
    err = refused(capsys, ["run", "c" * 5000, "--out", str(out)], "scene", "5000 characters")
    assert len(err) < 400 and not out.exists()


# -- the gymnasium environment -------------------------------------------------------------

@pytest.mark.parametrize("kwargs, field", [
    ({"dt": "abc"}, "dt"), ({"dt": 1e-9}, "dt"), ({"dt": 5.0}, "dt"),
    ({"max_steps": float("nan")}, "max_steps"), ({"max_steps": float("inf")}, "max_steps"),
    ({"max_steps": 1.5}, "max_steps"), ({"max_steps": "x"}, "max_steps"),
    ({"success_reward": float("nan")}, "success_reward"),
    ({"contact_penalty": float("inf")}, "contact_penalty"),
    ({"discomfort_penalty": "x"}, "discomfort_penalty"),
])
def test_env_arguments_refused(kwargs: dict, field: str) -> None:
    envs = pytest.importorskip("sweep_core.envs")
    with pytest.raises(SceneError) as err:
        envs.CrowdNavEnv(small_scene(), **kwargs)
    assert err.value.field == field


@pytest.fixture(scope="module")
def env() -> object:
    envs = pytest.importorskip("sweep_core.envs")
    env = envs.CrowdNavEnv(small_scene(), max_steps=5)
    env.reset(seed=0)
    return env


@pytest.mark.parametrize("action", ["ab", {"v": 1.0}, [1 + 1j, 0.0], np.zeros(10**6)])
def test_env_actions_refused(env: object, action: object) -> None:
    with pytest.raises(SceneError) as err:
        env.step(action)  # type: ignore[attr-defined]
    # one short line (a million numbers used to be printed in the message)
    assert err.value.field == "action" and len(str(err.value)) < 300
    # the refused action took no step: the episode goes on
    assert np.isfinite(env.step([0.5, 0.0])[1])  # type: ignore[attr-defined]


# -- the node's command messages -------------------------------------------------------------

def test_command_refusal_cuts_an_enormous_frame_id() -> None:
    """A goal, velocity or initial pose in a frame id of 1e5 characters is refused with a
    verdict of one short line (the whole frame id used to be quoted, twice for a map)."""
    pytest.importorskip("rclpy")
    from geometry_msgs.msg import PointStamped, PoseWithCovarianceStamped, TwistStamped

    from sweep_ros import messages, robot_messages

    huge = "x" * 100_000
    goal, twist, pose = PointStamped(), TwistStamped(), PoseWithCovarianceStamped()
    for msg in (goal, twist, pose):
        msg.header.frame_id = huge
    pose.pose.pose.orientation.w = 1.0
    for parse in (lambda: messages.goal_point(goal, "map"),
                  lambda: robot_messages.velocity_command(twist, True, "base_link", "bot/cmd_vel"),
                  lambda: robot_messages.initial_pose(pose, "map", "bot/initialpose")):
        with pytest.raises(messages.CommandError) as err:
            parse()
        assert "frame" in str(err.value) and len(str(err.value)) < 400, str(err.value)[:200]
