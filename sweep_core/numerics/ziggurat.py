"""numpy's ``Generator(PCG64).standard_normal``, compiled: the PCG64 stream (XSL-RR output of
a 128-bit LCG, held as two uint64 halves) and numpy's ziggurat for normals, with numpy's
tables, so that a stream started from a PCG64 state draws the very bits numpy draws from it.

The ziggurat (``random_standard_normal`` in numpy's ``distributions.c``): a draw r (uint64)
gives a layer i (its low 8 bits), a sign (the next bit) and a 52-bit magnitude a; x = a wi[i]
(signed) is returned when a < ki[i] (99.3% of draws); otherwise layer 0 samples the tail by
logarithms of further doubles, and another layer accepts x when
(fi[i-1] - fi[i]) u + fi[i] < exp(-x^2 / 2), u a further double; else it draws again. The
tail's log1p and exp are the C library's, as numpy's are. A double is (r >> 11) 2^-53.

The tables ki (uint64), wi and fi (float64), 256 each, and the tail's r and 1 / r are
numpy's (``ziggurat_constants.h``), read from numba, which holds them for its own
``np.random.Generator`` support (``numba.np.random._constants``; numba is pinned);
test_scan_noise checks the draws against numpy's.
"""
from __future__ import annotations

import numba
import numpy as np
from numba.np.random import _constants as _tables

#: numpy's ziggurat tables for normals (256 layers) and the tail's start r and 1 / r
KI: np.ndarray = np.ascontiguousarray(_tables.ki_double, dtype=np.uint64)
WI: np.ndarray = np.ascontiguousarray(_tables.wi_double, dtype=np.float64)
FI: np.ndarray = np.ascontiguousarray(_tables.fi_double, dtype=np.float64)
NOR_R: float = float(_tables.ziggurat_nor_r)
NOR_INV_R: float = float(_tables.ziggurat_nor_inv_r)
#: PCG64's 128-bit LCG multiplier, high and low halves
MULT_HI, MULT_LO = 0x2360ED051FC65DA4, 0x4385DF649FCCF645
_M32 = 0xFFFFFFFF


@numba.njit(cache=True, nogil=True)
def mul_high(a: np.uint64, b: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    """The high 64 bits of the 128-bit product a b (uint64 each)."""
    m = np.uint64(_M32)
    s32 = np.uint64(32)
    a0, a1 = a & m, a >> s32
    b0, b1 = b & m, b >> s32
    p01, p10 = a0 * b1, a1 * b0
    mid = ((a0 * b0) >> s32) + (p01 & m) + (p10 & m)
    return a1 * b1 + (p01 >> s32) + (p10 >> s32) + (mid >> s32)


@numba.njit(cache=True, nogil=True)
def lcg_step(state: np.ndarray) -> None:  # pragma: no cover - compiled
    """In place: state (4,) uint64 (state's high and low halves, increment's high and low)
    advanced by one step of PCG64's LCG, state * MULT + inc mod 2^128."""
    hi, lo = state[0], state[1]
    m_hi, m_lo = np.uint64(MULT_HI), np.uint64(MULT_LO)
    p_lo = lo * m_lo
    p_hi = mul_high(lo, m_lo) + lo * m_hi + hi * m_lo
    s_lo = p_lo + state[3]
    carry = np.uint64(1) if s_lo < p_lo else np.uint64(0)
    state[0] = p_hi + state[2] + carry
    state[1] = s_lo


@numba.njit(cache=True, nogil=True)
def next_uint64(state: np.ndarray) -> np.uint64:  # pragma: no cover - compiled
    """PCG64's next output (numpy's ``random_raw``): a step of ``state`` (4,) uint64, then the
    XSL-RR output of the new state."""
    lcg_step(state)
    x = state[0] ^ state[1]
    rot = state[0] >> np.uint64(58)
    return (x >> rot) | (x << ((np.uint64(64) - rot) & np.uint64(63)))


@numba.njit(cache=True, nogil=True)
def next_double(state: np.ndarray) -> float:  # pragma: no cover - compiled
    """numpy's double in [0, 1) from the next output: (r >> 11) 2^-53."""
    return float(next_uint64(state) >> np.uint64(11)) * (1.0 / 9007199254740992.0)


@numba.njit(cache=True, nogil=True)
def standard_normal(state: np.ndarray) -> float:  # pragma: no cover - compiled
    """numpy's ``standard_normal()`` from PCG64 ``state`` (4,) uint64, advanced in place."""
    while True:
        r = next_uint64(state)
        idx = r & np.uint64(0xFF)
        r >>= np.uint64(8)
        sign = r & np.uint64(1)
        rabs = (r >> np.uint64(1)) & np.uint64(0x000FFFFFFFFFFFFF)
        x = float(rabs) * WI[idx]
        if sign:
            x = -x
        if rabs < KI[idx]:
            return x
        if idx == 0:
            while True:
                xx = -NOR_INV_R * np.log1p(-next_double(state))
                yy = -np.log1p(-next_double(state))
                if yy + yy > xx * xx:
                    if (rabs >> np.uint64(8)) & np.uint64(1):
                        return -(NOR_R + xx)
                    return NOR_R + xx
        elif (FI[idx - np.uint64(1)] - FI[idx]) * next_double(state) + FI[idx] < np.exp(-0.5 * x * x):
            return x


@numba.njit(cache=True, nogil=True)
def standard_normals(state: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out (n,) = the next n of numpy's ``standard_normal`` draws from PCG64 ``state`` (4,)
    uint64 (advanced in place): ``Generator.standard_normal(n)``'s values."""
    for i in range(out.shape[0]):
        out[i] = standard_normal(state)
