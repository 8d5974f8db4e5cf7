"""sweep_core.model.elementary: sin, cos, atan2, exp and log against references computed in
60-digit decimal arithmetic (exact to far below a double's ulp), their special values, the
array forms against the scalar ones, and the same bits with the C library's and numpy's
CPU-specific variants switched off (a subprocess)."""
from __future__ import annotations

import decimal
import math
import subprocess
import sys
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
from test_platform import cpu_variants_off_env

from sweep_core.model import elementary as E

CTX = decimal.Context(prec=60)
PI = Decimal("3.14159265358979323846264338327950288419716939937510582097494459230781640628620899")


def d_sin_cos(x: float) -> tuple[Decimal, Decimal]:
    """sin and cos of the double x, by x mod 2 pi (80-digit pi) and the Taylor series."""
    with decimal.localcontext(CTX):
        v = Decimal(x) % (2 * PI)
        s, c, term, n = Decimal(0), Decimal(0), Decimal(1), 0
        while True:  # term = v^n / n!
            if n % 4 == 0:
                c += term
            elif n % 4 == 1:
                s += term
            elif n % 4 == 2:
                c -= term
            else:
                s -= term
            n += 1
            term = term * v / n
            if abs(term) < Decimal("1e-70") and n > 10:
                return s, c


def d_atan(t: Decimal) -> Decimal:
    """atan t, |t| <= 1: halve the angle to below 0.05, then the series."""
    with decimal.localcontext(CTX):
        halvings = 0
        while abs(t) > Decimal("0.05"):
            t = t / (1 + (1 + t * t).sqrt())
            halvings += 1
        z, term, total, n = t * t, t, Decimal(0), 0
        while term != 0 and abs(term) > abs(t) * Decimal("1e-60"):
            total += term / (2 * n + 1) * (-1 if n % 2 else 1)
            term *= z
            n += 1
        return total * 2 ** halvings


def d_atan2(y: float, x: float) -> Decimal:
    with decimal.localcontext(CTX):
        ay, ax = abs(Decimal(y)), abs(Decimal(x))
        a = d_atan(ay / ax) if ay <= ax else PI / 2 - d_atan(ax / ay)
        if x < 0:
            a = PI - a
        return a if y >= 0 else -a


def ulps(got: float, want: Decimal) -> float:
    """|got - want| in units of the last place of want (as a double)."""
    w = float(want)
    if w == 0.0:
        return 0.0 if got == 0.0 else math.inf
    with decimal.localcontext(CTX):
        return float(abs(Decimal(got) - want) / Decimal(math.ulp(w)))


RNG = np.random.default_rng(20261128)
ANGLES = np.concatenate([
    RNG.uniform(-10.0, 10.0, 600), RNG.uniform(-1e6, 1e6, 200),
    RNG.uniform(-1e-3, 1e-3, 100), np.ldexp(1.0, -RNG.integers(20, 1000, 50)),
    np.arange(1, 200) * (math.pi / 4), np.arange(1, 100) * (math.pi / 2) * 1001.0,
    RNG.uniform(-1e12, 1e12, 100)])


@pytest.mark.parametrize("name", ["sin", "cos"])
def test_sin_cos_within_2_ulp(name: str) -> None:
    fn = getattr(E, name)
    worst = 0.0
    for x in ANGLES:
        s, c = d_sin_cos(float(x))
        want = s if name == "sin" else c
        worst = max(worst, ulps(fn(float(x)), want))
    assert worst <= 2.0


def test_sin_cos_near_multiples_of_half_pi_keep_relative_accuracy() -> None:
    # sin(k pi/2 as a double) is tiny: only an exact reduction gets its digits right
    for k in (2, 4, 100, 1000, 2 ** 19):
        x = k * math.pi / 2
        s, c = d_sin_cos(x)
        assert ulps(E.sin(x), s) <= 2.0 and ulps(E.cos(x), c) <= 2.0


def test_atan2_within_4_ulp() -> None:
    y = np.concatenate([RNG.normal(size=800), RNG.normal(size=100) * 1e-200,
                        RNG.normal(size=100) * 1e200])
    x = np.concatenate([RNG.normal(size=800), RNG.normal(size=100),
                        RNG.normal(size=100) * 1e-3])
    worst = max(ulps(E.atan2(float(b), float(a)), d_atan2(float(b), float(a)))
                for b, a in zip(y, x, strict=True))
    assert worst <= 4.0


def test_exp_and_log_within_2_ulp() -> None:
    with decimal.localcontext(CTX):
        xs = np.concatenate([RNG.uniform(-700, 700, 400), RNG.uniform(-1, 1, 200),
                             RNG.uniform(-1e-8, 1e-8, 50)])
        assert max(ulps(E.exp(float(v)), Decimal(float(v)).exp()) for v in xs) <= 2.0
        vs = np.concatenate([np.exp(RNG.uniform(-700, 700, 400)), RNG.uniform(0.5, 2, 200),
                             1.0 + RNG.uniform(-1e-9, 1e-9, 50), [5e-324, 1.7e308]])
        assert max(ulps(E.log(float(v)), Decimal(float(v)).ln()) for v in vs) <= 2.0


def test_special_values() -> None:
    inf, nan = math.inf, math.nan
    assert math.copysign(1.0, E.sin(-0.0)) < 0 and E.sin(0.0) == 0.0 and E.cos(0.0) == 1.0
    assert all(math.isnan(f(v)) for f in (E.sin, E.cos) for v in (inf, -inf, nan))
    assert E.exp(0.0) == 1.0 and E.exp(710.0) == inf and E.exp(-746.0) == 0.0
    assert E.exp(-inf) == 0.0 and E.exp(inf) == inf and math.isnan(E.exp(nan))
    assert E.log(1.0) == 0.0 and E.log(0.0) == -inf and E.log(inf) == inf
    assert math.isnan(E.log(-1.0)) and math.isnan(E.log(nan))
    # atan2's conventions for zeros and infinities are the C library's
    for y, x in [(0.0, 0.0), (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0), (1.0, 0.0), (-1.0, -0.0),
                 (inf, inf), (-inf, inf), (inf, -inf), (1.0, inf), (-1.0, -inf), (inf, 3.0),
                 (0.0, -2.0), (-0.0, -2.0)]:
        got, want = E.atan2(y, x), math.atan2(y, x)
        assert got == pytest.approx(want, rel=1e-15) and math.copysign(1, got) == \
            math.copysign(1, want), (y, x)
    assert math.isnan(E.atan2(nan, 1.0)) and math.isnan(E.atan2(1.0, nan))
    # huge arguments: deterministic and in range
    for x in (1e15, 1e300, -1.7e308):
        assert -1.0 <= E.sin(x) <= 1.0 and -1.0 <= E.cos(x) <= 1.0


def test_array_forms_equal_the_scalars() -> None:
    a = ANGLES[:300].reshape(10, 30)
    assert np.array_equal(E.sin_of(a), [[E.sin(v) for v in row] for row in a])
    assert np.array_equal(E.cos_of(a), [[E.cos(v) for v in row] for row in a])
    assert all(E.sincos(v) == (E.sin(v), E.cos(v)) for v in ANGLES)
    e = RNG.uniform(-50, 50, 40)
    assert np.array_equal(E.exp_of(e), [E.exp(v) for v in e])
    y, x = RNG.normal(size=(4, 5)), RNG.normal(size=5)
    assert np.array_equal(E.atan2_of(y, x), [[E.atan2(b, a) for b, a in zip(r, x, strict=True)]
                                             for r in y])
    assert E.sin_of(3.0).shape == () and E.cos_of([]).shape == (0,)


def test_z_rotations_are_sin_and_cos_of_the_half_yaw() -> None:
    """The markers' quaternions (0, 0, sin(yaw / 2), cos(yaw / 2)), bit for bit the array
    forms of 0.5 yaw; signed zeros, NaN and huge angles included."""
    yaw = np.concatenate([ANGLES[:200], [0.0, -0.0, np.nan, np.inf, 1e300, -7.5]])
    out = np.full((len(yaw), 4), 9.0)
    E.z_rotations(yaw, out)
    want = np.column_stack([np.zeros((len(yaw), 2)), E.sin_of(0.5 * yaw), E.cos_of(0.5 * yaw)])
    assert out.tobytes() == want.tobytes()


# -- the same bits with the CPU-specific variants off ---------------------------------------

HASH_ELEMENTARY = """
import hashlib, numpy as np
from sweep_core.model import elementary as E
x = np.random.default_rng(3).uniform(-20, 20, 20000)
h = hashlib.sha256()
for a in (E.sin_of(x), E.cos_of(x), E.exp_of(x), E.atan2_of(x, x[::-1]),
          np.array([E.log(abs(v)) for v in x])):
    h.update(a.tobytes())
print(h.hexdigest())
"""


@pytest.mark.skipif(sys.platform != "linux", reason="glibc tunables")
def test_same_bits_without_fma_and_simd_variants() -> None:
    root = str(Path(__file__).resolve().parents[1])
    mine = subprocess.run([sys.executable, "-c", HASH_ELEMENTARY], capture_output=True,
                          text=True, cwd=root, check=True).stdout
    plain = subprocess.run([sys.executable, "-c", HASH_ELEMENTARY], capture_output=True,
                           text=True, cwd=root, check=True, env=cpu_variants_off_env()).stdout
    assert mine and mine == plain
