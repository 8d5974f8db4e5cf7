"""Invalid scenes are refused before anything steps, with the field named."""
from __future__ import annotations

import re

import numpy as np
import pytest
from scenes import GOOD, MISSING, variant

import sweep_core as sc
from sweep_core.model import radii


def test_good_scene_loads_and_round_trips(tmp_path):
    scene = sc.Scene.from_dict(GOOD)
    assert scene.n_agents == 3
    path = tmp_path / "s.yaml"
    path.write_text(scene.to_yaml())
    again = sc.Scene.from_yaml(path)
    assert np.array_equal(again.positions, scene.positions)
    assert again.spec == scene.spec


@pytest.mark.parametrize("path, value, field, words", [
    ("agents.positions", [[0, 0], [0.3, 0], [0, 1]], "agents.positions", "agents 0 and 1 overlap by 0.100 m"),
    ("agents.positions", [[0, 0], [0, 0], [0, 1]], "agents.positions", "coincident centres"),
    ("agents.positions", [[0, 0], [float("nan"), 0], [0, 1]], "agents.positions", "non-finite"),
    ("agents.positions", [[0, 0, 0]], "agents.positions", "shape"),
    ("agents.radius", 0.0, "agents.radius", "> 0"),
    ("agents.radius", [0.2, -0.1, 0.2], "agents.radius", "agent 1"),
    ("agents.radius", [0.2, 0.2], "agents.radius", "shape"),
    ("agents.radius", MISSING, "agents.radius", "missing"),
    ("agents.radius_law", {"kind": "cubic"}, "agents.radius_law.kind", "unknown kind 'cubic'"),
    ("agents.radius_law", {"kind": "sine", "amplitude": 0.3, "period": 1.0}, "agents.radius_law.amplitude", "<= 0 at t = 0.616"),
    ("agents.radius_law", {"kind": "sine", "amplitude": 0.01, "period": 0.0}, "agents.radius_law.period", "> 0"),
    ("walls.0", {"kind": "halfplane", "normal": [0, 1], "offset": -0.1}, "walls[0]", "agent 0 at [0, 0] (radius 0.2 m) violates walls[0]"),
    ("walls.0", {"kind": "halfplane", "normal": [0, 0], "offset": -1.0}, "walls[0].normal", "zero vector"),
    ("walls.1", {"kind": "segment", "a": [-2, 1.1], "b": [2, 1.1]}, "walls[1]", "agent 2 at [0, 1] (radius 0.2 m) violates walls[1] (segment)"),
    ("walls.1", {"kind": "segment", "a": [1, 1], "b": [1, 1]}, "walls[1]", "zero length"),
    ("walls.1", {"kind": "door"}, "walls[1].kind", "unknown kind 'door'"),
    ("obstacles.0", {"kind": "circle", "center": [1, 0.5], "radius": 0.4}, "obstacles[0]", "violates obstacles[0]"),
    ("obstacles.0", {"kind": "circle", "center": [3, 3], "radius": float("inf")}, "obstacles[0].radius", "finite"),
    ("drift", {"kind": "vortex"}, "drift.kind", "unknown kind 'vortex'"),
    ("drift", {"kind": "uniform", "velocity": [1, 2, 3]}, "drift.velocity", "shape"),
    ("drift", {"kind": "goal", "goal": [1, 1]}, "drift.speed", "missing"),
    ("noise", {"sigma": -1}, "noise.sigma", ">= 0"),
    ("noise", {"sigma": "loud"}, "noise.sigma", "number"),
    ("noise", {"amplitude": 1}, "noise", "unknown keys"),
    ("colour", "red", "scene", "unknown keys ['colour']"),
])
def test_refused_with_the_field_named(path, value, field, words):
    with pytest.raises(sc.SceneError) as err:
        sc.Scene.from_dict(variant(path, value))
    assert err.value.field == field
    assert words in str(err.value)
    assert str(err.value).startswith(field)


@pytest.mark.parametrize("kwargs, field", [
    ({"dt": 0.0}, "dt"), ({"dt": -0.01}, "dt"), ({"dt": float("nan")}, "dt"),
    ({"seed": -1}, "seed"), ({"scheme": "rk4"}, "scheme"),
])
def test_simulator_options_refused(kwargs, field):
    with pytest.raises(sc.SceneError) as err:
        sc.Simulator(sc.Scene.from_dict(GOOD), **kwargs)
    assert err.value.field == field


def test_shrinking_radii_refused_within_the_horizon():
    d = variant("agents.radius_law", {"kind": "linear", "rate": -0.1})
    sim = sc.Simulator(sc.Scene.from_dict(d), dt=0.01)
    with pytest.raises(sc.SceneError) as err:
        sim.run(3.0)
    assert err.value.field == "agents.radius_law.rate"
    assert "shrinks agent 0's radius 0.2 m to 0 at t = 2 s, within the horizon 3 s" in str(err.value)
    assert "set agents.radius_law.rate to more than -0.0666667 m/s" in str(err.value)
    assert sim.n_steps == 0  # refused before stepping
    d["horizon"] = 5.0
    with pytest.raises(sc.SceneError):
        sc.Scene.from_dict(d)


@pytest.mark.parametrize("amplitude, period", [(0.3, 1.0), (-0.3, 2.0), (0.2, 1.0), (1.5, 4.0)])
def test_sine_law_reaching_zero_says_when_and_by_how_much(amplitude, period):
    """It used to say 'radii reach -0.1 m <= 0 within the horizon 0 s'."""
    d = variant("agents.radius_law", {"kind": "sine", "amplitude": amplitude, "period": period})
    with pytest.raises(sc.SceneError) as err:
        sc.Scene.from_dict(d)
    msg = str(err.value)
    assert err.value.field == "agents.radius_law.amplitude" and "horizon" not in msg
    assert f": {amplitude:g} m is not below the smallest base radius 0.2 m (agent 0)" in msg
    t = float(re.search(r"would become <= 0 at t = ([0-9.e+-]+) s", msg).group(1))
    law = radii.Sine(amplitude=amplitude, period=period)
    assert 0.2 + law.offset(t) == pytest.approx(0.0, abs=1e-5)  # the first zero, not a later one
    assert all(0.2 + law.offset(s) > 0 for s in np.linspace(0.0, t, 500)[:-1])
    assert msg.endswith("(fix: set agents.radius_law.amplitude to less than 0.2 m in absolute "
                        "value, or make the radii larger)")


def test_bad_increments_refused():
    sim = sc.Simulator(sc.Scene.from_dict(GOOD))
    with pytest.raises(sc.SceneError, match="dB"):
        sim.step(dB=np.zeros((2, 2)))
    with pytest.raises(sc.SceneError, match="dB"):
        sim.step(dB=np.full((3, 2), np.inf))
    assert sim.n_steps == 0


def test_unreadable_file(tmp_path):
    with pytest.raises(sc.SceneError, match="cannot read"):
        sc.Scene.from_yaml(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("agents: [unclosed")
    with pytest.raises(sc.SceneError, match="not valid YAML"):
        sc.Scene.from_yaml(bad)
