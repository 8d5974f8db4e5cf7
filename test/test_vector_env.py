"""The vectorised sweep/CrowdNav-v0 (``gymnasium.make_vec(..., vectorization_mode=
"vector_entry_point")``): Gymnasium's vector API contract, checked against Gymnasium's own
SyncVectorEnv of the single environment bit for bit (next-step autoreset included), each
environment's episode that of the single environment with the same seed, and its bad input
refused in one line naming the argument, the value and the fix."""
from __future__ import annotations

import os
import signal
import threading

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from robot_scenes import small_scene
from test_envs import same as same_plain

import sweep_core.envs  # noqa: F401  (registers sweep/CrowdNav-v0)
from sweep_core.envs import vector
from sweep_core.envs.vector import CrowdNavVectorEnv
from sweep_core.errors import SceneError, SweepError


def same(a: object, b: object) -> bool:
    """Bit for bit (test_envs.same), object arrays (infos' lists) element by element."""
    if isinstance(a, np.ndarray) and a.dtype == object:
        return (isinstance(b, np.ndarray) and b.dtype == object and a.shape == b.shape
                and all(same(x, y) for x, y in zip(a.tolist(), b.tolist())))
    if isinstance(a, dict):
        return isinstance(b, dict) and a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))  # type: ignore
    return same_plain(a, b)


KW = {"scene": small_scene(), "dt": 0.1, "max_steps": 4}


def actions(k: int, step: int) -> np.ndarray:
    """A fixed, deterministic batch of commands (v, omega), one row per environment."""
    return np.array([[0.8 - 0.1 * i, 0.3 * np.sin(step + i)] for i in range(k)])


def rollout(envs: gymnasium.vector.VectorEnv, seed, steps: int) -> list:
    out = list(envs.reset(seed=seed))
    for step in range(steps):
        out += list(envs.step(actions(envs.num_envs, step)))
    return out


def test_the_vector_entry_point_is_gymnasiums_sync_vector_env_bit_for_bit() -> None:
    vec = gymnasium.make_vec("sweep/CrowdNav-v0", num_envs=3,
                             vectorization_mode="vector_entry_point", **KW)
    sync = gymnasium.make_vec("sweep/CrowdNav-v0", num_envs=3, vectorization_mode="sync",
                              **KW)
    assert isinstance(vec.unwrapped, CrowdNavVectorEnv)
    assert vec.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert sync.metadata["autoreset_mode"] == AutoresetMode.NEXT_STEP
    assert vec.observation_space == sync.observation_space
    assert vec.action_space == sync.action_space
    assert vec.single_observation_space == sync.single_observation_space
    # 11 steps of episodes of 4: two autoresets in each environment
    ours, theirs = rollout(vec, 5, 11), rollout(sync, 5, 11)
    assert same(ours, theirs)
    ours, theirs = rollout(vec, [9, 2, 4], 6), rollout(sync, [9, 2, 4], 6)
    assert same(ours, theirs)
    obs = ours[0]
    assert vec.observation_space.contains(obs)
    # the step after a truncation is the autoreset: reward 0, not done, a first observation
    trunc = [ours[2 + 5 * s + 3] for s in range(6)]
    assert [bool(t.all()) for t in trunc] == [False, False, False, True, False, False]
    assert (ours[2 + 5 * 4 + 1] == 0).all() and not ours[2 + 5 * 4 + 2].any()
    np.testing.assert_array_equal(ours[2 + 5 * 4]["odom"][:, :3], [[0.5, 1.5, 0.0]] * 3)
    vec.close()
    sync.close()


def test_each_environment_is_the_single_environment_with_its_seed() -> None:
    vec = vector.make(num_envs=3, **KW)
    batch = rollout(vec, [11, 12, 13], 4)
    for i, seed in enumerate([11, 12, 13]):
        single = gymnasium.make("sweep/CrowdNav-v0", **KW)
        obs, _ = single.reset(seed=seed)
        assert same({k: v[i] for k, v in batch[0].items()}, obs)
        for step in range(4):
            obs, reward, term, trunc, _ = single.step(actions(3, step)[i])
            got = batch[2 + 5 * step: 2 + 5 * step + 4]
            assert same({k: v[i] for k, v in got[0].items()}, obs)
            assert repr(float(got[1][i])) == repr(reward)
            assert bool(got[2][i]) == term and bool(got[3][i]) == trunc
    # the seed matters
    other = rollout(vec, [11, 99, 13], 4)
    assert not same(other, batch)
    assert same(other[0]["odom"][0], batch[0]["odom"][0])


@pytest.mark.parametrize(("num_envs", "words"), [
    (0, ["num_envs", "got 0", "num_envs=32"]), (-1, ["num_envs", "got -1"]),
    (2.5, ["num_envs", "2.5"]), ("x", ["num_envs", "'x'"]), (True, ["num_envs", "got true"]),
    (10 ** 9, ["num_envs", "1000000000", "100000"])])
def test_bad_counts_are_refused(num_envs: object, words: list[str]) -> None:
    with pytest.raises(SceneError) as err:
        vector.make(num_envs=num_envs, **KW)
    text = str(err.value)
    assert "\n" not in text
    for word in words:
        assert word in text, text


def test_more_environments_than_the_memory_holds_are_refused_before_building_them(
        monkeypatch: pytest.MonkeyPatch) -> None:
    built = []
    monkeypatch.setattr(vector, "available_memory", lambda: 10 ** 8)  # 100 MB
    real = vector.CrowdNavEnv

    def counted(*args: object, **kwargs: object) -> object:
        built.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(vector, "CrowdNavEnv", counted)
    with pytest.raises(SceneError) as err:
        vector.make(num_envs=50_000, **KW)
    text = str(err.value)
    assert "num_envs" in text and "50000 environments need about" in text and "GB" in text
    assert "num_envs=" in text and "or fewer" in text
    assert len(built) == 2  # only the two measured (one-time costs, then one environment)


def test_more_workers_than_the_memory_holds_are_refused_before_starting_them(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Each worker process takes memory of its own (WORKER_BYTES) beside the environments:
    too many for the memory are refused naming workers, before any is started."""
    from sweep_core.envs import workers
    monkeypatch.setattr(vector, "available_memory", lambda: 10 ** 9)  # 1 GB
    monkeypatch.setattr(workers.Workers, "__init__", lambda *a: pytest.fail("started"))
    with pytest.raises(SceneError) as err:
        vector.make(num_envs=64, workers=64, **KW)
    text = str(err.value)
    assert "\n" not in text and text.startswith("workers: 64 worker processes need about"), text
    most = int(text.split("(fix: workers=")[1].split(" ")[0])
    assert 2 <= most < 64 and text.endswith(" or fewer)"), text


@pytest.fixture(scope="module")
def envs() -> CrowdNavVectorEnv:
    env = vector.make(num_envs=3, **KW)
    env.reset(seed=0)
    return env


@pytest.mark.parametrize(("batch", "words"), [
    (np.zeros((2, 2)), ["actions", "(3, 2)", "(2, 2)"]),
    (np.zeros(6), ["actions", "(3, 2)", "(6,)"]),
    (np.array([[0.1, 0.0], [np.nan, 0.0], [0.0, 0.0]]), ["actions[1]", "nan", "environment 1"]),
    (np.array([[0.1, 0.0], [0.0, 0.0], [0.0, np.inf]]), ["actions[2]", "inf"]),
    ("fast", ["actions", "fast"]),
    (np.zeros((3, 2)) + 0.5j, ["actions", "numbers of shape (3, 2)", "complex"])])
def test_bad_actions_are_refused_naming_the_environment(envs: CrowdNavVectorEnv,
                                                        batch: object,
                                                        words: list[str]) -> None:
    with pytest.raises(SceneError) as err:
        envs.step(batch)
    text = str(err.value)
    assert "\n" not in text
    for word in words:
        assert word in text, text


@pytest.mark.parametrize(("seed", "words"), [
    ([1, 2], ["seed", "has 2 seeds for 3 environments", "a list of 3"]),
    ([1, 2, 3, 4], ["seed", "has 4 seeds"]), ("abc", ["seed", "'abc'"]),
    ([1, -2, 3], ["seed[1]", "-2"])])
def test_bad_seeds_are_refused(envs: CrowdNavVectorEnv, seed: object, words: list[str]) -> None:
    with pytest.raises(SceneError) as err:
        envs.reset(seed=seed)  # type: ignore[arg-type]
    text = str(err.value)
    assert "\n" not in text
    for word in words:
        assert word in text, text


def test_workers_step_the_same_episodes_bit_for_bit() -> None:
    """Two worker processes (shares of 1 and 2 environments) against this process: the same
    observations, rewards, flags and infos, autoresets and seed lists included; closing ends
    the workers."""
    mine = vector.make(num_envs=3, **KW)
    split = vector.make(num_envs=3, workers=2, **KW)
    assert split.workers is not None and split.envs == []
    assert [len(s) for s in split.workers.shares] == [1, 2]
    assert same(rollout(split, 5, 11), rollout(mine, 5, 11))
    assert same(rollout(split, [9, 2, 4], 6), rollout(mine, [9, 2, 4], 6))
    procs = list(split.workers.procs)
    assert all(p.is_alive() for p in procs)
    split.close()
    assert not any(p.is_alive() for p in procs)
    mine.close()


def test_shares_are_contiguous_and_even() -> None:
    from sweep_core.envs.workers import shares
    for k in range(1, 12):
        for w in range(1, k + 1):
            got = shares(k, w)
            assert [i for s in got for i in s] == list(range(k))
            assert max(map(len, got)) - min(map(len, got)) <= 1


@pytest.mark.parametrize(("workers", "words"), [
    (0, ["workers", "got 0", "workers=2"]), (-1, ["workers", "-1"]), (1.5, ["workers", "1.5"]),
    ("two", ["workers", "'two'"]), (4, ["workers", "4 is more than the 3 environments",
                                        "workers=3 or fewer"])])
def test_bad_worker_counts_are_refused(workers: object, words: list[str]) -> None:
    with pytest.raises(SceneError) as err:
        vector.make(num_envs=3, workers=workers, **KW)
    text = str(err.value)
    assert "\n" not in text
    for word in words:
        assert word in text, text


def test_a_workers_failure_is_raised_in_the_parent_as_it_was() -> None:
    from sweep_core.envs import workers
    with pytest.raises(SceneError) as err:
        workers.reraise(1, workers.portable(SceneError("robots[0].goal", "is missing", "give it")))
    assert str(err.value) == "robots[0].goal: is missing (fix: give it)"
    with pytest.raises(RuntimeError) as other:
        workers.reraise(0, workers.portable(ZeroDivisionError("division by zero")))
    assert str(other.value) == ("worker 0 of the vector environment failed: ZeroDivisionError: "
                                "division by zero")


def test_spawned_workers_step_the_same_episodes(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the platform does not fork (macOS, Windows), workers are spawned: the scene and
    the arguments reach them by pickling, and the episodes are the same bit for bit."""
    from sweep_core.envs import workers
    monkeypatch.setattr(workers, "start_method", lambda: "spawn")
    split = vector.make(num_envs=2, workers=2, **KW)
    mine = vector.make(num_envs=2, **KW)
    assert all(p.is_alive() for p in split.workers.procs)
    assert same(rollout(split, 7, 5), rollout(mine, 7, 5))
    split.close()
    mine.close()


def test_a_worker_that_ended_is_reported_in_one_line() -> None:
    """A worker killed from outside: the next step says which one ended and what to do,
    instead of a broken pipe's traceback."""
    split = vector.make(num_envs=2, workers=2, **KW)
    split.reset(seed=0)
    procs = list(split.workers.procs)
    split.workers.procs[1].kill()
    split.workers.procs[1].join(10)
    with pytest.raises(RuntimeError) as err:
        for _ in range(3):  # the pipe may take a send to notice
            split.step(actions(2, 0))
    text = str(err.value)
    assert "\n" not in text and "worker 1" in text and ("ended" in text), text
    split.close()
    assert not any(p.is_alive() for p in procs)


def test_a_worker_killed_during_a_step_is_reported_with_its_exit_code() -> None:
    """A worker killed while it steps (its answer never comes): the step says which worker
    ended, its exit code (not None: it is reaped first) and what to do."""
    split = vector.make(num_envs=2, workers=2, **KW)
    split.reset(seed=0)
    pid = split.workers.procs[1].pid
    os.kill(pid, signal.SIGSTOP)  # it receives the step but cannot answer it
    threading.Timer(0.5, os.kill, (pid, signal.SIGKILL)).start()
    with pytest.raises(RuntimeError) as err:
        split.step(actions(2, 0))
    text = str(err.value)
    assert text == ("worker 1 of the vector environment has ended (exit code -9): close it "
                    "and make a new one"), text
    assert isinstance(err.value, SweepError)  # the command line says it in one line
    split.close()


def test_workers_end_when_their_parent_is_killed(tmp_path) -> None:
    """A parent killed outright (no close, no exit handlers): its workers read the end of
    their pipes and end, instead of waiting for it forever."""
    import os
    import signal
    import subprocess
    import sys
    import time
    from pathlib import Path
    script = tmp_path / "parent.py"
    script.write_text(
        "import sys, time\n"
        f"sys.path.insert(0, {str(Path(__file__).parent)!r})\n"
        "from robot_scenes import small_scene\n"
        "from sweep_core.envs import vector\n"
        "env = vector.make(num_envs=2, workers=2, scene=small_scene(), dt=0.1, max_steps=4)\n"
        "env.reset(seed=0)\n"
        "print(' '.join(str(p.pid) for p in env.workers.procs), flush=True)\n"
        "time.sleep(600)\n")
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    try:
        pids = [int(p) for p in parent.stdout.readline().split()]  # type: ignore[union-attr]
        assert len(pids) == 2
    finally:
        parent.kill()
        parent.wait()

    def alive(pid: int) -> bool:  # an ended worker no one has reaped yet is a zombie (Z)
        try:
            stat = Path(f"/proc/{pid}/stat").read_text()
        except OSError:
            return False
        return stat.rsplit(")", 1)[1].split()[0] != "Z"

    deadline = time.monotonic() + 30.0
    while any(alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = [p for p in pids if alive(p)]
    for p in left:
        os.kill(p, signal.SIGKILL)
    assert not left, f"workers {left} outlived their killed parent"


def masked_rollout(envs: gymnasium.vector.VectorEnv) -> list:
    """Two steps, a reset of environment 1 alone (seeded, then unseeded), steps through the
    others' truncation and autoreset."""
    out = rollout(envs, 5, 2)
    out += list(envs.reset(seed=7, options={"reset_mask": np.array([False, True, False])}))
    for step in range(3):
        out += list(envs.step(actions(envs.num_envs, step)))
    out += list(envs.reset(options={"reset_mask": np.array([True, False, True])}))
    for step in range(2):
        out += list(envs.step(actions(envs.num_envs, step)))
    return out


@pytest.mark.parametrize("workers", [1, 2])
def test_a_reset_mask_resets_only_the_marked_environments_as_sync_does(workers: int) -> None:
    """Against Gymnasium's SyncVectorEnv: the observations (the unmarked rows kept), the
    infos (and their ``_`` masks: the reset ones only) and the following steps (t_s of the
    unmarked ones going on, autoresets) bit for bit with a seeded masked reset."""
    vec = gymnasium.make_vec("sweep/CrowdNav-v0", num_envs=3, workers=workers,
                             vectorization_mode="vector_entry_point", **KW)
    sync = gymnasium.make_vec("sweep/CrowdNav-v0", num_envs=3, vectorization_mode="sync",
                              **KW)
    ours, theirs = masked_rollout(vec), masked_rollout(sync)
    obs, info = ours[12], ours[13]
    assert info["_t_s"].tolist() == [False, True, False]
    np.testing.assert_array_equal(obs["odom"][[0, 2]], ours[7]["odom"][[0, 2]])
    assert same(ours, theirs)  # the unseeded reset draws from each environment's generator
    np.testing.assert_allclose(ours[18]["t_s"], [0.3, 0.1, 0.3], rtol=1e-12)
    assert ours[30]["_t_s"].tolist() == [True, False, True]
    np.testing.assert_array_equal(ours[29]["odom"][1], ours[24]["odom"][1])
    vec.close()
    sync.close()


@pytest.mark.parametrize(("mask", "words"), [
    ([True, False, True], ["[true, false, true] (a list)"]), (np.array([1, 0, 1]), ["dtype int64"]),
    (np.array([True, False]), ["shape (2,)"]), (np.zeros(3, dtype=bool), ["all False"])])
def test_bad_reset_masks_are_refused(envs: CrowdNavVectorEnv, mask: object,
                                     words: list[str]) -> None:
    with pytest.raises(SceneError) as err:
        envs.reset(options={"reset_mask": mask})
    text = str(err.value)
    assert "\n" not in text and text.startswith('options["reset_mask"]')
    for word in words:
        assert word in text, text


def test_copying_or_pickling_workers_is_refused_and_leaves_them_working() -> None:
    """deepcopy, copy and pickle of a vector environment with workers: one line, and the
    original then steps as before (as its in-process twin) and closes cleanly; without
    workers a deep copy is an independent twin."""
    import copy
    import pickle
    split = vector.make(num_envs=2, workers=2, **KW)
    mine = vector.make(num_envs=2, **KW)
    assert same(split.reset(seed=3), mine.reset(seed=3))
    for how in (copy.deepcopy, copy.copy, pickle.dumps):
        with pytest.raises(SceneError) as err:
            how(split)
        text = str(err.value)
        assert "\n" not in text and text.startswith("workers:") and "workers=2" in text
    for step in range(3):
        assert same(split.step(actions(2, step)), mine.step(actions(2, step)))
    split.close()
    twin = copy.deepcopy(mine)
    assert same(twin.step(actions(2, 3)), mine.step(actions(2, 3)))
    mine.close()
    twin.close()


@pytest.mark.parametrize("num_envs", [1, 2])
def test_an_episode_too_long_for_the_memory_is_refused_naming_max_steps(
        monkeypatch: pytest.MonkeyPatch, num_envs: int) -> None:
    """The episode's history is what does not fit: max_steps is named, and its suggested
    largest value is accepted. The measure of an environment's memory is pinned (2 MB kept,
    700 B per step, 1 MB of scratch): tracemalloc's measure varies from one process state
    to another, the arithmetic on it does not."""
    from sweep_core.envs import crowdnav
    monkeypatch.setattr(vector, "_memory_of", lambda build: (build(), (2e6, 700.0, 10 ** 6))[1])
    monkeypatch.setattr(vector, "available_memory", lambda: 10 ** 8)  # 100 MB
    monkeypatch.setattr(crowdnav, "available_memory", lambda: 10 ** 12)  # one env's check
    kw = {**KW, "max_steps": 10 ** 6}
    with pytest.raises(SceneError) as err:
        vector.make(num_envs=num_envs, **kw)
    text = str(err.value)
    assert "\n" not in text and text.startswith("max_steps: 1000000 steps"), text
    fix = text.split("(fix: max_steps=")[1]
    most = int(fix.split(" ")[0])
    assert 1 <= most < 10 ** 6 and fix.endswith(" or fewer)")
    envs = vector.make(num_envs=num_envs, **{**KW, "max_steps": most})
    assert envs.memory_estimate <= 0.5 * 10 ** 8
    envs.close()


@pytest.mark.parametrize("workers", [1, 2])
def test_a_closed_vector_environment_refuses_steps_and_resets_alike(workers: int) -> None:
    envs = vector.make(num_envs=2, workers=workers, **KW)
    envs.reset(seed=0)
    envs.close()
    for call in (lambda: envs.step(actions(2, 0)), lambda: envs.reset(seed=0)):
        with pytest.raises(SceneError) as err:
            call()
        text = str(err.value)
        assert "\n" not in text and "the vector environment is closed" in text
        assert "make a new one" in text
    envs.close()  # a second close is harmless


def combined_by_add_info(env: CrowdNavVectorEnv, infos: list[dict]) -> dict:
    out: dict = {}
    for i, info in enumerate(infos):
        out = env._add_info(out, info, i)
    return out


def test_infos_combine_as_gymnasiums_add_info() -> None:
    env = CrowdNavVectorEnv(num_envs=3, **KW)
    try:
        plain = [{"t_s": 0.1 * i, "clearance_m": [np.inf, 0.25, np.nan][i], "contacts": i,
                  "done": i == 1} for i in range(3)]
        ended = [dict(plain[0]), {**plain[1], "metrics": {"success": True, "time_s": 1.5}},
                 dict(plain[2])]
        mixed = [dict(plain[0]), {**plain[1], "contacts": 2.0}, dict(plain[2])]  # int, float
        fewer = [dict(plain[0]), {"t_s": 0.2}, dict(plain[2])]
        reordered = [dict(plain[0]), dict(reversed(list(plain[1].items()))), dict(plain[2])]
        numpy_scalar = [dict(plain[0]), {**plain[1], "t_s": np.float32(0.5)}, dict(plain[2])]
        for infos in (plain, ended, mixed, fewer, reordered, numpy_scalar):
            ours, theirs = env._combine(infos), combined_by_add_info(env, infos)
            assert list(ours) == list(theirs)
            assert same(ours, theirs)
            assert all(ours[k].dtype == theirs[k].dtype for k in ours if hasattr(ours[k], "dtype"))
    finally:
        env.close()


@pytest.mark.filterwarnings("ignore::UserWarning")  # Gymnasium logs the worker's traceback
def test_gymnasiums_async_vector_env_raises_the_environments_refusal_as_it_was() -> None:
    """Gymnasium's AsyncVectorEnv raises a worker's error again as ``type(err)(err)``: a
    SceneError so built is the same refusal (field, problem, fix), not a TypeError."""
    err = SceneError("action", "must be 2 finite numbers, got [nan, 0]", "give an element")
    again = SceneError(err)
    assert (again.field, again.problem, again.fix, str(again)) == (
        err.field, err.problem, err.fix, str(err))
    with pytest.raises(TypeError):
        SceneError("action")  # type: ignore[call-arg]
    envs = gymnasium.make_vec("sweep/CrowdNav-v0", num_envs=2, vectorization_mode="async", **KW)
    try:
        envs.reset(seed=0)
        with pytest.raises(SceneError) as raised:
            envs.step(np.array([[0.5, 0.0], [np.nan, 0.0]]))
        assert str(raised.value).startswith("action: must be 2 finite numbers"), raised.value
    finally:
        envs.close()


@pytest.mark.parametrize("workers", [1, 2])
def test_a_step_that_failed_in_one_environment_is_refused_until_a_reset(
        workers: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """Environment 1 of 3 fails its step after environment 0 has taken its own: the batch is
    out of step, so the next step and a masked reset are refused in one line; a reset of every
    environment starts them again, as a new vector environment with the same seed would."""
    from sweep_core.envs import crowdnav

    plain = crowdnav.CrowdNavEnv.step

    def fails(self, action):  # the second step of the episode seeded 1004 (environment 1)
        if self.np_random_seed == 1004 and self.steps == 1:
            raise RuntimeError("a step failed")
        return plain(self, action)

    monkeypatch.setattr(crowdnav.CrowdNavEnv, "step", fails)  # before the workers are forked
    envs = CrowdNavVectorEnv(num_envs=3, workers=workers, **KW)
    fresh = CrowdNavVectorEnv(num_envs=3, **KW)
    try:
        envs.reset(seed=1003)
        envs.step(actions(3, 0))
        with pytest.raises(RuntimeError, match="a step failed"):
            envs.step(actions(3, 1))
        for call in (lambda: envs.step(actions(3, 2)),
                     lambda: envs.reset(options={"reset_mask": np.array([True, False, False])})):
            with pytest.raises(SceneError, match=r"out of step \(fix: call reset\(\)"):
                call()
        assert same(envs.reset(seed=3), fresh.reset(seed=3))
        assert same(envs.step(actions(3, 0)), fresh.step(actions(3, 0)))
        assert same(envs.step(actions(3, 1)), fresh.step(actions(3, 1)))
    finally:
        envs.close()
        fresh.close()


@pytest.mark.parametrize("workers", [1, 2])
def test_a_misspelt_reset_option_is_refused_not_read_as_a_full_reset(workers: int) -> None:
    envs = CrowdNavVectorEnv(num_envs=2, workers=workers, **KW)
    try:
        envs.reset(seed=0)
        for options, words in (({"resetmask": np.array([True, False])},
                                "options: has the key 'resetmask', but the environment takes "
                                "only the key 'reset_mask'"),
                               ([True, False], "options: must be a dict or None")):
            with pytest.raises(SceneError) as raised:
                envs.reset(options=options)
            assert str(raised.value).startswith(words), raised.value
        envs.reset(options={"reset_mask": np.array([True, False])})
    finally:
        envs.close()
