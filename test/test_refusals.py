"""Every refusal of a scene names the field, the offending value and the fix, on one line, with
numbers shown plainly (never numpy reprs such as ``np.float64(-0.1)`` or ``array(...)``)."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest
from scenes import GOOD, MISSING, variant

import sweep_core as sc
from sweep_core import checks
from sweep_core.errors import show

#: (fault, dotted path in GOOD, bad value, field named, the value as the message shows it)
FAULTS = [
    ("negative radius", "agents.radius", -0.1, "agents.radius", "got -0.1"),
    ("negative radius of one agent", "agents.radius", [0.2, -0.1, 0.2], "agents.radius",
     "agent 1 has -0.1"),
    ("numpy negative radius", "agents.radius", np.float64(-0.25), "agents.radius", "got -0.25"),
    ("radius not a number", "agents.radius", "big", "agents.radius", "'big'"),
    ("radius list of the wrong length", "agents.radius", [0.2, 0.2], "agents.radius",
     "got [0.2, 0.2]"),
    ("missing radius", "agents.radius", MISSING, "agents.radius", "missing"),
    ("NaN position", "agents.positions", [[0, 0], [math.nan, 0], [0, 1]], "agents.positions",
     "nan at index [1, 0]"),
    ("positions of 3 coordinates", "agents.positions", [[0, 0, 0]], "agents.positions",
     "shape (1, 3)"),
    ("overlapping agents", "agents.positions", [[0, 0], [0.3, 0], [0, 1]], "agents.positions",
     "centres [0, 0] and [0.3, 0]"),
    ("coincident agents", "agents.positions", [[0, 0], [0, 0], [0, 1]], "agents.positions",
     "coincident centres [0, 0]"),
    ("negative preferred speed", "agents.speed", -2, "agents.speed", "got -2"),
    ("unknown radius law", "agents.radius_law", {"kind": "cubic"}, "agents.radius_law.kind",
     "'cubic'"),
    ("sine law larger than the radius", "agents.radius_law",
     {"kind": "sine", "amplitude": 0.3, "period": 1.0}, "agents.radius_law.amplitude",
     "0.3 m is not below the smallest base radius 0.2 m"),
    ("sine law of period 0", "agents.radius_law",
     {"kind": "sine", "amplitude": 0.01, "period": 0.0}, "agents.radius_law.period", "got 0"),
    ("linear law rate not a number", "agents.radius_law", {"kind": "linear", "rate": "fast"},
     "agents.radius_law.rate", "'fast'"),
    ("linear law with a sine key", "agents.radius_law",
     {"kind": "linear", "rate": 0.1, "period": 2}, "agents.radius_law", "['period']"),
    ("agent inside a half-plane wall", "walls.0",
     {"kind": "halfplane", "normal": [0, 1], "offset": -0.1}, "walls[0]",
     "agent 0 at [0, 0] (radius 0.2 m) violates walls[0] (halfplane) by 0.100 m"),
    ("agent inside a segment wall", "walls.1", {"kind": "segment", "a": [-2, 1.1], "b": [2, 1.1]},
     "walls[1]", "agent 2 at [0, 1]"),
    ("agent inside an obstacle", "obstacles.0", {"kind": "circle", "center": [1, 0.5],
                                                 "radius": 0.4}, "obstacles[0]", "at [1, 0]"),
    ("zero wall normal", "walls.0", {"kind": "halfplane", "normal": [0, 0], "offset": -1.0},
     "walls[0].normal", "[0, 0]"),
    ("segment of zero length", "walls.1", {"kind": "segment", "a": [1, 1], "b": [1, 1]},
     "walls[1]", "[1, 1]"),
    ("unknown wall kind", "walls.1", {"kind": "door"}, "walls[1].kind", "'door'"),
    ("walls not a list", "walls", {"kind": "segment"}, "walls", "{kind: 'segment'}"),
    ("infinite obstacle radius", "obstacles.0", {"kind": "circle", "center": [3, 3],
                                                 "radius": math.inf}, "obstacles[0].radius",
     "got inf"),
    ("unknown drift kind", "drift", {"kind": "vortex"}, "drift.kind", "'vortex'"),
    ("drift velocity of 3 components", "drift", {"kind": "uniform", "velocity": [1, 2, 3]},
     "drift.velocity", "[1, 2, 3]"),
    ("drift goal without speed", "drift", {"kind": "goal", "goal": [1, 1]}, "drift.speed",
     "missing"),
    ("irregular drift grid", "drift", {"kind": "grid", "x": [0, 1, 3], "y": [0],
                                       "vx": [[0, 0, 0]], "vy": [[0, 0, 0]]},
     "drift.x", "[0, 1, 3]"),
    ("unsorted drift grid", "drift", {"kind": "grid", "x": [0, 2, 1], "y": [0],
                                      "vx": [[0, 0, 0]], "vy": [[0, 0, 0]]},
     "drift.x", "[0, 2, 1]"),
    ("per-agent drift for 2 of 3 agents", "drift",
     {"kind": "per_agent", "velocities": [[0, 0], [1, 1]]}, "drift.velocities", "shape (2, 2)"),
    ("negative sigma", "noise", {"sigma": -1}, "noise.sigma", "got -1"),
    ("negative sigma of one agent", "noise", {"sigma": [0.1, np.float32(-0.5), 0.1]},
     "noise.sigma", "agent 1 has -0.5"),
    ("sigma not a number", "noise", {"sigma": "loud"}, "noise.sigma", "'loud'"),
    ("unknown noise key", "noise", {"amplitude": 1}, "noise", "['amplitude']"),
    ("unknown top-level key", "colour", "red", "scene", "['colour']"),
    ("negative horizon", "horizon", -1.0, "horizon", "got -1"),
    ("agents not a mapping", "agents", [[0, 0]], "agents", "list [[0, 0]]"),
    ("wall ends at 1e16 m", "walls.1", {"kind": "segment", "a": [-1e16, 3], "b": [1e16, 3]},
     "walls[1].a[0]", "coordinate -1e+16 m is beyond the bound 10000 m"),
    ("wall end just beyond the bound", "walls.1", {"kind": "segment", "a": [-2, 3],
                                                   "b": [10000.5, 3]},
     "walls[1].b[0]", "coordinate 10000.5 m is beyond the bound 10000 m"),
    ("position of 1e308", "agents.positions", [[0, 0], [1e308, 0], [0, 1]],
     "agents.positions[1, 0]", "coordinate 1e+308 m is beyond the bound 1e+06 m"),
    ("position beyond 1e6 m", "agents.positions", [[0, 0], [1, 0], [0, -2e6]],
     "agents.positions[2, 1]", "coordinate -2e+06 m is beyond the bound 1e+06 m"),
    ("radius of 1e300", "agents.radius", [0.2, 1e300, 0.2], "agents.radius[1]",
     "radius 1e+300 m is beyond the bound"),
    ("obstacle centre beyond the bound", "obstacles.0",
     {"kind": "circle", "center": [3, 2e4], "radius": 0.5}, "obstacles[0].center[1]",
     "coordinate 20000 m"),
    ("obstacle radius beyond the bound", "obstacles.0",
     {"kind": "circle", "center": [3, 3], "radius": 1e300}, "obstacles[0].radius",
     "length 1e+300 m"),
    ("half-plane offset beyond the bound", "walls.0",
     {"kind": "halfplane", "normal": [0, 1], "offset": -1e12}, "walls[0].offset",
     "offset -1e+12 m"),
    ("polygon vertex beyond the bound", "obstacles.0",
     {"kind": "polygon", "points": [[3, 3], [4, 3], [4, 1e17]]}, "obstacles[0].points[2, 1]",
     "coordinate 1e+17 m"),
    ("goal beyond the bound", "drift", {"kind": "goal", "goal": [1e9, 0], "speed": 1.0},
     "drift.goal[0]", "coordinate 1e+09 m"),
    ("description as a mapping", "description", {"l0": [1, 1], "l1": [[1, 1], [1, 1]]},
     "description", "must be text, got dict"),
    ("description of 10 001 characters", "description", "x" * 10_001, "description",
     "has 10001 characters, more than 10000"),
    ("name as a list", "name", ["a", "b"], "name", "must be text, got list ['a', 'b']"),
]

#: phrases a fix starts with
FIX = re.compile(r"\(fix: (use|set|add|write|move|place|remove|replace|sort|give|resample|end|"
                 r"correct|for a round obstacle)\b")


def refusal(path: str, value) -> sc.SceneError:
    with pytest.raises(sc.SceneError) as err:
        sc.Scene.from_dict(variant(path, value))
    return err.value


def test_the_table_has_at_least_15_distinct_faults():
    assert len({f[0] for f in FAULTS}) == len(FAULTS) >= 15


@pytest.mark.parametrize("fault, path, value, field, shown", FAULTS, ids=[f[0] for f in FAULTS])
def test_refusal_names_field_value_and_fix(fault, path, value, field, shown):
    err = refusal(path, value)
    msg = str(err)
    assert err.field == field, msg
    assert msg.startswith(field + ": "), msg
    assert shown in msg, msg
    assert FIX.search(msg), msg
    assert err.fix and msg.endswith(f"(fix: {err.fix})"), msg
    assert "\n" not in msg


def test_no_numpy_reprs_in_refusals():
    """Values reach the validators as numpy scalars and arrays (the node, the simulator, user
    code); the messages show them as plain numbers and lists."""
    messages = [str(refusal(path, value)) for _, path, value, _, _ in FAULTS]
    np_cases = [
        ("agents.radius", np.array([0.2, -0.1, 0.2])),
        ("agents.radius", np.float64(-0.1)),
        ("agents.radius", np.array([np.nan, 0.2, 0.2])),
        ("agents.positions", np.array([[0.0, 0.0], [0.3, 0.0], [0.0, 1.0]])),
        ("agents.speed", np.float32(-1.5)),
        ("horizon", np.float64(-2.0)),
        ("noise", {"sigma": np.array([0.1, -0.2, 0.1])}),
        ("drift", {"kind": "uniform", "velocity": np.array([1.0, 2.0, 3.0])}),
        ("drift", {"kind": "goal", "goal": [0, 0], "speed": np.float64(-1.0)}),
        ("agents.radius_law", {"kind": "sine", "amplitude": np.float64(0.25), "period": 2.0}),
        ("walls.0", {"kind": "halfplane", "normal": np.zeros(2), "offset": -1.0}),
    ]
    messages += [str(refusal(path, value)) for path, value in np_cases]
    sim = sc.Simulator(sc.Scene.from_dict(GOOD))
    for call in (lambda: sim.set_sigma(np.array([0.1, np.float64(-0.3), 0.1])),
                 lambda: sc.Simulator(sc.Scene.from_dict(GOOD), dt=np.float64(-0.1)),
                 lambda: sc.Simulator(sc.Scene.from_dict(GOOD), seed=np.int64(-3))):
        with pytest.raises(sc.SceneError) as err:
            call()
        messages.append(str(err.value))
    assert any("-0.3" in m for m in messages) and any("-0.1" in m for m in messages)
    for msg in messages:
        assert "np." not in msg and "array(" not in msg and "dtype" not in msg, msg


@pytest.mark.parametrize("value, text", [
    (np.float64(-0.1), "-0.1"), (np.float32(0.5), "0.5"), (np.int64(3), "3"),
    (np.array([1.5, np.nan]), "[1.5, nan]"), (np.bool_(True), "true"),
    ([[0, 0], [np.float64(0.3), 1]], "[[0, 0], [0.3, 1]]"), (1e-9, "1e-09"), ("red", "'red'"),
    (np.arange(20.0), "[0, 1, 2, 3, 4, 5, ... (20 items)]"), (None, "null"),
])
def test_show_is_plain(value, text):
    assert show(value) == text


def test_validators_show_numpy_values_plainly():
    with pytest.raises(sc.SceneError, match=r"^x: must be > 0, got -0.1 \(fix: set x to a "):
        checks.number(np.float64(-0.1), "x", positive=True)
    with pytest.raises(sc.SceneError, match=r"^n: must be an integer >= 1, got 0\.5 \(fix: "):
        checks.integer(np.float64(0.5), "n", low=1)


def test_every_scene_refusal_in_the_model_passes_a_fix():
    """Static guard: each SceneError raised by the scene's validators is given a fix."""
    import ast
    from pathlib import Path
    root = Path(__file__).resolve().parents[1] / "sweep_core"
    files = sorted((root / "model").glob("*.py")) + [root / "checks.py"]
    missing = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "SceneError" \
                    and len(node.args) + len(node.keywords) < 3:
                missing.append(f"{path.name}:{node.lineno}")
    assert not missing, missing
