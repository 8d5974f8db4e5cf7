"""YAML is parsed with libyaml's loader when PyYAML has it, with the same data and errors that
still name the line and column."""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

import sweep_core as sc
from sweep_core.model import yaml_files
from sweep_core.model.scene import default_scene_path
from sweep_core.model.yaml_files import load_yaml, yaml_problem

HAS_LIBYAML = bool(getattr(yaml, "__with_libyaml__", False)) and hasattr(yaml, "CSafeLoader")

MIXED = """\
name: mixed
agents:
  positions: [[0.0, -1.5e-3], [1, 2], [.5, -.25]]
  radius: [0.2, 2e-1, 1_0.5]
flags: {a: yes, b: off, c: true, d: null, e: ~}
specials: [.inf, -.Inf, .nan, 0x1f, 0o17, 1:30, "quoted 1.5", '2020-01-01']
nested:
  - {kind: halfplane, normal: [0, 1], offset: -1}
  - kind: segment
    a: [-2, 3]
    b: [2, 3]
"""


def same(a, b) -> bool:
    """Equality that counts nan == nan."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    if isinstance(a, dict) and isinstance(b, dict):
        return list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


@pytest.mark.skipif(not HAS_LIBYAML, reason="PyYAML built without libyaml")
def test_the_c_loader_and_dumper_are_used_when_available():
    assert yaml_files.SAFE_LOADER is yaml.CSafeLoader
    assert yaml_files.SAFE_DUMPER is yaml.CSafeDumper


@pytest.mark.parametrize("text", [MIXED, default_scene_path().read_text()],
                         ids=["mixed", "room_door"])
def test_load_equals_the_pure_python_loader(text):
    assert same(load_yaml(text), yaml.load(text, Loader=yaml.SafeLoader))


def test_dump_loads_back_as_the_pure_python_dumper_writes():
    data = yaml.load(MIXED, Loader=yaml.SafeLoader)
    text = yaml_files.dump_yaml(data)
    assert same(yaml.load(text, Loader=yaml.SafeLoader), data)
    assert text.startswith("name: mixed\nagents:")  # key order kept


@pytest.mark.skipif(not HAS_LIBYAML, reason="PyYAML built without libyaml")
def test_scene_files_are_parsed_by_libyaml(tmp_path, monkeypatch):
    """The pure-Python parser is made unusable: a scene file (and a recorded scene's text)
    still loads, so it went through libyaml, and equals what the pure-Python loader gives."""
    scene = sc.Scene.from_yaml(default_scene_path())
    path = tmp_path / "s.yaml"
    path.write_text(scene.to_yaml())

    def refuse(*args, **kwargs):
        raise AssertionError("the pure-Python YAML parser was used")

    monkeypatch.setattr(yaml.parser.Parser, "__init__", refuse)
    monkeypatch.setattr(yaml.emitter.Emitter, "__init__", refuse)
    again = sc.Scene.from_yaml(path)
    recorded = sc.Scene.from_yaml_text(scene.to_yaml())
    monkeypatch.undo()
    for other in (again, recorded):
        assert np.array_equal(other.positions, scene.positions)
        assert other.spec == scene.spec


@pytest.mark.parametrize("loader", [yaml.SafeLoader, yaml_files.SAFE_LOADER],
                         ids=["python", "default"])
@pytest.mark.parametrize("text, where", [
    ("agents: {positions: [[0, 0]], radius: [0.2\nname: x\n", "line 2 column 5"),
    ("agents:\n  positions: [[0, 0]]\n radius: 0.2\n", "line 3 column 2"),
    ("name: \"a\\qb\"\n", "line 1 column "),
    ("agents:\n\tpositions: []\n", "line 2 column 1"),
])
def test_errors_name_line_and_column_with_either_loader(loader, text, where):
    with pytest.raises(yaml.YAMLError) as err:
        yaml.load(text, Loader=loader)
    problem = yaml_problem(err.value)
    assert problem.startswith(where), problem
    assert "\n" not in problem


def test_broken_scene_file_says_file_line_and_fix(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nagents: {positions: [[0, 0]], radius: [0.2\nnoise: {}\n")
    with pytest.raises(sc.SceneError) as err:
        sc.Scene.from_yaml(bad)
    msg = str(err.value)
    assert msg.startswith(f"scene: {bad} is not valid YAML: line 3 column ")
    assert msg.endswith("(fix: correct the YAML syntax at that line)")
    assert "\n" not in msg and "<unicode string>" not in msg


def test_binary_scene_file_is_refused(tmp_path):
    bad = tmp_path / "bin.yaml"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe")
    with pytest.raises(sc.SceneError, match="is not UTF-8 text"):
        sc.Scene.from_yaml(bad)
