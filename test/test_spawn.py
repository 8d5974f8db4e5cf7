"""agents.spawn: non-overlapping disks in the free space of a region (issue 13)."""
import numpy as np
import pytest

import sweep_core as sc
from sweep_core.errors import SceneError
from sweep_core.model.gaps import gaps

ROOM = {"kind": "polyline", "points": [[0, 0], [10, 0], [10, 6], [0, 6]], "closed": True}
PILLAR = {"kind": "polygon", "points": [[4, 2], [6, 2], [6, 4], [4, 4]]}


def scene(count: int, radius: object = 0.2, region: dict | None = None, seed: int = 0
          ) -> sc.Scene:
    region = region or {"kind": "rectangle", "min": [0, 0], "max": [10, 6]}
    return sc.Scene.from_dict({"walls": [ROOM], "obstacles": [PILLAR],
                               "agents": {"spawn": {"region": region, "count": count,
                                                    "radius": radius, "seed": seed}}})


@pytest.mark.parametrize("radius", [0.2, [0.15, 0.3]])
def test_spawned_crowd_is_feasible_and_in_the_region(radius: object) -> None:
    s = scene(150, radius)
    q, r = s.positions, s.radii(0.0)
    assert len(q) == 150
    assert gaps(s.geometry, 0.0, q, r).min_gap >= 0.0
    assert np.all((q > 0) & (q < [10, 6]))
    # nobody in the pillar (the gaps would be negative) and radii in range
    lo, hi = (radius, radius) if np.isscalar(radius) else radius
    assert r.min() >= lo and r.max() <= hi


def test_polygon_region_and_reproducible_seed() -> None:
    tri = {"kind": "polygon", "points": [[0.5, 0.5], [9.5, 0.5], [0.5, 5.5]]}
    a, b, c = scene(80, region=tri, seed=4), scene(80, region=tri, seed=4), scene(80, region=tri, seed=5)
    assert np.array_equal(a.positions, b.positions)
    assert not np.array_equal(a.positions, c.positions)
    x, y = a.positions.T
    assert np.all((x - 0.5) / 9.0 + (y - 0.5) / 5.0 <= 1.0) and np.all((x >= 0.5) & (y >= 0.5))


def test_spec_holds_the_positions() -> None:
    s = scene(50)
    again = sc.Scene.from_dict(s.spec)
    assert "spawn" not in s.spec["agents"]
    assert np.array_equal(again.positions, s.positions)


def test_too_many_agents_are_refused_with_the_count_that_fits() -> None:
    with pytest.raises(SceneError) as err:
        scene(2000, 0.3)  # 2000 x 0.28 m^2 is far more than the 56 m^2 of free floor
    assert err.value.field == "agents.spawn.count" and "exceed the 171" in str(err.value)
    with pytest.raises(SceneError) as err:
        scene(165, 0.3)  # under the bound, which ignores the pillar, but more than fits
    assert err.value.field == "agents.spawn.count" and "of 165 agents" in str(err.value)


@pytest.mark.parametrize("spawn, field", [
    ({"region": {"kind": "rectangle", "min": [5, 5], "max": [1, 1]}, "count": 3, "radius": 0.2},
     "agents.spawn.region"),
    ({"region": {"kind": "rectangle", "min": [0, 0], "max": [1, 1]}, "count": 0, "radius": 0.2},
     "agents.spawn.count"),
    ({"region": {"kind": "rectangle", "min": [0, 0], "max": [1, 1]}, "count": 3,
      "radius": [0.3, 0.1]}, "agents.spawn.radius"),
])
def test_bad_spawn_is_refused(spawn: dict, field: str) -> None:
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict({"agents": {"spawn": spawn}})
    assert err.value.field == field and err.value.fix


def test_a_count_beyond_the_jamming_bound_is_refused_before_any_draw(monkeypatch) -> None:
    """10^8 agents of 0.2 m in a 9 x 4 m rectangle exhausted the memory (batches of 4x the
    count); 10 000 took minutes. Both are refused before anything is drawn, naming the bound
    and its source: 0.547 x the area grown by r (41.33 m^2) / (pi r^2) = 179.9, plus
    3 sqrt(n) + 1 = 221."""
    def no_draws(*args, **kwargs):
        raise AssertionError("a random generator was made")

    monkeypatch.setattr(np.random, "default_rng", no_draws)
    for count in (100_000_000, 10_000, 222):
        with pytest.raises(SceneError) as err:
            sc.Scene.from_dict({"agents": {"spawn": {
                "region": {"kind": "rectangle", "min": [0.5, 0.5], "max": [9.5, 4.5]},
                "count": count, "radius": 0.2}}})
        msg = str(err.value)
        assert err.value.field == "agents.spawn.count", msg
        assert f"{count} agents of radius 0.2 m exceed the 221 that the region can hold" in msg
        assert "jams at 0.547" in msg and "Feder 1980" in msg and "\n" not in msg


def test_a_range_of_radii_is_bounded_by_the_area() -> None:
    """With radii in [0.1, 0.2] m the bound is the grown area over the smallest disk:
    (9 x 4 + 26 x 0.2 + pi 0.04) / (pi 0.01) = 1315."""
    with pytest.raises(SceneError, match="1316 agents of radius \\[0.1, 0.2\\] exceed the 1315"):
        sc.Scene.from_dict({"agents": {"spawn": {
            "region": {"kind": "rectangle", "min": [0.5, 0.5], "max": [9.5, 4.5]},
            "count": 1316, "radius": [0.1, 0.2]}}})


def test_a_count_that_passes_the_bound_but_does_not_fit_ends_after_bounded_draws(
        monkeypatch) -> None:
    """The bound ignores walls and obstacles: a count under it that the free floor cannot take
    is refused after at most DRAWS x count candidates, with the count that fitted."""
    from sweep_core.model import spawn as spawn_module
    drawn = []
    make = np.random.default_rng

    class Counted:
        def __init__(self, seed):
            self.rng = make(seed)

        def random(self, size):
            drawn.append(int(np.prod(size)))
            return self.rng.random(size)

    monkeypatch.setattr(np.random, "default_rng", Counted)
    pillar = {"kind": "polygon", "points": [[0.4, 0.4], [9.6, 0.4], [9.6, 4.6], [0.4, 4.6]]}
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict({"obstacles": [pillar], "agents": {"spawn": {
            "region": {"kind": "rectangle", "min": [0, 0], "max": [10, 5]},
            "count": 150, "radius": 0.2}}})
    assert "only " in str(err.value) and "of 150 agents" in str(err.value)
    # positions (2 per candidate) and nothing else: equal radii are not drawn
    assert sum(drawn) <= 2 * spawn_module.DRAWS * 150


@pytest.mark.parametrize("region", [
    {"kind": "rectangle", "min": [-3, 1], "max": [2, 5]},           # partly outside the room
    {"kind": "polygon", "points": [[1, 1], [9, 1], [9, 5], [1, 5]]},  # over a closed pillar
])
def test_a_region_crossed_by_a_closed_outline_is_refused(region: dict) -> None:
    # without the check, some of the 10 agents were placed outside the room or inside the
    # closed outline of the pillar, where they stay (a silent wrong crowd)
    pillar = {"kind": "polyline", "points": [[4, 2], [6, 2], [6, 4], [4, 4]], "closed": True}
    with pytest.raises(SceneError) as err:
        sc.Scene.from_dict({"walls": [ROOM, pillar],
                            "agents": {"spawn": {"region": region, "count": 10, "radius": 0.2}}})
    msg = str(err.value)
    assert msg.startswith("agents.spawn.region: is crossed by walls[") and "\n" not in msg
    assert "fix: keep agents.spawn.region on one side of walls[" in msg
