"""``sweep compare`` says what two runs share (scene, seed, noise path) and calls the distance
the pathwise error only when they share the scene and the path."""
from __future__ import annotations

import json

from sweep_core.analysis.compare import spec_differences
from sweep_core.cli import main
from sweep_core.model.gallery import resolve_scene_path
from sweep_core.model.yaml_files import dump_yaml, load_yaml


def test_spec_differences_name_the_keys():
    a = {"name": "a", "drift": {"kind": "goal", "speed": 1.3}, "noise": {"sigma": 0.05}}
    b = {"name": "b", "drift": {"kind": "uniform", "velocity": [1.0, 0.0]},
         "noise": {"sigma": 0.5}}
    assert spec_differences(a, b) == ["drift.kind", "drift.speed", "drift.velocity",
                                      "noise.sigma"]
    assert spec_differences(a, dict(a, name="other", description="x")) == []


def test_two_scenes_on_one_seed_are_not_a_pathwise_error(tmp_path, capsys):
    """room_door against a copy with another drift and sigma 0.5, same seed and dt. Before:
    'shared path yes ... (the distance is the pathwise error)', exit 0."""
    spec = load_yaml(resolve_scene_path("room_door").read_text())
    spec["drift"] = {"kind": "uniform", "velocity": [1.0, 0.0]}
    spec["noise"] = {"sigma": 0.5}
    spec["name"] = "room_door_copy"
    copy = tmp_path / "copy.yaml"
    copy.write_text(dump_yaml(spec))
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    for scene, out in (("room_door", a), (str(copy), b)):
        assert main(["run", scene, "--t-end", "0.2", "--dt", "0.05", "--seed", "0", "--out",
                     str(out), "--quiet"]) == 0
    capsys.readouterr()
    assert main(["compare", str(a), str(b), "--no-plots", "--quiet"]) == 0
    out = capsys.readouterr().out
    lines = {ln[:18].strip(): ln[19:] for ln in out.splitlines()}
    assert lines["scene"].startswith("DIFFERENT:") and "drift" in lines["scene"], out
    assert "noise.sigma" in lines["scene"], out
    assert lines["seed"] == "same: 0", out
    assert lines["distance"].startswith("NOT a pathwise error (the scenes differ)"), out
    assert "is the pathwise error" not in out and "statistics" in lines["distance"]

    assert main(["compare", str(a), str(a), "--no-plots", "--quiet", "--json"]) == 0
    same = json.loads(capsys.readouterr().out)
    assert same["pathwise"] is True and same["sup_m"] == 0.0
    assert same["same_scene"].startswith("same") and same["shared_path"].startswith("shared")
    assert same["distance"].startswith("the pathwise error")


def _no_state(path):
    """A recording of the project's writer with its channels and no recorded state."""
    from sweep_core.io import topics
    from sweep_core.io.metadata import run_metadata
    from sweep_core.io.recording.background import BackgroundRecorder
    from sweep_core.model.scene import Scene
    from sweep_core.numerics.simulator import Simulator

    scene = Scene.from_dict({"agents": {"positions": [[0.0, 0.0]], "radius": 0.2}})
    with BackgroundRecorder(path, metadata=run_metadata(scene, Simulator(scene, dt=0.05,
                                                                         seed=0), None)) as r:
        for name, msgtype in topics.TYPES.items():
            r.add_channel("/" + name, msgtype)
    return path


def test_bad_recordings_are_refused_in_one_line(tmp_path, capsys):
    """Before: a recording without a state was 'no recorded time in common' with the other,
    and a 0-byte file 'cut short before its first flush'."""
    empty, foreign = tmp_path / "empty.mcap", tmp_path / "foreign.mcap"
    empty.write_bytes(b"")
    foreign.write_text("t,x,y\n0,1,2\n")
    none = _no_state(tmp_path / "none.mcap")
    for bad, problem in ((empty, "the file is empty (0 bytes)"), (foreign, "not an MCAP file"),
                         (none, "holds no recorded state")):
        assert main(["compare", str(bad), str(none), "--no-plots", "--quiet"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"sweep: error: {bad}: {problem}"), err
        assert "fix:" in err[0]
    assert not list(tmp_path.glob("*.csv"))
