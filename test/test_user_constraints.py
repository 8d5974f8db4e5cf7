"""User constraints g(t, q) >= r written in Python (issue 13): an ellipse obstacle."""
import numpy as np
import pytest

import sweep_core as sc
from sweep_core.errors import SceneError
from sweep_core.model.gaps import gaps


class Ellipse:
    """Outside the ellipse x^2/a^2 + y^2/b^2 <= 1 centred at c (b <= a): g = b (|A (q - c)| - 1)
    with A = diag(1/a, 1/b). Convex, 1-Lipschitz (|grad g| <= b / b), zero on the ellipse, so
    g <= the distance to it: agents keep at least r away (exactly r along the minor axis)."""

    name = "ellipse"

    def __init__(self, a: float, b: float, c: tuple = (0.0, 0.0)) -> None:
        self.a, self.b, self.c = a, b, np.asarray(c, dtype=float)

    def value(self, t: float, q: np.ndarray) -> np.ndarray:
        u = (q - self.c) / [self.a, self.b]
        return self.b * (np.hypot(u[:, 0], u[:, 1]) - 1.0)

    def gradient(self, t: float, q: np.ndarray) -> np.ndarray:
        u = (q - self.c) / [self.a, self.b]
        norm = np.maximum(np.hypot(u[:, 0], u[:, 1]), 1e-300)
        return self.b * u / norm[:, None] / [self.a, self.b]


def true_distance(q: np.ndarray, a: float, b: float) -> np.ndarray:
    """Distance from points outside to the ellipse, by dense sampling of its boundary."""
    th = np.linspace(0, 2 * np.pi, 200_001)
    e = np.stack([a * np.cos(th), b * np.sin(th)], axis=1)
    return np.array([np.hypot(*(e - p).T).min() for p in q])


def test_disk_pushed_onto_the_ellipse_stops_exactly() -> None:
    r = 0.2
    base = sc.Scene.from_dict({"agents": {"positions": [[0.0, 2.0]], "radius": r},
                               "drift": {"kind": "uniform", "velocity": [0.0, -1.0]}})
    scene = base.with_constraints(Ellipse(3.0, 1.0))
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    sim.step(200)
    # along the minor axis g is the exact distance: the centre stops at y = b + r
    assert np.allclose(sim.positions[0], [0.0, 1.0 + r], atol=1e-9)


def test_noisy_crowd_never_enters_the_ellipse() -> None:
    a, b, r = 2.0, 1.0, 0.15
    ang = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    pos = np.stack([3.2 * np.cos(ang), 2.2 * np.sin(ang)], axis=1)
    scene = sc.Scene.from_dict({"agents": {"positions": pos.tolist(), "radius": r},
                                "drift": {"kind": "goal", "goal": [0, 0], "speed": 1.0},
                                "noise": {"sigma": 0.2}}).with_constraints(Ellipse(a, b))
    sim = sc.Simulator(scene, dt=0.01, seed=2)
    for _ in range(150):
        sim.step()
        assert gaps(scene.geometry, sim.t, sim.positions, scene.radii(sim.t)).min_gap >= -1e-9
    # the true distance to the ellipse (g is a lower bound of it) is at least r; sampling
    # the boundary every 3e-5 rad overestimates the distance by at most a * (3e-5)^2 / 2
    assert true_distance(sim.positions, a, b).min() >= r - 1e-9
    assert true_distance(sim.positions, a, b).min() < r + 0.05  # they pressed on it


def test_bad_constraints_and_specs_are_refused() -> None:
    base = sc.Scene.from_dict({"agents": {"positions": [[0.0, 0.5]], "radius": 0.2}})
    with pytest.raises(SceneError, match="has no method value"):
        base.with_constraints(object())
    with pytest.raises(SceneError) as err:  # the agent starts inside
        base.with_constraints(Ellipse(3.0, 1.0))
    assert "constraints[0] (ellipse)" in str(err.value)

    class Bad(Ellipse):
        def value(self, t: float, q: np.ndarray) -> np.ndarray:
            return np.zeros(len(q) + 1)

    far = sc.Scene.from_dict({"agents": {"positions": [[0.0, 5.0]], "radius": 0.2}})
    with pytest.raises(SceneError, match="returned shape"):
        far.with_constraints(Bad(1.0, 1.0))
    ok = far.with_constraints(Ellipse(1.0, 1.0))
    assert ok.spec["constraints"] == ["ellipse"]
    with pytest.raises(SceneError, match="with_constraints"):
        sc.Scene.from_dict(ok.spec)
