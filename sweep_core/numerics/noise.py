"""Brownian increments: independent 2-D Brownian motions, one per agent.

Increments are drawn as sqrt(h) * standard normals from a seeded numpy Generator (PCG64), so
a seed fixes the whole path and runs that differ only in sigma share the same path (the
sigma -> 0 study). A scene with sigma = 0 everywhere draws nothing.
"""
from __future__ import annotations

import functools
import math

import numba
import numpy as np

from sweep_core.numerics import ziggurat


def generator(seed: int) -> np.random.Generator:
    """The project's random generator for a seed."""
    return np.random.Generator(np.random.PCG64(seed))


def increments(rng: np.random.Generator, h: float, n: int) -> np.ndarray:
    """Increments of n independent 2-D standard Brownian motions over a step h (s): shape
    (n, 2), each component N(0, h). The scheme multiplies them by sigma (m / sqrt(s))."""
    # math.sqrt and np.sqrt are both IEEE correctly rounded: the same bits
    return math.sqrt(h) * rng.standard_normal((n, 2))


# -- numpy's seeding of a generator by a key, without building a SeedSequence --------------
# numpy's SeedSequence (O'Neill's seed_seq_fe, pool of 4 32-bit words) and PCG64's seeding,
# compiled: the state np.random.PCG64(key) starts in (pcg64_start), from which the robots'
# scans (one key (seed, robot, step) per robot and scan) draw numpy's normals in compiled code
# (key_normals, with the stream and ziggurat of .ziggurat). test_noise_keys and
# test_scan_noise check both against numpy.
_MASK32 = 0xFFFFFFFF
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_L, _MIX_R = 0xCA01F9DD, 0x4973F715
_POOL = 4


def key_words(key: tuple[int, ...]) -> list[int]:
    """The key's integers as SeedSequence's entropy: each as its little-endian 32-bit words
    (0 as one word); ValueError for a negative one, as numpy refuses it."""
    out = []
    for n in key:
        n = int(n)
        if n < 0:
            raise ValueError(f"a seed key holds only non-negative integers, got {n}")
        if n == 0:
            out.append(0)
        while n > 0:
            out.append(n & _MASK32)
            n >>= 32
    return out


@numba.njit(cache=True)
def _state_words(entropy: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """SeedSequence's pool mixed from the entropy words (uint64 holding 32-bit values), then
    its ``generate_state(4, uint64)``: (4,) uint64."""
    mask = np.uint64(_MASK32)
    s16 = np.uint64(16)
    const = np.uint64(_INIT_A)
    mult_a, mix_l, mix_r = np.uint64(_MULT_A), np.uint64(_MIX_L), np.uint64(_MIX_R)
    pool = np.zeros(_POOL, dtype=np.uint64)
    for i in range(_POOL):
        value = entropy[i] if i < len(entropy) else np.uint64(0)
        value ^= const
        const = (const * mult_a) & mask
        value = (value * const) & mask
        pool[i] = value ^ (value >> s16)
    for src in range(_POOL + max(0, len(entropy) - _POOL)):
        for dst in range(_POOL):
            if src < _POOL and src == dst:
                continue
            value = pool[src] if src < _POOL else entropy[src]
            value ^= const
            const = (const * mult_a) & mask
            value = (value * const) & mask
            value ^= value >> s16
            mixed = (mix_l * pool[dst] - mix_r * value) & mask
            pool[dst] = mixed ^ (mixed >> s16)
    const = np.uint64(_INIT_B)
    mult_b = np.uint64(_MULT_B)
    out = np.zeros(4, dtype=np.uint64)
    for i in range(8):
        value = pool[i % _POOL] ^ const
        const = (const * mult_b) & mask
        value = (value * const) & mask
        value ^= value >> s16
        out[i // 2] |= value << np.uint64(32 * (i % 2))
    return out


@numba.njit(cache=True, nogil=True)
def pcg64_start(entropy: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """The state ``np.random.PCG64(key)`` starts in, from the key's entropy words (uint64
    holding 32-bit values, :func:`key_words`): (4,) uint64, the 128-bit state's high and low
    halves, then the increment's (as :mod:`.ziggurat` steps them)."""
    u64 = _state_words(entropy)
    one = np.uint64(1)
    out = np.empty(4, dtype=np.uint64)
    out[2] = (u64[2] << one) | (u64[3] >> np.uint64(63))  # inc = (seq << 1) | 1
    out[3] = (u64[3] << one) | one
    out[0], out[1] = out[2], out[3]  # state 0, one step: inc
    low = out[1] + u64[1]  # + seed
    out[0] = out[0] + u64[0] + (one if low < out[1] else np.uint64(0))
    out[1] = low
    ziggurat.lcg_step(out)
    return out


@functools.lru_cache(maxsize=16)
def seed_words(seed: int) -> np.ndarray:
    """A seed's SeedSequence entropy words (:func:`key_words`), (W,) uint64 read-only, computed
    once per seed: the head of a key (seed, ...) that :func:`key_normals` completes."""
    words = np.array(key_words((seed,)), dtype=np.uint64)
    words.flags.writeable = False
    return words


@numba.njit(cache=True, nogil=True)
def key_normals(head: np.ndarray, a: int, b: int, n: int) -> np.ndarray:  # pragma: no cover
    """(n,) the first n ``standard_normal`` draws of ``np.random.Generator(np.random.PCG64(
    [seed, a, b]))``, numpy's bits (:mod:`.ziggurat`): ``head`` the seed's words
    (:func:`seed_words`), a and b non-negative integers below 2^63."""
    entropy = np.empty(head.shape[0] + 4, dtype=np.uint64)
    m = head.shape[0]
    entropy[:m] = head
    for value in (a, b):
        v = np.uint64(value)
        if v == np.uint64(0):
            entropy[m] = v
            m += 1
        while v > np.uint64(0):
            entropy[m] = v & np.uint64(_MASK32)
            m += 1
            v >>= np.uint64(32)
    state = pcg64_start(entropy[:m])
    out = np.empty(n)
    ziggurat.standard_normals(state, out)
    return out
