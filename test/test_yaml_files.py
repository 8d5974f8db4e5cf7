"""YAML is parsed with libyaml's loader when PyYAML has it, with the same data and errors that
still name the line and column."""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

import sweep_core as sc
from sweep_core.model import yaml_files
from sweep_core.model.scene import Scene, default_scene_path
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
    class Pure(yaml.SafeLoader):
        pass

    Pure.add_implicit_resolver("tag:yaml.org,2002:float", yaml_files.EXPONENT_FLOAT,
                               list("-+0123456789."))
    assert same(load_yaml(text), yaml.load(text, Loader=Pure))


def test_exponent_notation_is_a_number():
    text = "a: 1e5\nb: 5e-2\nc: -2E+3\nd: .5e1\ne: 1.5e-3\nf: [1e-3, 2]\ng: '1e5'\nh: 1e\ni: e5\n"
    assert load_yaml(text) == {"a": 1e5, "b": 0.05, "c": -2000.0, "d": 5.0, "e": 1.5e-3,
                               "f": [1e-3, 2], "g": "1e5", "h": "1e", "i": "e5"}
    # YAML 1.1 (PyYAML's own loaders, left unchanged) reads most of them as text
    assert yaml.load(text, Loader=yaml.SafeLoader)["b"] == "5e-2"


def test_exponent_in_a_scene_is_the_number():
    base = default_scene_path().read_text()
    assert "sigma: 0.05" in base
    a = Scene.from_yaml_text(base)
    b = Scene.from_yaml_text(base.replace("sigma: 0.05", "sigma: 5e-2"))
    assert np.all(b.sigma == a.sigma) and np.all(a.sigma == 0.05)


def test_a_whole_number_written_as_a_float_is_named_so():
    spawn = ("name: s\nagents:\n  spawn: {region: {kind: rectangle, min: [0, 0], max: [5, 5]}, "
             "count: 2e1, radius: 0.2, seed: 0}\n")
    with pytest.raises(sc.SceneError) as err:
        Scene.from_yaml_text(spawn)
    assert "agents.spawn.count" in str(err.value) and "20.0" in str(err.value)
    assert "exponent" in str(err.value)


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


def alias_bomb(levels: int, width: int = 9) -> str:
    """A description of nested aliases: level k repeats level k - 1 ``width`` times, so the
    last stands for width^levels numbers in a few hundred bytes."""
    rows = [f"l0: &a0 [{', '.join(['1'] * width)}]"]
    rows += [f"l{k}: &a{k} [{', '.join([f'*a{k - 1}'] * width)}]" for k in range(1, levels)]
    return "agents: {positions: [[0, 0]], radius: 0.2}\ndescription: {" + ", ".join(rows) + "}\n"


def test_alias_bomb_is_refused_before_it_is_expanded():
    """10 levels of 9 aliases stand for 9^10 (3.5e9) numbers in 600 bytes; the refusal names
    the limit and the line, and comes before anything is composed."""
    text = alias_bomb(10)
    assert len(text) < 700
    with pytest.raises(yaml_files.YAMLLimitError) as err:
        load_yaml(text)
    assert "aliases repeat more than 100000 nodes" in yaml_problem(err.value)
    with pytest.raises(sc.SceneError) as err:
        sc.Scene.from_yaml_text(text, source="bomb.yaml")
    msg = str(err.value)
    assert msg.startswith("scene: bomb.yaml is not valid YAML: line 2 column ") and "\n" not in msg
    assert "(the limit MAX_ALIAS_NODES" in msg and "(fix: use fewer, smaller aliases)" in msg


def test_few_small_aliases_still_load():
    text = ("agents: {positions: [[0, 0], [1, 0]], radius: &r 0.2}\n"
            "walls: [{kind: segment, a: &a [-2, 1], b: [2, 1]}, {kind: segment, a: *a, "
            "b: [-2, 3]}]\nobstacles: [{kind: circle, center: [3, 3], radius: *r}]\n")
    scene = sc.Scene.from_yaml_text(text)
    assert scene.spec["walls"][1]["a"] == [-2.0, 1.0] and scene.spec["obstacles"][0]["radius"] == 0.2


def test_more_aliases_than_the_limit_are_refused():
    text = "a: &a 1\nb: [" + ", ".join(["*a"] * (yaml_files.MAX_ALIASES + 1)) + "]\n"
    with pytest.raises(yaml_files.YAMLLimitError, match="more than 1000 aliases"):
        load_yaml(text)


def test_a_document_of_more_nodes_than_the_limit_is_refused_before_it_is_composed(
        monkeypatch):
    """Every scalar, key, list and mapping counts (the document's top mapping, its key, the
    list and its items): one node over MAX_NODES is refused with its line, at the limit the
    text loads. The limit is lowered here; its value bounds the memory of composing."""
    monkeypatch.setattr(yaml_files, "MAX_NODES", 1000)
    at_limit = "x: [" + ", ".join(["0"] * (1000 - 3)) + "]\n"
    assert len(load_yaml(at_limit)["x"]) == 997
    with pytest.raises(sc.SceneError) as err:
        sc.Scene.from_yaml_text("x: [" + ", ".join(["0"] * (1000 - 2)) + "]\n",
                                source="long.yaml")
    msg = str(err.value)
    assert msg.startswith("scene: long.yaml is not valid YAML: line 1 column ")
    assert "more than 1000 values, keys, lists and mappings in one document (the limit " \
        "MAX_NODES)" in msg and "(fix: give long per-agent lists by a rule" in msg
    # aliases count once each here (their expansion has its own limit)
    assert load_yaml("a: &a 1\nb: [" + ", ".join(["*a"] * 990) + "]\n") is not None


@pytest.mark.parametrize("depth", [yaml_files.MAX_DEPTH + 1, 1000])
def test_deep_nesting_is_refused_with_its_line(depth):
    text = "agents: {positions: [[0, 0]], radius: 0.2}\ndescription: " + "[" * depth + \
        "]" * depth + "\n"
    with pytest.raises(sc.SceneError) as err:
        sc.Scene.from_yaml_text(text)
    msg = str(err.value)
    assert "line 2 column 77: nesting deeper than 64 levels of lists and mappings" in msg, msg
    assert "(fix: write the data with fewer levels" in msg


def test_nesting_within_the_limit_loads():
    inner = "[" * (yaml_files.MAX_DEPTH - 1) + "1" + "]" * (yaml_files.MAX_DEPTH - 1)
    assert load_yaml(f"x: {inner}\n")["x"] is not None


def test_5000_nested_brackets_in_sweep_run_are_one_line_not_a_crash(tmp_path):
    """The loader composes recursively: 50 000 nested brackets crashed the process (SIGSEGV)
    and 1000 gave a RecursionError traceback. In a subprocess: exit code 2, one line."""
    import subprocess
    import sys
    scene = tmp_path / "deep.yaml"
    scene.write_text("agents: {positions: [[0, 0]], radius: 0.2}\ndescription: "
                     + "[" * 5000 + "]" * 5000 + "\n")
    proc = subprocess.run([sys.executable, "-m", "sweep_core.cli", "run", str(scene), "--t-end",
                           "0.1", "--out", str(tmp_path / "out.mcap")],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-2000:])
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "nesting deeper than 64 levels" in lines[0], proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr and not (tmp_path / "out.mcap").exists()


@pytest.mark.parametrize("text, where, key", [
    ("agents: {positions: [[0, 0]], radius: 0.2}\nname: a\nname: b\n", "line 3 column 1", "name"),
    ("agents:\n  positions: [[0, 0]]\n  radius: 0.2\n  radius: 0.3\n", "line 4 column 3",
     "radius"),
    ("agents: {positions: [[0, 0]], radius: 0.2}\nwalls:\n  - {kind: segment, a: [0, 1], "
     "b: [1, 1], a: [0, 2]}\n", "line 3 column 43", "a"),
])
def test_a_key_given_twice_is_refused_with_its_line(text, where, key):
    with pytest.raises(sc.SceneError) as err:
        sc.Scene.from_yaml_text(text)
    msg = str(err.value)
    assert f"{where}: key '{key}' is given twice in one mapping (first at line" in msg, msg
    assert msg.endswith("(fix: remove one of them)")


def test_the_same_key_in_different_mappings_is_fine():
    scene = sc.Scene.from_yaml_text("agents: {positions: [[0, 0]], radius: 0.2}\nwalls:\n"
                                    "  - {kind: segment, a: [-1, 1], b: [1, 1]}\n"
                                    "  - {kind: segment, a: [-1, 2], b: [1, 2]}\n")
    assert len(scene.spec["walls"]) == 2
