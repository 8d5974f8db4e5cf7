"""``noise.pcg64_start``: the state ``np.random.PCG64(key)`` starts in (numpy's SeedSequence
and PCG64 seeding, compiled; the robots' scans seed one per robot and scan), checked against
numpy's own seeding."""
from __future__ import annotations

import numpy as np
import pytest

from sweep_core.numerics import noise


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
        start = noise.pcg64_start(np.array(noise.key_words(key), dtype=np.uint64))
        want = np.random.PCG64(list(key)).state["state"]
        assert (int(start[0]) << 64 | int(start[1])) == want["state"], key
        assert (int(start[2]) << 64 | int(start[3])) == want["inc"], key


def test_a_negative_key_is_refused_as_numpy_refuses_it() -> None:
    with pytest.raises(ValueError):
        np.random.PCG64([1, -2])
    with pytest.raises(ValueError, match="non-negative"):
        noise.key_words((1, -2))
    with pytest.raises(ValueError, match="non-negative"):
        noise.seed_words(-2)
