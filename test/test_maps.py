"""Occupancy maps (map_server YAML + PGM/PNG) as walls (issue 13)."""
import re
from pathlib import Path

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.errors import SceneError
from sweep_core.model.maps import OccupancyMap, map_from_spec, read_map_yaml

# 8 x 6 cells of 0.5 m: a wall all round, a 1 x 1 cell pillar at column 5, row 3 from the top;
# '#' occupied (0), '.' free (254), '?' unknown (205)
ROOM = ["########",
        "#......#",
        "#......#",
        "#....#.#",
        "#.....?#",
        "########"]
PIXEL = {"#": 0, ".": 254, "?": 205}


def write_map(tmp: Path, rows: list[str] = ROOM, fmt: str = "P5", origin: str = "[-1.0, 2.0, 0.0]",
              negate: int = 0) -> Path:
    h, w = len(rows), len(rows[0])
    values = np.array([[PIXEL[c] for c in row] for row in rows], dtype=np.uint8)
    if negate:
        values = 255 - values
    if fmt == "P5":
        (tmp / "room.pgm").write_bytes(f"P5\n# made by hand\n{w} {h}\n255\n".encode()
                                       + values.tobytes())
    else:
        body = "\n".join(" ".join(str(v) for v in row) for row in values)
        (tmp / "room.pgm").write_text(f"P2\n{w} {h}\n255\n{body}\n")
    (tmp / "room.yaml").write_text(
        f"image: room.pgm\nresolution: 0.5\norigin: {origin}\nnegate: {negate}\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    return tmp / "room.yaml"


@pytest.mark.parametrize("fmt, negate", [("P5", 0), ("P2", 0), ("P5", 1)])
def test_cells_and_walls(tmp_path: Path, fmt: str, negate: int) -> None:
    grid = read_map_yaml(write_map(tmp_path, fmt=fmt, negate=negate))
    assert grid.shape == (6, 8)
    # row 0 of the grid is the image's last row; the unknown cell counts as blocked
    expect = np.array([[c != "." for c in row] for row in ROOM[::-1]])
    assert np.array_equal(grid.blocked, expect)
    a, b = grid.segments()
    # every wall piece is axis-aligned, on the cell lines, and between a blocked and a free cell
    assert np.all((a[:, 0] == b[:, 0]) | (a[:, 1] == b[:, 1]))
    local = grid.to_local(np.concatenate([a, b])) / 0.5
    assert np.allclose(local, np.round(local))
    mid = (a + b) / 2
    normal = np.stack([b[:, 1] - a[:, 1], a[:, 0] - b[:, 0]], axis=1) / np.hypot(
        *(b - a).T)[:, None]
    side = grid.is_blocked(mid + 0.1 * normal) != grid.is_blocked(mid - 0.1 * normal)
    assert side.all()
    # total length: the free region's perimeter (6 x 4 room: 20 cells, pillar inside: 4,
    # the unknown cell cuts a corner: +0 since it replaces 2 edges by 2)
    length = float(np.hypot(*(b - a).T).sum())
    assert length == pytest.approx((20 + 4) * 0.5)


def test_agent_pushed_into_a_map_corner_stops_exactly(tmp_path: Path) -> None:
    path = write_map(tmp_path)
    scene = sc.Scene.from_dict({"map": {"yaml": str(path)},
                                "agents": {"positions": [[0.0, 3.5]], "radius": 0.2},
                                "drift": {"kind": "uniform", "velocity": [-1.0, 1.0]}})
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    sim.step(300)
    # free space starts at x = -1 + 0.5 and ends at y = 2 + 5 * 0.5 (top wall row)
    assert np.allclose(sim.positions[0], [-0.5 + 0.2, 4.5 - 0.2], atol=1e-9)


def test_noisy_crowd_stays_in_free_cells(tmp_path: Path) -> None:
    path = write_map(tmp_path)
    pos = [[-0.3 + 0.45 * i, 2.7 + 0.45 * j] for i in range(4) for j in range(4)]
    scene = sc.Scene.from_dict({"map": {"yaml": str(path)},
                                "agents": {"positions": pos, "radius": 0.15},
                                "drift": {"kind": "goal", "goal": [2.2, 4.2], "speed": 1.0},
                                "noise": {"sigma": 0.3}})
    sim = sc.Simulator(scene, dt=0.01, seed=1)
    grid = map_from_spec(scene.spec["map"], "map", None)
    for _ in range(200):
        sim.step()
        assert not grid.is_blocked(sim.positions).any()
    # the crowd went round the pillar towards the goal
    assert np.hypot(*(sim.positions.mean(axis=0) - [2.2, 4.2])) < 1.2


def test_spec_is_self_contained_and_round_trips(tmp_path: Path) -> None:
    path = write_map(tmp_path, origin="[1.0, -2.0, 0.5]")
    scene = sc.Scene.from_dict({"map": {"yaml": str(path)},
                                "agents": {"positions": [], "radius": 0.2}})
    (tmp_path / "room.pgm").unlink()  # the spec alone rebuilds the walls
    again = sc.Scene.from_dict(scene.spec)
    assert np.array_equal(again.geometry.segment_a, scene.geometry.segment_a)
    assert np.array_equal(again.geometry.segment_b, scene.geometry.segment_b)


def test_map_relative_to_the_scene_file(tmp_path: Path) -> None:
    write_map(tmp_path)
    (tmp_path / "scene.yaml").write_text(
        "map: {yaml: room.yaml}\nagents: {positions: [[0.0, 3.0]], radius: 0.2}\n")
    scene = sc.Scene.from_yaml(tmp_path / "scene.yaml")
    assert len(scene.geometry.segment_a) > 0


@pytest.mark.parametrize("position, words", [([1.75, 3.25], "blocked"), ([9.0, 9.0], "blocked")])
def test_agents_in_blocked_cells_are_refused(tmp_path: Path, position: list, words: str) -> None:
    path = write_map(tmp_path)
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict({"map": {"yaml": str(path)},
                            "agents": {"positions": [position], "radius": 0.1}})
    assert err.value.field == "agents.positions" and words in str(err.value) and err.value.fix


def test_bad_map_files_are_refused(tmp_path: Path) -> None:
    path = write_map(tmp_path)
    (tmp_path / "room.pgm").write_bytes(b"P5\n8 6\n255\n" + bytes(10))
    with pytest.raises(SceneError, match="fewer than 8 x 6"):
        read_map_yaml(path)
    (tmp_path / "room.pgm").write_bytes(b"GIF89a")
    with pytest.raises(SceneError, match="neither PGM"):
        read_map_yaml(path)
    path.write_text("image: room.pgm\nresolution: -1\norigin: [0, 0, 0]\n")
    with pytest.raises(SceneError, match="resolution"):
        read_map_yaml(path)
    with pytest.raises(SceneError, match="cannot read"):
        read_map_yaml(tmp_path / "missing.yaml")


@pytest.mark.parametrize("origin, shown", [("[0.0, 0.0]", "is [0, 0], 2 numbers"),
                                           ("[1.0, 2.0, 0.0, 0.0]", "is [1, 2, 0, 0], 4 numbers")])
def test_an_origin_that_is_not_x_y_yaw_is_refused(tmp_path: Path, origin: str, shown: str) -> None:
    path = write_map(tmp_path, origin=origin)
    with pytest.raises(SceneError) as err:
        read_map_yaml(path)
    assert err.value.field.endswith("origin") and "not [x, y, yaw]" in err.value.problem
    assert shown in str(err.value) and "[0.0, 0.0, 0.0]" in err.value.fix
    assert "\n" not in str(err.value)


def test_sweep_map_prints_the_bounding_box_of_a_rotated_map(tmp_path: Path,
                                                          capsys: pytest.CaptureFixture) -> None:
    from sweep_core.cli import main

    assert main(["map", str(write_map(tmp_path))]) == 0  # 8 x 6 cells of 0.5 m at (-1, 2)
    assert re.search(r"extent_m +\[-1, 2\] to \[3, 5\]\n", capsys.readouterr().out)
    assert main(["map", str(write_map(tmp_path, origin="[1.0, -2.0, 0.5]"))]) == 0
    c, s = np.cos(0.5), np.sin(0.5)  # corners (0, 0), (4, 0), (4, 3), (0, 3) turned by 0.5
    box = f"[{1 - 3 * s:g}, {-2.0:g}] to [{1 + 4 * c:g}, {-2 + 4 * s + 3 * c:g}]"
    assert f"{box} (bounding box of the rotated map)" in capsys.readouterr().out


def test_sweep_map_prints_draws_and_writes_a_scene(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from sweep_core.cli import main

    path = write_map(tmp_path)
    png, scene_file = tmp_path / "walls.png", tmp_path / "scene.yaml"
    assert main(["map", str(path), "--png", str(png), "--scene", str(scene_file),
                 "--count", "10", "--radius", "0.15"]) == 0
    out = capsys.readouterr().out
    assert "8 x 6 of 0.5 m" in out and "wall_length_m" in out and "12" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    scene = sc.Scene.from_yaml(scene_file)  # the map path is relative to the scene file
    assert scene.n_agents == 10
    # people walk round the walls to a free point; coordinates are written as decimals
    assert scene.spec["drift"]["kind"] == "geodesic"
    assert not re.search(r"\d\.\d*0000000\d|\d\.\d*9999999\d", scene_file.read_text())
    sim = sc.Simulator(scene, dt=0.01, seed=0)
    start = sim.positions.copy()
    goal = np.array(scene.spec["drift"]["goal"])
    sim.step(100)
    before = np.linalg.norm(start - goal, axis=1).mean()
    assert np.linalg.norm(sim.positions - goal, axis=1).mean() < 0.8 * before  # 0.5 here


def test_sweep_map_bad_file_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    from sweep_core.cli import main

    assert main(["map", str(tmp_path / "nope.yaml")]) != 0
    err = capsys.readouterr().err
    assert "cannot read" in err and "Traceback" not in err


def test_long_noisy_run_never_enters_a_polygon_or_a_blocked_cell(tmp_path: Path) -> None:
    # a 6 x 4 m room from a map with a pillar, a non-convex polygon obstacle, 40 noisy agents
    # spawned in the free space and driven back and forth for 1500 steps
    from sweep_core.model.geometry import inside_polygons

    rows = ["#" * 14] + ["#" + "." * 12 + "#"] * 8 + ["#" * 14]
    rows[3] = "#......##....#"
    path = write_map(tmp_path, rows=rows, origin="[0.0, 0.0, 0.0]")
    ell = [[4.2, 0.8], [5.6, 0.8], [5.6, 2.0], [5.0, 2.0], [5.0, 1.4], [4.2, 1.4]]
    scene = sc.Scene.from_dict({
        "map": {"yaml": str(path)}, "obstacles": [{"kind": "polygon", "points": ell}],
        "agents": {"spawn": {"region": {"kind": "rectangle", "min": [0.5, 0.5], "max": [6.5, 4.5]},
                             "count": 40, "radius": [0.1, 0.16], "seed": 3}},
        "drift": {"kind": "linear", "matrix": [[0, -1], [1, 0]], "offset": [4.5, -3.5]},
        "noise": {"sigma": 0.4}})
    grid = map_from_spec(scene.spec["map"], "map", None)
    sim = sc.Simulator(scene, dt=0.01, seed=11)
    for _ in range(1500):
        sim.step()
        assert not grid.is_blocked(sim.positions).any()
        assert not inside_polygons(sim.positions, scene.geometry).any()


def grid_message_data(rows: list[str], free: float = 0.196, occupied: float = 0.65) -> np.ndarray:
    """What map_server publishes for the map write_map writes (trinary mode): 100 occupied,
    0 free, -1 unknown, row-major from the origin (the image's last row first)."""
    p = (255.0 - np.array([[PIXEL[c] for c in row] for row in rows], dtype=float)) / 255.0
    values = np.where(p > occupied, 100, np.where(p < free, 0, -1)).astype(np.int8)
    return values[::-1].ravel()


def test_occupancy_grid_gives_the_map_files_cells_and_walls(tmp_path: Path) -> None:
    from_file = read_map_yaml(write_map(tmp_path, origin="[1.0, -2.0, 0.5]"))
    grid = OccupancyMap.from_occupancy_grid(grid_message_data(ROOM), 8, 6, 0.5, (1.0, -2.0, 0.5),
                                            free_thresh=0.196, source="/map")
    assert np.array_equal(grid.blocked, from_file.blocked)
    for mine, theirs in zip(grid.segments(), from_file.segments()):
        assert np.array_equal(mine, theirs)
    assert grid.origin == from_file.origin and grid.resolution == 0.5
    # the packed form round-trips, so a recording can hold it
    again = map_from_spec(grid.to_spec(), "map", None)
    assert np.array_equal(again.blocked, grid.blocked) and again.source == "/map"


def test_occupancy_grid_threshold_and_orientation() -> None:
    # 3 x 2, row 0 (lowest y) first: occupancy percent 24 is free, 25 (= free_thresh) blocked
    grid = OccupancyMap.from_occupancy_grid([0, 24, 25, -1, 100, 10], 3, 2, 1.0, (0.0, 0.0, 0.0))
    assert grid.blocked.tolist() == [[False, False, True], [True, True, False]]
    centres = np.array([[0.5, 0.5], [2.5, 0.5], [2.5, 1.5]])
    assert grid.is_blocked(centres).tolist() == [False, True, False]


@pytest.mark.parametrize("kwargs, words", [
    ({"data": [0] * 5}, "holds 5 cells, not width x height = 3 x 2"),
    ({"data": [0, 0, 0, 0, 0, 101]}, "holds 101 at cell 5"),
    ({"data": [0, 0, 0, 0, 0, -2]}, "holds -2 at cell 5"),
    ({"data": [0.5] * 6}, "flat sequence of integers"),
    ({"width": 0}, "map.info.width"),
    ({"resolution": 0.0}, "map.info.resolution"),
    ({"free_thresh": 0.9}, "not 0 <= free <= occupied <= 1"),
])
def test_malformed_occupancy_grids_are_refused(kwargs: dict, words: str) -> None:
    args = {"data": [0] * 6, "width": 3, "height": 2, "resolution": 1.0,
            "origin_xy_yaw": (0.0, 0.0, 0.0), **kwargs}
    with pytest.raises(SceneError) as err:
        OccupancyMap.from_occupancy_grid(**args)
    assert words in str(err.value) and err.value.fix


@pytest.mark.parametrize("count, words", [
    ("-1", "argument --count: -1 is not > 0"), ("0", "argument --count: 0 is not > 0"),
    ("100000", "--count: 100000 agents of radius 0.15 m exceed the")])
def test_sweep_map_refuses_a_starter_count_that_cannot_be_spawned(
        tmp_path: Path, capsys: pytest.CaptureFixture, count: str, words: str) -> None:
    """A count <= 0 was written into the starter scene (which then failed to load); a count
    beyond the spawn bound is refused before the file is written."""
    from sweep_core.cli import main

    path = write_map(tmp_path)
    scene_file = tmp_path / "scene.yaml"
    try:
        code = main(["map", str(path), "--scene", str(scene_file), "--count", count,
                     "--radius", "0.15"])
    except SystemExit as stop:  # argparse's usage error
        code = stop.code
    assert code == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err, err
    assert not scene_file.exists()


@pytest.mark.parametrize("mode, shown, fix", [
    ("raw", "raw", "trinary"),       # raw pixels are occupancies 0..100: read as trinary, the
    ("trinry", "'trinry'", "trinary"),  # free cells became walls and unknown ones free
])
def test_a_mode_other_than_trinary_or_scale_is_refused(tmp_path: Path, mode: str, shown: str,
                                                       fix: str) -> None:
    path = write_map(tmp_path)
    path.write_text(path.read_text() + f"mode: {mode}\n")
    with pytest.raises(SceneError) as err:
        read_map_yaml(path)
    assert err.value.field.endswith("(room.yaml).mode") and shown in err.value.problem
    assert fix in err.value.fix and "\n" not in str(err.value)


@pytest.mark.parametrize("mode", ["trinary", "scale"])
def test_trinary_and_scale_modes_give_the_same_cells(tmp_path: Path, mode: str) -> None:
    plain = read_map_yaml(write_map(tmp_path)).blocked.copy()
    path = write_map(tmp_path)
    path.write_text(path.read_text() + f"mode: {mode}\n")
    assert np.array_equal(read_map_yaml(path).blocked, plain)


@pytest.mark.parametrize("region", [{"kind": "rectangle", "min": [9, 9], "max": [10, 10]},
                                    {"kind": "rectangle", "min": [1.6, 3.1], "max": [1.9, 3.4]}])
def test_a_source_in_blocked_map_cells_only_is_refused(tmp_path: Path, region: dict) -> None:
    # outside the image (blocked) or inside the pillar's cells: no entering agent could ever
    # be placed there, and the source used to be accepted and wait for ever
    path = write_map(tmp_path)
    spec = {"map": {"yaml": str(path)}, "agents": {"positions": [[0.0, 3.0]], "radius": 0.2},
            "flows": {"sources": [{"region": region, "rate": 1.0, "count": 3, "radius": 0.1}]}}
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict(spec)
    assert str(err.value).startswith("flows.sources[0].region: has no point 0.1 m")
    assert "blocked map cells" in str(err.value) and "\n" not in str(err.value)
    spec["flows"]["sources"][0]["region"] = {"kind": "rectangle", "min": [0, 2.6],
                                             "max": [1, 4.4]}
    assert sc.Scene.from_dict(spec).flows.sources  # free cells: taken
