"""``noise.reseed``: a kept generator put in the state ``Generator(PCG64(key))`` starts in
(the robots' scans seed one per robot and scan), checked against numpy's own seeding."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core.numerics.noise import pcg64_state, reseed


def _keys() -> list[tuple[int, ...]]:
    rng = np.random.default_rng(20261128)
    keys: list[tuple[int, ...]] = [(0,), (0, 0, 0), (1, 2, 3), (2**32 - 1, 2**32, 1),
                                   (2**64 + 5, 0, 7), (2**128 - 1,), (3, 0, 1, 2, 3, 4, 5)]
    for _ in range(400):
        size = int(rng.integers(1, 7))
        keys.append(tuple(int(v) for v in rng.integers(0, 2**62, size)
                          >> rng.integers(0, 62, size)))
    return keys


def test_the_state_is_numpys_for_every_key() -> None:
    for key in _keys():
        assert pcg64_state(key) == np.random.PCG64(list(key)).state, key


def test_a_reseeded_generator_draws_the_seeded_stream() -> None:
    kept = np.random.Generator(np.random.PCG64(99))
    kept.standard_normal(3)  # a used generator, as after a scan
    for key in [(7, 0, 12), (7, 1, 12), (2**40, 3, 0)]:
        got = reseed(kept, key).standard_normal(37)
        want = np.random.Generator(np.random.PCG64(list(key))).standard_normal(37)
        assert got.tobytes() == want.tobytes()


def test_a_negative_key_is_refused_as_numpy_refuses_it() -> None:
    with pytest.raises(ValueError):
        np.random.PCG64([1, -2])
    with pytest.raises(ValueError, match="non-negative"):
        pcg64_state((1, -2))
