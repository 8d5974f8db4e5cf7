"""The scans' noise drawn in compiled code (``noise.key_normals``: numpy's SeedSequence and
PCG64 seeding, the PCG64 stream and numpy's ziggurat, :mod:`sweep_core.numerics.ziggurat`)
is numpy's own: bit for bit the draws of ``np.random.Generator(np.random.PCG64([seed, a,
b]))``, for seeds from 0 to far beyond 64 bits, and long enough streams to take the
ziggurat's rare paths (the tail beyond NOR_R, the wedges' exp test) many times; and a scan
with noise is the ray cast plus those draws."""
from __future__ import annotations

import numpy as np

from sweep_core.model.robots import ScanSpec
from sweep_core.model.scene import Scene
from sweep_core.numerics import noise, ziggurat
from sweep_core.numerics.robots.scan import cast_beams, finish_ranges, scan

SEEDS = [0, 1, 2, 7, 2**31 - 1, 2**32 - 1, 2**32, 2**32 + 1, 2**40 + 7, 2**63 - 1, 2**63,
         2**64 - 1, 2**64 + 5, 2**100 + 17, 12345678901234567890123456789]
SMALL = [0, 1, 2, 9, 2**31, 2**32 - 1, 2**32, 2**33 + 5, 2**62, 2**63 - 1]


def numpys(key: list[int], n: int) -> np.ndarray:
    return np.random.Generator(np.random.PCG64(key)).standard_normal(n)


def test_key_normals_are_numpys_draws_for_every_seed() -> None:
    for seed in SEEDS:
        head = noise.seed_words(seed)
        for a in SMALL[:6]:
            for b in SMALL:
                got = noise.key_normals(head, a, b, 40)
                assert got.tobytes() == numpys([seed, a, b], 40).tobytes(), (seed, a, b)
        assert noise.key_normals(head, 3, 4, 0).shape == (0,)


def test_random_keys_and_long_streams_take_every_path_with_numpys_bits() -> None:
    rng = np.random.default_rng(20261129)
    tail = wedge = 0
    for _ in range(60):
        seed = int(rng.integers(0, 2**63)) >> int(rng.integers(0, 63))
        a, b = (int(v) for v in rng.integers(0, 2**40, 2) >> rng.integers(0, 40, 2))
        want = numpys([seed, a, b], 20_000)
        got = noise.key_normals(noise.seed_words(seed), a, b, 20_000)
        assert got.tobytes() == want.tobytes(), (seed, a, b)
        tail += int(np.sum(np.abs(want) > ziggurat.NOR_R))
        # draws a layer's rectangle did not hold: beyond its ki bound (the exp test)
        raw = np.random.PCG64([seed, a, b]).random_raw(20_000)
        idx = (raw & np.uint64(0xFF)).astype(np.intp)
        rabs = (raw >> np.uint64(9)) & np.uint64(0x000FFFFFFFFFFFFF)
        wedge += int(np.sum((rabs >= ziggurat.KI[idx]) & (idx > 0)))
    assert tail > 20 and wedge > 1000  # the rare paths were compared, many times


def test_a_started_state_draws_numpys_stream() -> None:
    for key in ([0], [5, 0], [2**32, 1, 2**32 - 1, 0], [2**128 - 1], [3, 0, 1, 2, 3, 4, 5]):
        words = np.array(noise.key_words(tuple(key)), dtype=np.uint64)
        state = noise.pcg64_start(words)
        want = np.random.PCG64(key).state["state"]
        assert (int(state[0]) << 64 | int(state[1])) == want["state"], key
        assert (int(state[2]) << 64 | int(state[3])) == want["inc"], key
        raw = np.random.PCG64(key).random_raw(500)
        assert [int(ziggurat.next_uint64(state)) for _ in range(500)] == raw.tolist(), key
        out = np.empty(3000)
        ziggurat.standard_normals(noise.pcg64_start(words), out)
        assert out.tobytes() == numpys(key, 3000).tobytes(), key


def test_a_noisy_scan_is_the_ray_cast_plus_numpys_draws() -> None:
    spec = ScanSpec(0.05, 6.0, -3.0, 3.0, 0.01, 10.0, 0.05)
    geom = Scene.from_dict({
        "agents": {"positions": [[0.0, 0.0]], "radius": 0.2},
        "walls": [{"kind": "segment", "a": [-2.0, -1.0], "b": [4.0, -1.0]},
                  {"kind": "halfplane", "normal": [0.0, -1.0], "offset": -2.0}]}).geometry
    rng = np.random.default_rng(4)
    for seed, robot, step in [(0, 0, 0), (3, 1, 17), (2**70 + 1, 2, 2**33)]:
        people = rng.uniform(-1.5, 3.0, (12, 2))
        radii = np.full(12, 0.2)
        pose = (0.1, 0.2, 0.7)
        got = scan(spec, pose, 0.0, step, geom, people, radii, (seed, robot, step))
        want, hits = cast_beams(0.7, spec.angles(), 0.1, 0.2, people, radii, geom.packed[2],
                                geom.packed[3], geom.packed[0], geom.offsets(0.0), 6.0)
        draws = np.random.Generator(np.random.PCG64([seed, robot, step])).standard_normal(hits)
        finish_ranges(want, draws, 0.05, 0.05, 6.0)
        assert hits > 0 and got.ranges.tobytes() == want.tobytes()
        assert (got.t, got.step, got.pose, got.spec) == (0.0, step, pose, spec)
        quiet = scan(spec, pose, 0.0, step, geom, people, radii)  # no key: no noise
        plain, _ = cast_beams(0.7, spec.angles(), 0.1, 0.2, people, radii, geom.packed[2],
                              geom.packed[3], geom.packed[0], geom.offsets(0.0), 6.0)
        finish_ranges(plain, np.empty(0), 0.0, 0.05, 6.0)
        assert quiet.ranges.tobytes() == plain.tobytes()
