"""agents.spawn: non-overlapping disks in the free space of a region (issue 13)."""
import numpy as np
import pytest

import sweep_core as sc
from sweep_core.errors import SceneError
from sweep_core.model.geometry import gaps

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
    assert err.value.field == "agents.spawn.count" and "of 2000 agents" in str(err.value)


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
