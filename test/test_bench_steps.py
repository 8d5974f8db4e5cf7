"""``sweep bench speed --scenes steps``: ORCA built on the same scene, the rows' arithmetic,
and its options refused before anything is measured."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sweep_core.bench import steps
from sweep_core.cli import main
from sweep_core.model.scene import load_scene


def test_walls_become_segments() -> None:
    """robot_crowd's closed polyline of 5 points is 4 segments; crowdnav's two walls 2."""
    segs = steps._segments(load_scene("robot_crowd"))
    assert segs == [((0.0, 0.0), (16.0, 0.0)), ((16.0, 0.0), (16.0, 10.0)),
                    ((16.0, 10.0), (0.0, 10.0)), ((0.0, 10.0), (0.0, 0.0))]
    assert len(steps._segments(load_scene("crowdnav"))) == 2


def test_orca_has_the_scenes_agents_and_walks_to_the_goal() -> None:
    pytest.importorskip("pyrvo", reason="pyrvo (requirements-dev.txt) is the ORCA column")
    scene = load_scene("crowdnav")
    orca = steps.Orca(scene, 0.1)
    assert orca.n == scene.n_agents + 1  # ten people and the robot
    q0 = np.array([orca.sim.get_agent_position(i).to_tuple() for i in range(orca.n)])
    np.testing.assert_allclose(q0[:-1], scene.positions)
    for _ in range(5):
        orca.step()
    q1 = np.array([orca.sim.get_agent_position(i).to_tuple() for i in range(orca.n)])
    # the people head west to (-1, 3), the robot east to its goal (11, 3)
    assert (q1[:-1, 0] < q0[:-1, 0]).all()
    assert q1[-1, 0] > q0[-1, 0]


def test_engine_row_is_a_ratio_of_medians() -> None:
    pytest.importorskip("pyrvo", reason="pyrvo (requirements-dev.txt) is the ORCA column")
    row = steps.engine_vs_orca("crowdnav", steps=3)
    assert row["agents"] == 11
    assert row["sweep_median_ms"] > 0 and row["other_median_ms"] > 0
    assert math.isclose(row["ratio"], row["sweep_median_ms"] / row["other_median_ms"])
    assert row["sweep_cpu_median_ms"] > 0 and "CPU time" in row["note"]


@pytest.mark.parametrize(("option", "value"), [("--run-steps", "0"), ("--run-steps", "-1"),
                                               ("--run-steps", "1000000000"),
                                               ("--env-steps", "0"),
                                               ("--env-steps", "10000000000000"),
                                               ("--num-envs", "0"),
                                               ("--num-envs", "100000"),
                                               ("--env-workers", "0"),
                                               ("--env-workers", "33")])
def test_steps_options_refused(capsys: pytest.CaptureFixture[str], tmp_path: object,
                               option: str, value: str) -> None:
    csv = tmp_path / "steps.csv"  # type: ignore[operator]
    rc = main(["bench", "speed", "--scenes", "steps", option, value, "--csv", str(csv)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err.startswith("sweep: error: ") and "\n" not in err, err
    assert option in err and value in err, err
    assert not csv.exists()


@pytest.mark.parametrize(("given", "workers"), [([], 1), (["--env-workers", "1"], 1)])
def test_one_environment_runs_without_the_workers_row(monkeypatch, tmp_path, given,
                                                      workers) -> None:
    """--num-envs 1 is not refused for the default --env-workers (2): that default is at
    most --num-envs, and 1 makes no workers row."""
    row = {"measure": "m", "scene": "s"}
    monkeypatch.setattr(steps, "engine_vs_orca", lambda name: row)
    monkeypatch.setattr(steps, "recorded_vs_engine", lambda name, n: row)
    monkeypatch.setattr(steps.kernels, "warm_up", lambda say: None)
    asked = []
    monkeypatch.setattr(steps, "env_rates", lambda n, k, w: asked.append((n, k, w)) or [])
    csv = tmp_path / "steps.csv"
    assert main(["bench", "speed", "--scenes", "steps", "--num-envs", "1", *given,
                 "--csv", str(csv)]) == 0
    assert asked == [(2000, 1, workers)]


def test_recorded_row_pairs_each_recorded_step_with_an_engine_step() -> None:
    row = steps.recorded_vs_engine("crowdnav", 4)
    assert row["note"].startswith("steps 21-24,")  # four recorded steps measured
    assert row["sweep_median_ms"] > 0 and row["other_median_ms"] > 0
    assert math.isclose(row["ratio"], row["sweep_median_ms"] / row["other_median_ms"])


def test_the_single_environments_rate_resets_it_at_the_end_of_an_episode(monkeypatch):
    """Stepping an ended episode is not stepping the environment: env_rates resets the single
    environment when an episode ends (every 7 steps here) and the vectorised one resets its
    own environments."""
    import sweep_core.envs as envs

    class Episodes:
        action_space = type("Box", (), {"shape": (2,)})()

        def __init__(self) -> None:
            self.resets, self.t = 0, 0

        def reset(self, seed=None):
            self.resets, self.t = self.resets + 1, 0
            return {}, {}

        def step(self, action):
            assert self.t < 7, "stepped an ended episode"
            self.t += 1
            return {}, 0.0, self.t == 7, False, {}

        def close(self) -> None:
            pass

    env = Episodes()
    monkeypatch.setattr(envs, "make_single", lambda: env)
    monkeypatch.setattr(envs, "has_vector", lambda: False)
    rows = steps.env_rates(70, 5)
    assert len(rows) == 1 and np.isfinite(rows[0]["sweep_median_ms"])
    # per seed: its reset, then 10 + 14 steps, reset after every 7th
    assert env.resets == 5 * (1 + (10 + 14 - 1) // 7)
    assert "over 70 env steps" in rows[0]["note"]


def test_the_single_environment_steps_the_vectorised_rows_episodes(monkeypatch):
    """The single row times the steps the vectorised rows time: seeds 0 .. K - 1 in turn, 10
    untimed and steps // K timed steps each."""
    import sweep_core.envs as envs

    calls: list = []

    class Single:
        action_space = type("Box", (), {"shape": (2,)})()

        def reset(self, seed=None):
            calls.append(("reset", seed))
            return {}, {}

        def step(self, action):
            calls.append(("step", float(action[0])))
            return {}, 0.0, False, False, {}

        def close(self) -> None:
            pass

    monkeypatch.setattr(envs, "make_single", lambda: Single())
    monkeypatch.setattr(envs, "has_vector", lambda: False)
    steps.env_rates(9, 3)
    assert calls == [c for seed in range(3)
                     for c in [("reset", seed)] + [("step", 0.8)] * 13]


def test_the_workers_row_steps_the_vector_environment_in_workers(monkeypatch):
    """With workers > 1 a third row times the vector environment made with those workers (its
    note says the workers' CPU time is not counted); with 1, no such row."""
    import sweep_core.envs as envs

    made = []

    class Batch:
        action_space = type("Box", (), {"shape": (4, 2)})()

        def reset(self, seed=None):
            return {}, {}

        def step(self, action):
            return {}, np.zeros(4), np.zeros(4, bool), np.zeros(4, bool), {}

        def close(self) -> None:
            pass

    def make_vector(num_envs, **kwargs):
        made.append((num_envs, kwargs))
        return Batch()

    class Single(Batch):
        def step(self, action):
            return {}, 0.0, False, False, {}

    monkeypatch.setattr(envs, "make_single", lambda: Single())
    monkeypatch.setattr(envs, "has_vector", lambda: True)
    monkeypatch.setattr(envs, "make_vector", make_vector)
    rows = steps.env_rates(8, 4, workers=2)
    assert [r["measure"] for r in rows] == ["env steps/s, single", "env steps/s, K=4",
                                            "env steps/s, K=4/2"]
    assert made == [(4, {}), (4, {"workers": 2})]
    assert "2 worker processes" in rows[2]["note"] and "CPU time:" in rows[1]["note"]
    assert len(steps.env_rates(8, 4, workers=1)) == 2


@pytest.mark.parametrize("option, value", [("--num-envs", "64"), ("--env-workers", "2"),
                                           ("--run-steps", "200"), ("--env-steps", "10")])
def test_a_steps_option_without_the_steps_scenes_is_refused(
        capsys: pytest.CaptureFixture[str], tmp_path, option: str, value: str) -> None:
    """--scenes hex --num-envs 64 would measure no environment and say nothing of it."""
    csv = tmp_path / "speed.csv"
    rc = main(["bench", "speed", "--scenes", "hex", "--sizes", "100", option, value,
               "--csv", str(csv)])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and err == (f"sweep: error: {option}: is an option of --scenes steps, "
                               "which is not among --scenes hex (fix: add steps to --scenes, "
                               f"or leave {option} out)"), err
    assert not csv.exists()


@pytest.mark.parametrize("memory, option, problem", [
    # half of 8 GB holds the 1024 environments (about 0.9 GB), not 1024 workers (16 MB each)
    (8 * 10 ** 9, "--env-workers", "1024 worker processes need about"),
    # half of 1 GB does not hold the 1024 environments
    (10 ** 9, "--num-envs", "1024 environments need about")])
def test_the_environments_memory_is_refused_before_any_row_runs(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path,
        memory: int, option: str, problem: str) -> None:
    """The vector environment refuses K environments or W workers the available memory does
    not hold when it is built, after the engine rows (minutes): the bench asks it first."""
    pytest.importorskip("gymnasium")
    from sweep_core.envs import vector

    monkeypatch.setattr(vector, "available_memory", lambda: memory)
    ran = []

    def row(name: str, *_: object) -> dict:
        ran.append(name)
        return {"measure": "engine step", "scene": name}

    monkeypatch.setattr(steps, "engine_vs_orca", row)
    monkeypatch.setattr(steps, "recorded_vs_engine", row)
    csv = tmp_path / "steps.csv"
    rc = main(["bench", "speed", "--scenes", "steps", "--num-envs", "1024", "--env-workers",
               "1024", "--env-steps", "1024", "--csv", str(csv)])
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert rc == 2 and "\n" not in err, err
    assert err.startswith(f"sweep: error: {option}: {problem}"), err
    assert f"(fix: {option} " in err and "max_steps" not in err.split("(fix:")[1], err
    assert ran == [] and "engine step" not in captured.out and not csv.exists()
