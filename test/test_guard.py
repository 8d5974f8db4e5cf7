"""The planners' safety layer (passive motion safety, sweep_core/numerics/robots/guard.py) on
hand-built observations: the bound's closed form, no advance into a person in contact, the
nearest safe velocity."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sweep_core import Scene
from sweep_core.model import elementary
from sweep_core.numerics.robots.control import Observation
from sweep_core.numerics.robots.guard import nearest_safe, safe_speed, safe_speeds
from sweep_core.numerics.robots.planners import controller_for, to_command

LIMITS = {"max_speed": 1.0, "max_angular_speed": 1.5, "max_acceleration": 1.0,
          "max_angular_acceleration": 3.0}
EAST = np.array([1.0, 0.0])


def _robot(kind: str, controller: dict) -> tuple:
    scene = Scene.from_dict({
        "agents": {"positions": [[5.0, 2.0]], "radius": 0.25}, "noise": {"sigma": 0.0},
        "walls": [{"kind": "segment", "a": [-2.0, -3.0], "b": [12.0, -3.0]},
                  {"kind": "segment", "a": [-2.0, 3.0], "b": [12.0, 3.0]}],
        "robots": [{"name": "bot", "radius": 0.3, "pose": [0.0, 0.0, 0.0],
                    "kinematics": {"type": kind, **LIMITS}, "goal": [8.0, 0.0],
                    "goal_radius": 0.3, "controller": controller}]})
    return scene, scene.robots[0]


def _obs(people, speed: float) -> Observation:
    xy = np.array(people, dtype=np.float64).reshape(-1, 2)
    return Observation(0.0, (0.0, 0.0, 0.0), (speed, 0.0, 0.0), None, (8.0, 0.0), 0.3, 0.3,
                       xy, np.full(len(xy), 0.25), (speed, 0.0, 0.0), 0.01)


def test_the_bound_stops_the_robot_before_a_person_closing_in_can_reach_it():
    # a person straight ahead at gap 0.5 m; margin 0.1, a = 1, people close at 0.5 m/s
    v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                   1.0, 0.1, 0.5)
    assert v == pytest.approx(2 * 0.4 / (0.5 + math.sqrt(0.25 + 0.8)), rel=1e-12)
    # at that speed, braking at a: its own advance v^2 / 2a and the person's v_h v / a fill
    # the gap less the margin exactly
    assert v * v / 2 + 0.5 * v == pytest.approx(0.4, rel=1e-12)
    # a person 60 degrees off the direction: the robot advances at v cos 60 towards them
    p = 1.05 * np.array([[math.cos(math.pi / 3), math.sin(math.pi / 3)]])
    v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, p, np.array([0.25]), 1.0, 0.1, 0.5)
    assert 0.5 * v * v / 2 + 0.5 * v == pytest.approx(0.4, rel=1e-12)
    # standing people (v_h = 0): the braking distance sqrt(2 a (g - g0))
    v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                   1.0, 0.1, 0.0)
    assert v == pytest.approx(math.sqrt(0.8), rel=1e-12)


def test_no_advance_towards_a_person_in_contact_and_none_bound_by_people_behind():
    contact = np.array([[0.549, 0.0]])  # edge to edge: touching (1 mm overlap)
    dirs = np.array([[1.0, 0.0], [0.6, 0.8], [0.0, 1.0], [-1.0, 0.0]])
    v = safe_speeds((0.0, 0.0, 0.0), dirs, 0.3, contact, np.array([0.25]), 1.0, 0.0, 0.5)
    assert v[0] == 0.0 and v[1] == 0.0  # any direction with a component towards them
    assert math.isinf(v[2]) and math.isinf(v[3])  # sideways, away
    assert math.isinf(safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.empty((0, 2)), np.empty(0),
                                 1.0, 0.1, 0.5))


def test_the_nearest_safe_velocity_slides_past_a_person_in_contact():
    # touching a person 30 degrees to the left of the wished velocity: the nearest velocity
    # with no advance towards them is u less its component along e (sampled every 5 degrees)
    e = np.array([math.cos(math.pi / 6), math.sin(math.pi / 6)])
    u = np.array([1.0, 0.0])
    v = nearest_safe(u, (0.0, 0.0, 0.0), 0.3, 0.549 * e[None, :], np.array([0.25]), 1.0, 0.0,
                     0.5, directions=72)
    assert v @ e <= 1e-12
    assert v == pytest.approx(u - (u @ e) * e, abs=1e-12)  # -60 degrees is a sampled heading
    # head on, the nearest such velocity is rest
    assert nearest_safe(u, (0.0, 0.0, 0.0), 0.3, np.array([[0.549, 0.0]]), np.array([0.25]),
                        1.0, 0.0, 0.5) == pytest.approx([0.0, 0.0], abs=1e-12)


@pytest.mark.parametrize("controller", ["orca", "social_force", "window"])
def test_planners_brake_for_a_person_who_may_close_in(controller):
    # moving at 0.5 m/s, a person 0.3 m ahead (edge to edge): with people closing at up to
    # 0.5 m/s the robot cannot be at rest in time at this speed, so it brakes as hard as it
    # may (0.5 - a dt); a planner that only brakes for people standing still keeps going
    scene, robot = _robot("diff_drive", {"kind": controller, "stop_margin": 0.1,
                                         "people_speed": 0.5})
    cmd = controller_for(scene, robot)(_obs([[0.85, 0.0]], 0.5))
    assert cmd[0] == pytest.approx(0.5 - 0.01, abs=1e-12)


@pytest.mark.parametrize("controller", ["orca", "social_force", "window"])
def test_a_holonomic_robot_at_rest_never_advances_into_a_person_in_contact(controller):
    scene, robot = _robot("holonomic", {"kind": controller, "stop_margin": 0.05})
    for y in (-0.1, 0.0, 0.2):  # the person touching it, ahead and a little to the side
        p = np.array([[0.55, y]])
        p = p * 0.549 / np.hypot(*p[0])
        vx, vy, _ = controller_for(scene, robot)(_obs(p, 0.0))
        assert vx * p[0, 0] + vy * p[0, 1] <= 1e-12


def test_people_who_move_by_noise_reach_sqrt_t_farther_and_the_bound_keeps_it():
    # a person straight ahead at gap 0.5 m; margin 0.1, a = 1, v_h = 0.3 m/s, noise 0.3
    # m/sqrt(s): at the bound the robot's braking advance v^2 / 2a, the drift v_h v / a and
    # the noise's reach n sqrt(v / a) over its stopping time fill the gap less the margin
    for c, n in ((1.0, 0.3), (0.5, 0.3), (1.0, 0.05), (1.0, 2.0), (0.05, 0.3)):
        p = 1.05 * np.array([[c, math.sqrt(1.0 - c * c)]])
        v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, p, np.array([0.25]), 1.0, 0.1, 0.3, n)
        assert c * v * v / 2 + 0.3 * v + n * math.sqrt(v) == pytest.approx(0.4, rel=1e-12)
    # slower than the drift-only bound, and no drift: the noise alone
    drift = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                       1.0, 0.1, 0.3)
    noise = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                       1.0, 0.1, 0.3, 0.3)
    assert noise < drift
    v = safe_speed((0.0, 0.0, 0.0), EAST, 0.3, np.array([[1.05, 0.0]]), np.array([0.25]),
                   1.0, 0.1, 0.0, 0.3)
    assert v * v / 2 + 0.3 * math.sqrt(v) == pytest.approx(0.4, rel=1e-12)
    # within the margin, or in contact: no advance at all; sideways: no bound
    dirs = np.array([[1.0, 0.0], [0.0, 1.0]])
    for x in (0.549, 0.62):
        s = safe_speeds((0.0, 0.0, 0.0), dirs, 0.3, np.array([[x, 0.0]]), np.array([0.25]),
                        1.0, 0.1, 0.3, 0.3)
        assert s[0] == 0.0 and math.isinf(s[1])


@pytest.mark.parametrize("kind", ["diff_drive", "holonomic"])
def test_the_layer_brakes_for_a_person_whose_noise_may_bring_them_close(kind):
    # wishing to go on at 0.3 m/s, a person 0.25 m ahead (edge to edge), margin 0.1: people
    # closing in at 0.3 m/s allow 0.32 m/s, but one who moves by noise of 0.3 m/sqrt(s) may
    # cover 0.3 sqrt(0.3) = 0.16 m more in the 0.3 s it takes to stop: the robot brakes as
    # hard as it may (0.3 - a dt)
    u = np.array([0.3, 0.0])
    for noise, want in ((0.0, 0.3), (0.3, 0.3 - 0.01)):
        scene, robot = _robot(kind, {"kind": "orca", "stop_margin": 0.1, "people_speed": 0.3,
                                     "people_noise": noise})
        cmd = to_command(robot, u, _obs([[0.8, 0.0]], 0.3), robot.params)
        assert cmd[0] == pytest.approx(want, abs=1e-12) and abs(cmd[1]) <= 1e-12


def test_safe_speeds_keep_the_bits_of_the_numpy_form() -> None:
    """safe_speeds' compiled bound gives, bit for bit, what the numpy form below gives (the
    same operations on arrays), on random robots, people and parameters."""
    import math

    from sweep_core.numerics.robots.guard import AHEAD

    def numpy_form(pose, directions, radius, people, people_radii, accel, margin, ps):
        if not len(people):
            return np.full(len(directions), math.inf)
        rel = people - np.array(pose[:2])
        d = np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-12)
        unit = rel / d[:, None]
        c = unit[:, :1] * directions[:, 0] + unit[:, 1:] * directions[:, 1]
        gap = np.maximum(d - radius - people_radii - margin, 0.0)[:, None]
        root = np.sqrt(ps * ps + 2.0 * accel * np.maximum(c, 0.0) * gap)
        bound = np.where(gap > 0.0, 2.0 * accel * gap / np.maximum(ps + root, 1e-300), 0.0)
        return np.where(c > AHEAD, bound, math.inf).min(axis=0, initial=math.inf)

    rng = np.random.default_rng(7)
    for _ in range(500):
        m, k = int(rng.integers(0, 25)), int(rng.integers(1, 80))
        phi = rng.uniform(0.0, 2 * math.pi, k)
        args = ((float(rng.normal()), float(rng.normal()), 0.0),
                np.column_stack([np.cos(phi), np.sin(phi)]), 0.3, rng.normal(size=(m, 2)) * 3,
                rng.uniform(0.1, 0.4, m), float(rng.uniform(0.5, 3.0)),
                float(rng.uniform(0.0, 0.2)), float(rng.choice([0.0, 0.5, 1.0])))
        assert safe_speeds(*args).tobytes() == numpy_form(*args).tobytes()


def test_safe_speeds_with_people_noise_keep_the_bits_of_the_numpy_form() -> None:
    """safe_speeds' compiled bound with people_noise > 0 gives, bit for bit, what the numpy
    form below gives (Newton's method on whole arrays from the smallest one-term root), on
    random robots, people and parameters, people in contact and beside the robot included
    (the compiled form skips people whose bound cannot be the smallest: the minimum must not
    change)."""
    from sweep_core.numerics.robots.guard import AHEAD, NEWTON_STEPS

    def reach_root(quartic, square, linear, room):
        s = room / linear
        if square > 0:
            s = np.minimum(s, np.sqrt(room / square))
        s = np.minimum(s, np.where(quartic > 0, np.sqrt(np.sqrt(room / np.maximum(quartic, 1e-300))),
                                   np.inf))
        for _ in range(NEWTON_STEPS):
            f = ((quartic * s * s + square) * s + linear) * s - room
            s = np.maximum(s - f / ((4.0 * quartic * s * s + 2.0 * square) * s + linear), 0.0)
        return s

    def numpy_form(pose, directions, radius, people, people_radii, accel, margin, ps, noise):
        if not len(people):
            return np.full(len(directions), math.inf)
        rel = people - np.array(pose[:2])
        d = np.maximum(np.hypot(rel[:, 0], rel[:, 1]), 1e-12)
        c = (rel[:, :1] / d[:, None]) * directions[:, 0] + \
            (rel[:, 1:] / d[:, None]) * directions[:, 1]
        gap = np.maximum(d - radius - people_radii - margin, 0.0)
        room = np.broadcast_to(gap[:, None], c.shape)
        s = reach_root(accel * np.maximum(c, 0.0) / 2.0, ps, noise, room)
        bound = np.where(room > 0.0, accel * s * s, 0.0)
        return np.where(c > AHEAD, bound, math.inf).min(axis=0, initial=math.inf)

    rng = np.random.default_rng(11)
    for _ in range(500):
        m, k = int(rng.integers(0, 60)), int(rng.integers(1, 80))
        phi = rng.uniform(0.0, 2 * math.pi, k)
        people = rng.normal(size=(m, 2)) * 3
        if m:
            people[0] = (0.55, 0.0)  # in contact with the robot at the origin
        args = ((0.0, 0.0, 0.0) if m % 3 == 0 else (float(rng.normal()), float(rng.normal()), 0.0),
                np.column_stack([np.cos(phi), np.sin(phi)]), 0.3, people,
                rng.uniform(0.1, 0.4, m), float(rng.uniform(0.5, 3.0)),
                float(rng.uniform(0.0, 0.2)), float(rng.choice([0.0, 0.1, 0.5])),
                float(rng.choice([0.01, 0.05, 0.3, 1.0])))
        assert safe_speeds(*args).tobytes() == numpy_form(*args).tobytes()


def test_social_force_people_term_keeps_the_bits_of_the_numpy_form() -> None:
    """SocialForce.people_force (compiled terms, elementary's exponentials) gives, bit for bit,
    what the numpy form below gives, on random people, velocities and headings."""
    from types import SimpleNamespace

    from sweep_core.numerics.robots.planners import SocialForce

    params = {"anticipation": 0.6, "anisotropy": 0.3, "strength": 2.1, "range": 0.35,
              "side": 0.4}

    def numpy_form(obs, o, v, v_people):
        d = o - obs.people
        y = (v_people - v) * params["anticipation"]
        dn = np.maximum(np.hypot(*d.T), 1e-9)
        dy = d - y
        dyn = np.maximum(np.hypot(*dy.T), 1e-9)
        yn = np.hypot(*y.T)
        b = 0.5 * np.sqrt(np.maximum((dn + dyn) ** 2 - yn ** 2, 1e-18))
        grad = ((dn + dyn) / (4.0 * np.maximum(b, 1e-9)))[:, None] * (
            d / dn[:, None] + dy / dyn[:, None])
        e = d / dn[:, None]
        cos_phi = -(e[:, 0] * elementary.cos(obs.pose[2]) + e[:, 1] * elementary.sin(obs.pose[2]))
        lam = params["anisotropy"]
        w = lam + (1.0 - lam) * (1.0 + cos_phi) / 2.0
        mag = params["strength"] * elementary.exp_of((obs.radius + obs.people_radii - b)
                                          / params["range"]) * w
        turn = np.column_stack([-grad[:, 1], grad[:, 0]])
        side = params["side"] * np.maximum(cos_phi, 0.0)
        return (mag[:, None] * (grad + side[:, None] * turn)).sum(axis=0)

    planner = SocialForce.__new__(SocialForce)
    planner.params = params
    rng = np.random.default_rng(3)
    for _ in range(500):
        m = int(rng.integers(1, 30))
        obs = SimpleNamespace(people=rng.normal(size=(m, 2)) * 3,
                              people_radii=rng.uniform(0.1, 0.4, m), radius=0.3,
                              pose=(0.0, 0.0, float(rng.uniform(-3.2, 3.2))))
        o, v = rng.normal(size=2), rng.normal(size=2)
        v_people = rng.normal(size=(m, 2))
        got = planner.people_force(obs, o, v, v_people)
        assert got.tobytes() == numpy_form(obs, o, v, v_people).tobytes()


def test_tracker_and_wall_search_keep_the_bits_of_the_numpy_forms() -> None:
    """The planners' Tracker.update and segments within the sensor range (compiled) give, bit
    for bit, what their numpy forms below give, on random crowds (people appearing and
    leaving, ties) and segments (the robot beyond either end, degenerate segments)."""
    import math
    from types import SimpleNamespace

    from sweep_core.numerics.robots import planners

    def track_numpy(old_t, old_xy, old_v, t, xy):
        v = np.zeros_like(xy)
        dt = t - old_t
        dx = xy[:, None, 0] - old_xy[None, :, 0]
        dy = xy[:, None, 1] - old_xy[None, :, 1]
        d2 = dx * dx + dy * dy
        j = np.argmin(d2, axis=1)
        back = np.argmin(d2, axis=0)
        ok = (back[j] == np.arange(len(xy))) & (d2[np.arange(len(xy)), j]
                                                 <= planners.GATE ** 2)
        a = 1.0 - math.exp(-dt / planners.TRACK_TIME)
        step = (xy[ok] - old_xy[j[ok]]) / dt
        v[ok] = old_v[j[ok]] + a * (step - old_v[j[ok]])
        return v

    rng = np.random.default_rng(5)
    for _ in range(400):
        m, k = int(rng.integers(1, 12)), int(rng.integers(1, 12))
        old = np.round(rng.uniform(0, 3, (k, 2)), 1)  # rounded: ties of distance
        xy = np.round(old[rng.integers(0, k, m)] + rng.normal(0, 0.2, (m, 2)), 2)
        tracker = planners.Tracker()
        tracker.t, tracker.xy, tracker.v = 1.0, old, rng.normal(size=(k, 2))
        want = track_numpy(1.0, old, tracker.v, 1.1, xy)
        assert tracker.update(1.1, xy).tobytes() == want.tobytes()

    planner = planners.Planner.__new__(planners.Planner)
    for _ in range(400):
        s = int(rng.integers(1, 10))
        a = rng.uniform(-5, 5, (s, 2))
        b = a + rng.normal(size=(s, 2)) * rng.choice([0.0, 1.0, 4.0], (s, 1))
        p = rng.uniform(-6, 6, 2)
        reach = float(rng.uniform(0.5, 6.0))
        geometry = SimpleNamespace(segment_a=a, segment_b=b)
        planner.scene = SimpleNamespace(geometry=SimpleNamespace(at=lambda t, g=geometry: g))
        planner.params = {"sensor_range": reach}
        got = planner.segments(SimpleNamespace(t=0.0, pose=(p[0], p[1], 0.0)))
        e = b - a
        ee = np.maximum(np.einsum("ij,ij->i", e, e), 1e-300)
        u = np.clip(np.einsum("ij,ij->i", p - a, e) / ee, 0.0, 1.0)
        near = np.hypot(*(a + u[:, None] * e - p).T) <= reach
        assert got[0].tobytes() == a[near].tobytes() and got[1].tobytes() == b[near].tobytes()


def test_social_force_wall_term_keeps_the_bits_of_the_numpy_form() -> None:
    """The social force's wall term (compiled offsets and sum, numpy's exponential) gives, bit
    for bit, the numpy form's force, on random segments and robots."""
    from sweep_core.numerics.robots.social_kernels import scaled_sum, wall_offsets

    rng = np.random.default_rng(9)
    for _ in range(500):
        s = int(rng.integers(1, 10))
        a = rng.uniform(-5, 5, (s, 2))
        b = a + rng.normal(size=(s, 2)) * rng.choice([0.0, 1.0, 4.0], (s, 1))
        o = rng.uniform(-6, 6, 2)
        e = b - a
        ee = np.maximum(np.einsum("ij,ij->i", e, e), 1e-300)
        u = np.clip(np.einsum("ij,ij->i", o - a, e) / ee, 0.0, 1.0)
        rel = o - (a + u[:, None] * e)
        d = np.maximum(np.hypot(*rel.T), 1e-9)
        mag = 2.0 * np.exp(-(d - 0.3) / 0.2)
        want = (mag[:, None] * rel / d[:, None]).sum(axis=0)
        got_rel, got_d = np.empty((s, 2)), np.empty(s)
        wall_offsets(float(o[0]), float(o[1]), a, b, got_rel, got_d)
        assert got_rel.tobytes() == rel.tobytes() and got_d.tobytes() == d.tobytes()
        assert scaled_sum(mag, got_rel, got_d).tobytes() == want.tobytes()


def test_nearest_safe_keeps_the_bits_of_the_numpy_form() -> None:
    """nearest_safe (its choice compiled) gives, bit for bit, the numpy form's velocity, on
    random wished velocities and crowds, some with no room (safe speeds of 0)."""
    import math

    def numpy_form(u, pose, radius, people, radii, accel, margin, ps, directions=72):
        if float(np.hypot(u[0], u[1])) <= 1e-12:
            return np.zeros(2)
        phi = elementary.atan2(u[1], u[0]) + np.arange(directions) * (2.0 * math.pi / directions)
        dirs = np.column_stack([elementary.cos_of(phi), elementary.sin_of(phi)])
        along = dirs[:, 0] * u[0] + dirs[:, 1] * u[1]
        s = np.clip(along, 0.0, safe_speeds(pose, dirs, radius, people, radii, accel, margin, ps))
        miss = (u[0] - s * dirs[:, 0]) ** 2 + (u[1] - s * dirs[:, 1]) ** 2
        k = int(np.argmin(miss))
        return np.asarray(s[k] * dirs[k])

    rng = np.random.default_rng(13)
    for case in range(600):
        m = int(rng.integers(0, 15))
        u = rng.normal(size=2) * rng.choice([1.0, 1e-13])
        if case % 7 == 0:
            u[int(rng.integers(0, 2))] = 0.0  # along an axis: components of -0.0 and 0.0
        people = rng.normal(size=(m, 2)) * rng.choice([0.5, 3.0])
        args = (u, (0.0, 0.0, float(rng.uniform(-3, 3))), 0.3, people, rng.uniform(0.1, 0.4, m),
                float(rng.uniform(0.5, 3.0)), float(rng.uniform(0.0, 0.2)),
                float(rng.choice([0.0, 0.5])))
        assert nearest_safe(*args).tobytes() == numpy_form(*args).tobytes()
