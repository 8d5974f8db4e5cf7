"""The bundled scene gallery: every scene in it runs, ``sweep scenes`` lists each one as its
index says, every scene whose people walk somewhere uses the validated speed law (the pure
model one key away), and ``sweep run NAME`` runs a bundled scene by name when no such file
exists."""
import importlib.util
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from sweep_core.cli import build_parser, main
from sweep_core.errors import SceneError
from sweep_core.model.gallery import bundled_scenes, resolve_scene_path, scenes_dir
from sweep_core.model.scene import Scene, load_scene
from sweep_core.model.speed_law import headway_from_spec
from sweep_core.model.yaml_files import load_yaml
from sweep_core.numerics.simulator import Simulator

REPO = Path(__file__).resolve().parents[1]
SCENES = bundled_scenes()
#: what the gallery must show at least (the docs' gallery page shows each)
REQUIRED = {"room_door", "corridor_groups", "bottleneck", "four_exit_hall", "crossing_flows",
            "moving_obstacle", "map_two_rooms"}


def test_the_index_lists_every_bundled_scene_file_and_nothing_else() -> None:
    files = {p.stem for p in scenes_dir().glob("*.yaml")} - {"gallery"}
    names = [s.name for s in SCENES]
    assert len(names) == len(set(names))
    assert {n for n in names if "/" not in n} == files
    # entries in a folder (the RiMEA scenes of sweep verify) name files that exist there
    assert all((scenes_dir() / f"{n}.yaml").is_file() for n in names)
    assert REQUIRED <= files
    assert resolve_scene_path("rimea/rimea06_corner") == scenes_dir() / "rimea/rimea06_corner.yaml"


@pytest.mark.parametrize("entry", SCENES, ids=[s.name for s in SCENES])
def test_every_gallery_scene_runs_a_few_steps(entry) -> None:
    scene = load_scene(entry.name)
    assert scene.n_agents == entry.agents
    sim = Simulator(scene, dt=0.01, seed=0)
    start = sim.positions.copy()
    sim.step(3)
    assert sim.t == pytest.approx(0.03)
    assert sim.state.min_gap >= -1e-9
    # the scene's drift moves its crowd (none of them is a scene of agents standing still)
    assert np.max(np.hypot(*(sim.positions - start).T)) > 1e-3


def test_sweep_scenes_lists_each_with_agents_and_model(capsys) -> None:
    """Agents, model and what each shows; no run time (it depends on the machine)."""
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    table = out.split("\n\n")[0]   # the first table (the second says why each model)
    rows = {line.split()[0]: line.split() for line in table.splitlines() if line.strip()}
    for entry in SCENES:
        row = rows[entry.name]
        assert int(row[1]) == entry.agents
        assert " ".join(row[2:4]) == entry.model or row[2] == entry.model
        assert entry.shows in out and entry.why in out
    assert "run s" not in out and "measured on" not in out


def test_sweep_run_name_runs_the_bundled_scene(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["run", "bottleneck", "--t-end", "0.02", "--out", "b.mcap", "--quiet"]) == 0
    summary = json.loads(Path("b.summary.json").read_text())
    assert summary["status"] == "completed"
    assert summary["scene"] == "bottleneck"
    assert summary["agents"] == next(s.agents for s in SCENES if s.name == "bottleneck")


def test_a_file_of_that_name_wins_over_the_bundled_scene(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    assert resolve_scene_path("bottleneck") == scenes_dir() / "bottleneck.yaml"
    assert resolve_scene_path("bottleneck.yaml") == scenes_dir() / "bottleneck.yaml"
    shutil.copy(scenes_dir() / "room_door.yaml", tmp_path / "bottleneck.yaml")
    assert resolve_scene_path("bottleneck.yaml") == Path("bottleneck.yaml")
    assert load_scene("bottleneck.yaml").n_agents == 200
    # a path with a folder is never a bundled name
    with pytest.raises(SceneError, match="sub/corridor_groups.yaml"):
        load_scene("sub/corridor_groups.yaml")


def test_an_unknown_name_is_a_one_line_error(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    assert main(["run", "no_such_scene", "--out", "x.mcap", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("sweep: error:") and "no_such_scene" in err
    assert all(s.name in err for s in SCENES)   # the fix names the bundled scenes
    assert len(err.splitlines()) == 1


def test_run_help_says_a_name_is_a_bundled_scene() -> None:
    run = build_parser()._subparsers._group_actions[0].choices["run"]
    assert "bundled scene" in " ".join(run.format_help().split())


def test_the_gallery_page_shows_every_scene_with_its_picture() -> None:
    spec = importlib.util.spec_from_file_location("docs_gallery", REPO / "docs" / "gallery.py")
    page = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(page)
    # the page is what docs/gallery.py writes from the index today (regenerate it if not)
    assert (REPO / "docs" / "gallery.md").read_text() == page.page_text()
    for entry in SCENES:
        assert (REPO / "docs" / "gallery" / f"{entry.name}.png").stat().st_size > 10_000


def test_the_node_takes_a_bundled_scene_name(tmp_path, monkeypatch) -> None:
    params = pytest.importorskip("sweep_ros.params")
    monkeypatch.chdir(tmp_path)
    assert params.check_value("scene", "corridor_groups") is None
    problem = params.check_value("scene", "no_such_scene")
    assert problem.startswith("scene:") and "corridor_groups" in problem
    assert "no file" in params.check_value("scene", "/no/such/scene.yaml")


def _walks(scene: Scene) -> bool:
    """Whether some agent of the scene wishes a velocity at t = 0 (walks somewhere)."""
    return bool(np.any(scene.drift(0.0, scene.positions) != 0.0))


@pytest.mark.parametrize("entry", SCENES, ids=[s.name for s in SCENES])
def test_every_walking_scene_uses_the_validated_speed_law(entry) -> None:
    scene = load_scene(entry.name)
    spec = load_yaml(entry.path.read_text())
    headway = (spec.get("flows") or {}).get("headway")
    # people who walk to a goal or an exit walk with the speed law; the index says so
    assert _walks(scene) == (entry.model == "speed law"), entry.why
    assert (headway is not None) == (entry.model == "speed law")
    assert entry.why
    if headway is None:
        return
    # the law sweep verify validates: csm at its default parameters, as the scene runs it
    assert headway == {}
    law = scene.flows
    validated = headway_from_spec({})
    assert law.law == validated["law"] == "csm"
    assert (law.time_gap, law.repulsion, law.repulsion_range, law.lateral, law.follow) == (
        validated["time_gap"], validated["repulsion"], validated["repulsion_range"],
        validated["lateral"], validated["follow"])
    # the pure model is one key away: the same scene without flows.headway loads and runs
    del spec["flows"]["headway"]
    pure = Scene.from_dict(spec, name=entry.name, base=entry.path.parent)
    assert pure.flows is None or pure.flows.time_gap is None
    sim = Simulator(pure, dt=0.01, seed=0)
    start = sim.positions.copy()
    sim.step(2)
    assert sim.state.min_gap >= -1e-9
    assert np.max(np.hypot(*(sim.positions - start).T)) > 1e-3
