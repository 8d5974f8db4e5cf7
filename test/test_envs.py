"""The Gymnasium environment sweep/CrowdNav-v0: gymnasium's own checker, seeded episodes
reproduced bit for bit, the reward and the metrics at the end of an episode."""
import math

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from robot_scenes import small_scene

import sweep_core.envs  # noqa: F401  (registers sweep/CrowdNav-v0)
from sweep_core.envs import CrowdNavEnv, crowdnav
from sweep_core.errors import SceneError


def test_the_environment_passes_gymnasiums_checker():
    env = CrowdNavEnv(small_scene(), dt=0.1, max_steps=10)
    check_env(env, skip_render_check=True)
    assert env.observation_space["scan"].shape[0] >= 2


def episode(env: gymnasium.Env, seed: int, steps: int) -> list:
    obs, info = env.reset(seed=seed)
    out = [obs, info]
    for k in range(steps):
        action = np.array([0.8, 0.3 * math.sin(k)])  # a fixed, deterministic sequence
        obs, reward, terminated, truncated, info = env.step(action)
        out += [obs, reward, terminated, truncated, info]
        if terminated or truncated:
            break
    return out


def same(a, b) -> bool:
    """Equal bit for bit: arrays by their bytes, floats by repr, containers elementwise."""
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    return repr(a) == repr(b)


def test_a_seeded_episode_is_reproduced_bit_for_bit():
    make = lambda: gymnasium.make("sweep/CrowdNav-v0", scene=small_scene(), dt=0.1,  # noqa: E731
                                  max_steps=12)
    first, second = episode(make(), 7, 12), episode(make(), 7, 12)
    assert same(first, second)
    # the seed matters: the crowd's noise and the scan's noise follow it
    other = episode(make(), 8, 12)
    assert not same(first, other)
    # and reset(seed) on a used environment starts the same episode again
    env = make()
    episode(env, 3, 5)
    assert same(episode(env, 7, 12), first)
    # the last step of the truncated episode carries the metrics
    info = first[-1]
    assert first[-2] is True and "metrics" in info  # truncated
    m = info["metrics"]
    assert m["frames"] == 13 and not m["success"]
    assert m["path_length_m"] > 0 and m["clearance"]["min_m"] == pytest.approx(
        min(i["clearance_m"] for i in first[1::5]))


def test_a_straight_drive_reaches_the_goal_with_the_metrics_of_a_clear_path():
    # no noise, no people near the robot's lane (they walk along y = 1 and 2 west, the robot
    # drives along y = 1.5 east... so clear them: put them far off)
    scene = small_scene(sigma=0.0, holonomic=True)
    scene["agents"]["positions"] = [[7.0, 0.5], [7.0, 2.5]]
    scene["drift"] = {"kind": "none"}
    env = CrowdNavEnv(scene, dt=0.1, max_steps=100)
    obs, _ = env.reset(seed=1)
    assert obs["goal"] == pytest.approx([4.5, 0.0], abs=1e-12)  # 4.5 m ahead, in base_link
    total, steps = 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(np.array([1.0, 0.0, 0.0]))
        total += reward
        steps += 1
        if terminated or truncated:
            break
    m = info["metrics"]
    assert terminated and m["success"] and not m["collided"]
    # the episode's reward: the geodesic progress plus the success reward
    x = obs["odom"][0]
    progress = env.unwrapped.geodesic - float(env.unwrapped.field.travel_distance(
        np.array([[x, 1.5]]))[0])
    assert total == pytest.approx(progress + 1.0, abs=1e-9)
    assert m["time_to_goal_s"] == pytest.approx(steps * 0.1, abs=1e-9)
    assert m["path_length_m"] == pytest.approx(x - 0.5, abs=1e-9)
    assert m["heading_change_rad"] == 0.0 and m["contact"]["frames"] == 0


def test_a_scene_without_a_robot_goal_or_scan_is_refused():
    scene = small_scene()
    del scene["robots"][0]["scan"]
    with pytest.raises(SceneError, match=r"robots\[0\]\.scan"):
        CrowdNavEnv(scene)
    scene = small_scene()
    scene["robots"] = []
    with pytest.raises(SceneError, match="robots"):
        CrowdNavEnv(scene)
    with pytest.raises(SceneError, match="'nobody' is not a robot"):
        CrowdNavEnv(small_scene(), robot="nobody")


def test_the_bundled_scene_makes_the_default_environment():
    env = gymnasium.make("sweep/CrowdNav-v0")
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs["goal"] == pytest.approx([10.0, 0.0])  # from (1, 3) facing east to (11, 3)


def test_episodes_do_not_build_the_driven_robots_controller(monkeypatch):
    """The actions replace the driven robot's controller, so its navigation field is not
    built at each reset; the episodes are those of the same scene with controller none."""
    from sweep_core.envs.crowdnav import DEFAULT_SCENE
    from sweep_core.model.scene import load_scene
    from sweep_core.numerics.robots import planners

    scene = load_scene(str(DEFAULT_SCENE))
    assert scene.robots[0].controller == "social_force"
    spec = dict(scene.spec, robots=[dict(scene.spec["robots"][0], controller="none")])
    plain = CrowdNavEnv(spec, max_steps=30)
    want = episode(plain, 3, 30)

    build = planners.controller_for

    def refuse(scene, robot):
        assert robot.controller == "none", "the driven robot's controller was built"
        return build(scene, robot)

    monkeypatch.setattr(planners, "controller_for", refuse)
    env = CrowdNavEnv(scene, max_steps=30)
    assert same(episode(env, 3, 30), want)


def test_an_action_outside_the_box_drives_as_the_box_clipped_one():
    """Actions beyond the box (and signed zeros) give the episode of the actions clipped to
    the box by np.clip, bit for bit."""
    env_a, env_b = (CrowdNavEnv(small_scene(), dt=0.1, max_steps=30) for _ in range(2))
    low, high = env_a.action_space.low, env_a.action_space.high
    rng = np.random.default_rng(4)
    out_a, out_b = [env_a.reset(seed=9)], [env_b.reset(seed=9)]
    for _ in range(30):
        action = rng.uniform(-3.0, 3.0, 2) * high
        action[rng.uniform(size=2) < 0.2] = -0.0
        out_a.append(env_a.step(action))
        out_b.append(env_b.step(np.clip(action, low, high)))
        if out_a[-1][2] or out_a[-1][3]:
            break
    assert same(out_a, out_b)
    assert any(st[4]["clipped"] for st in out_a[1:])  # the engine's own limits took part too


def test_the_distance_to_go_keeps_growing_off_the_goal_fields_grid():
    """Driving straight away from the goal, out of the goal field's grid: each step's reward
    stays the progress, about -speed * dt, and the distance to go grows with the distance
    from the grid's edge."""
    env = CrowdNavEnv(max_steps=400)
    env.reset(seed=0)
    left = float(env.field.x[0])
    off = []
    for _ in range(80):
        _, reward, terminated, truncated, info = env.step([-1.0, 0.0])
        assert not (terminated or truncated)
        x = env.rows[-1][1]
        if x < left - 0.2 and info["clearance_m"] > 0.2:
            off.append((reward, x, env.togo))
    assert len(off) >= 20
    for (reward, x, togo), (_, x0, togo0) in zip(off[1:], off):
        assert reward == pytest.approx(-(x0 - x), abs=1e-9)
        assert reward == pytest.approx(-0.1, abs=1e-3)
        assert togo - togo0 == pytest.approx(x0 - x, abs=1e-9)


@pytest.mark.parametrize(("seed", "words"), [
    (-1, ["seed", "integer >= 0", "-1"]), (np.int64(-1), ["seed", "-1"]),
    (1.5, ["seed", "1.5"]), ("3", ["seed", "'3'"]), (True, ["seed", "true"])])
def test_bad_seeds_are_refused_in_one_line(seed, words):
    single = CrowdNavEnv(small_scene(), dt=0.1, max_steps=4)
    vec = gymnasium.make_vec("sweep/CrowdNav-v0", num_envs=2,
                             vectorization_mode="vector_entry_point", scene=small_scene(),
                             dt=0.1, max_steps=4)
    for env in (single, vec):
        with pytest.raises(SceneError) as err:
            env.reset(seed=seed)
        text = str(err.value)
        assert "\n" not in text and text.startswith("seed:"), text
        for word in words:
            assert word in text, text
    vec.close()


def test_a_numpy_integer_seed_is_the_int_seed():
    env = CrowdNavEnv(small_scene(), dt=0.1, max_steps=4)
    assert same(episode(env, np.int64(3), 3), episode(env, 3, 3))


def test_a_zero_dimensional_array_seed_is_the_int_seed():
    """np.array(3) is the seed 3, for the single environment and the vector one (whose seed
    list may hold such arrays too)."""
    env = CrowdNavEnv(small_scene(), dt=0.1, max_steps=4)
    assert same(episode(env, np.array(3), 3), episode(env, 3, 3))
    vec = make_vec(num_envs=2)
    ours, theirs = vec.reset(seed=np.array(3))[0], vec.reset(seed=3)[0]
    assert all(same(ours[k], theirs[k]) for k in ours)
    ours = vec.reset(seed=[np.array(5), np.array(4)])[0]
    theirs = vec.reset(seed=[5, 4])[0]
    assert all(same(ours[k], theirs[k]) for k in ours)
    vec.close()


def make_vec(**kwargs):
    return gymnasium.make_vec("sweep/CrowdNav-v0", vectorization_mode="vector_entry_point",
                              scene=small_scene(), dt=0.1, max_steps=4, **kwargs)


@pytest.mark.parametrize(("build", "words"), [
    (lambda: gymnasium.make("sweep/CrowdNav-v0", render_mode="rgb_array"),
     ["render_mode:", "'rgb_array'", "sweep render"]),
    (lambda: make_vec(num_envs=2, render_mode="human"), ["render_mode:", "'human'"]),
    (lambda: CrowdNavEnv(small_scene()).render(), ["render:", "draws nothing", "sweep run"]),
    (lambda: make_vec(num_envs=2).render(), ["render:", "draw nothing"]),
    (lambda: CrowdNavEnv(small_scene(), holonomic=True),
     ["holonomic:", "not an argument", "max_steps", "render_mode"]),
    (lambda: CrowdNavEnv(small_scene(), workers=2), ["workers:", "gymnasium.make_vec"]),
    (lambda: make_vec(num_envs=2, foo=1), ["foo:", "num_envs, workers, scene"])])
def test_render_modes_and_unknown_arguments_are_refused_in_one_line(build, words):
    with pytest.raises(SceneError) as err:
        build()
    text = str(err.value)
    assert "\n" not in text
    for word in words:
        assert word in text, text


def test_render_mode_none_is_accepted():
    assert gymnasium.make("sweep/CrowdNav-v0", render_mode=None).render_mode is None
    envs = make_vec(num_envs=2, render_mode=None)
    assert envs.render_mode is None
    envs.close()


def test_an_episode_too_long_for_the_memory_is_refused_naming_max_steps(monkeypatch):
    # the memory available held fixed (8 GiB), so that the fix offered is checked against the
    # memory it was computed for (other processes change the machine's from moment to moment)
    monkeypatch.setattr(crowdnav, "available_memory", lambda: 8 * 2 ** 30)
    with pytest.raises(SceneError) as err:
        CrowdNavEnv(small_scene(), max_steps=10 ** 18)
    text = str(err.value)
    assert "\n" not in text and text.startswith("max_steps: 1000000000000000000 steps"), text
    most = int(text.split("(fix: max_steps=")[1].split(" ")[0])
    assert CrowdNavEnv(small_scene(), max_steps=most).max_steps == most


def test_a_step_before_the_first_reset_is_refused_in_one_line():
    env = CrowdNavEnv(small_scene(), dt=0.1, max_steps=4)
    with pytest.raises(SceneError) as err:
        env.step([0.5, 0.0])
    text = str(err.value)
    assert "\n" not in text and text.startswith("step:") and "call reset() first" in text
    env.reset(seed=0)
    assert env.step([0.5, 0.0])[4]["t_s"] == pytest.approx(0.1)


@pytest.mark.parametrize("action", [np.array([0.5 + 0.5j, 0.0]), np.array([0.5, 0.0], complex)])
def test_a_complex_action_is_refused_not_cut_to_its_real_part(action):
    """numpy casts complex to float by dropping the imaginary part (a warning only): refused
    in one line instead, as a Python complex is."""
    env = CrowdNavEnv(small_scene(), dt=0.1, max_steps=4)
    env.reset(seed=0)
    with pytest.raises(SceneError) as err:
        env.step(action)
    text = str(err.value)
    assert "\n" not in text and text.startswith("action:") and "complex" in text, text


@pytest.mark.parametrize("options, words", [
    ([1, 2], "options: must be a dict or None, got [1, 2] (a list)"),
    ({"reset_mask": np.array([True])}, "options: has the key 'reset_mask', but the environment "
                                       "takes no reset options"),
    ({"seed": 3}, "options: has the key 'seed'")])
def test_reset_options_the_environment_does_not_take_are_refused(options, words) -> None:
    """A misspelt or foreign key would be ignored, silently; None and {} are accepted."""
    env = gymnasium.make("sweep/CrowdNav-v0", scene=small_scene(), dt=0.1, max_steps=4)
    with pytest.raises(SceneError) as raised:
        env.reset(seed=0, options=options)
    assert str(raised.value).startswith(words) and "(fix: " in str(raised.value)
    env.reset(seed=0, options={})
    env.reset(seed=0, options=None)


def test_a_step_after_the_episode_ended_is_refused_until_a_reset() -> None:
    """Stepping on after the end would give the goal's reward again at every step, and grow
    the episode beyond max_steps: refused in one line saying how it ended."""
    scene = small_scene()
    scene["robots"][0]["goal"] = [1.0, 1.5]  # 0.5 m ahead: reached within a few steps
    env = gymnasium.make("sweep/CrowdNav-v0", scene=scene, dt=0.1, max_steps=40)
    env.reset(seed=0)
    steps = 0
    while steps < 40:
        _, reward, terminated, truncated, _ = env.step(np.array([0.8, 0.0]))
        steps += 1
        if terminated:
            break
    assert terminated and not truncated and reward > 0
    with pytest.raises(SceneError, match=rf"^step: called after the episode ended \(the robot "
                       rf"reached its goal at step {steps}\) \(fix: call reset\(\)"):
        env.step(np.array([0.8, 0.0]))
    short = gymnasium.make("sweep/CrowdNav-v0", scene=small_scene(), dt=0.1, max_steps=3)
    short.reset(seed=0)
    flags = [short.step(np.array([0.0, 0.0]))[3] for _ in range(3)]
    assert flags == [False, False, True]
    with pytest.raises(SceneError, match=r"\(truncated at max_steps = 3\)"):
        short.step(np.array([0.0, 0.0]))
    short.reset(seed=1)  # a new episode steps again
    assert not short.step(np.array([0.0, 0.0]))[3]
