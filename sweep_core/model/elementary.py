"""Elementary functions (sin, cos, atan2, exp, log) with the same bits on every CPU.

The C library's ``sin``, ``cos``, ``atan2``, ``exp`` and ``log`` and numpy's SIMD kernels of
them are chosen at run time by the CPU's features (glibc has FMA variants, numpy AVX2 and
AVX-512 kernels); they differ in the last bit between those variants, and an angle or a
weight that decides a position made runs depend on the CPU. The functions here use only
additions, multiplications, divisions, square roots, ``floor``, ``fmod``, ``frexp`` and
``ldexp``, which IEEE 754 rounds exactly (``fmod``, ``frexp`` and ``ldexp`` are exact), and
numba does not fuse a multiplication and an addition unless asked (``fastmath``), so their
bits depend on the input alone.

Methods (textbook ones; the polynomials are Taylor series, truncated below 2^-60 relative):

* sin, cos: x = k pi/2 + r, |r| <= pi/4, with pi/2 in three parts (Cody and Waite) so that
  k pi/2 is subtracted exactly for |x| < 2^20 pi/2; larger x are first reduced exactly
  modulo the double nearest 2 pi (``fmod``), then by the small rest, which keeps the
  result within about 1e-15 absolute for |x| < 2^52 (beyond, where doubles are integers,
  x carries no angle and the result is that of x modulo the double nearest 2 pi).
  Within 2 ulp in the tests.
* atan2: the quadrant from the signs, t = min(|x|, |y|) / max(|x|, |y|) in [0, 1], halved
  as an angle (atan t = 2 atan(t / (1 + sqrt(1 + t^2)))) until t <= 0.2, then its series.
  Within 4 ulp in the tests.
* exp: x = k ln 2 + r, |r| <= ln 2 / 2, e^r by its series to r^14 / 14!, times 2^k.
* log: x = m 2^e with m in [sqrt(1/2), sqrt(2)), log m = 2 atanh(s), s = (m - 1) / (m + 1).

Scalars: :func:`sin`, :func:`cos`, :func:`sincos`, :func:`atan2`, :func:`exp`, :func:`log`
(numba functions of float64, callable from Python and from compiled code; an int is taken as a
float); arrays of any shape: :func:`sin_of`, :func:`cos_of`, :func:`exp_of`, :func:`atan2_of`.
"""
from __future__ import annotations

import math
from fractions import Fraction

import numba
import numpy as np

#: pi to 80 digits (a published constant), exact as a fraction
PI = Fraction("3.14159265358979323846264338327950288419716939937510582097494459230781640628620899")


def _leading(value: Fraction, bits: int) -> float:
    """value rounded to ``bits`` significant bits (exact as a double for bits <= 53)."""
    e = math.floor(math.log2(abs(value)))
    scale = Fraction(2) ** (bits - 1 - e)
    return float(Fraction(round(value * scale)) / scale)


#: pi / 2 in three parts: 33, 33 and 53 significant bits (k * PIO2_1 and k * PIO2_2 exact
#: for |k| < 2^20)
PIO2_1 = _leading(PI / 2, 33)
PIO2_2 = _leading(PI / 2 - Fraction(PIO2_1), 33)
PIO2_3 = _leading(PI / 2 - Fraction(PIO2_1) - Fraction(PIO2_2), 53)
TWO_OVER_PI = float(2 / PI)
#: 2^20 pi / 2: beyond it, the first reduction is modulo 2 pi
REDUCE_LIMIT = float(2 ** 20 * PI / 2)
#: the double nearest 2 pi, and 2 pi minus it
TWO_PI = float(2 * PI)
TWO_PI_REST = float(2 * PI - Fraction(TWO_PI))
#: 2^52: beyond it doubles are integers (at least 1 rad apart) and the count of turns
#: (x - fmod(x, TWO_PI)) / TWO_PI is no longer exact
TURNS_LIMIT = 2.0 ** 52
#: pi / 2 and pi as a double and their rests
PIO2_HI = float(PI / 2)
PIO2_LO = float(PI / 2 - Fraction(PIO2_HI))
PI_HI = float(PI)
PI_LO = float(PI - Fraction(PI_HI))
#: ln 2 in two parts (the high part's last 32 bits zero, so k LN2_HI is exact for |k| < 2^20)
LN2_HI = 6.93147180369123816490e-01
LN2_LO = 1.90821492927058770002e-10
INV_LN2 = 1.44269504088896338700e+00
SQRT_HALF = 0.70710678118654752440
#: 1 / n! for n = 0 .. 18: the Taylor coefficients of e^x, sin and cos
FACTORIAL_INV = np.array([float(Fraction(1, math.factorial(n))) for n in range(19)])
#: (-1)^n / (2n + 1) for n = 0 .. 12: the series of atan; 1 / (2n + 1): of atanh
ATAN_SERIES = np.array([float(Fraction((-1) ** n, 2 * n + 1)) for n in range(13)])
ATANH_SERIES = np.array([float(Fraction(1, 2 * n + 1)) for n in range(13)])


@numba.njit("float64(float64)", cache=True, nogil=True)
def exp(x: float) -> float:
    """e^x (x a float): x = k ln 2 + r with |r| <= ln 2 / 2 (Cody and Waite's two-part
    ln 2), e^r by its Taylor series to r^14 / 14! (truncation below 5e-18 relative), then
    scaled by 2^k; within 2 ulp of e^x. inf above 709.79, 0 below -745.2, NaN for NaN."""
    if x != x:
        return x
    if x > 709.79:
        return math.inf
    if x < -745.2:
        return 0.0
    k = math.floor(x * INV_LN2 + 0.5)
    r = (x - k * LN2_HI) - k * LN2_LO
    p = FACTORIAL_INV[14]
    for n in range(13, -1, -1):  # Horner: sum of r^n / n!
        p = p * r + FACTORIAL_INV[n]
    return math.ldexp(p, int(k))


@numba.njit("float64(float64)", cache=True, nogil=True)
def log(x: float) -> float:
    """Natural log of x (a float): x = m 2^e with m in [sqrt(1/2), sqrt(2)); log m =
    2 atanh(s), s = (m - 1) / (m + 1), |s| <= 0.1716, by its series to s^25 / 25 (truncation
    below 1e-20 relative); plus e ln 2 in two parts. -inf at 0, NaN below 0 or for NaN,
    inf at inf."""
    if x != x or x < 0.0:
        return math.nan
    if x == 0.0:
        return -math.inf
    if x == math.inf:
        return x
    m, e = math.frexp(x)  # x = m 2^e, m in [0.5, 1)
    if m < SQRT_HALF:
        m *= 2.0
        e -= 1
    s = (m - 1.0) / (m + 1.0)
    z = s * s
    p = ATANH_SERIES[12]
    for n in range(11, 0, -1):
        p = p * z + ATANH_SERIES[n]
    # log m = 2 s + 2 s z p, the exact 2 s leading
    return e * LN2_HI + ((e * LN2_LO + 2.0 * s * z * p) + 2.0 * s)


@numba.njit(cache=True, nogil=True)
def _reduce(x: float) -> tuple[float, int]:
    """r, k mod 4 with x = k pi/2 + r, |r| <= pi/4 (about); x finite."""
    c = 0.0  # a small rest of the turns, subtracted last so that it rounds at |r|
    if abs(x) >= REDUCE_LIMIT:
        # fmod is exact: x = n TWO_PI + r0, and x - n 2 pi = r0 - n TWO_PI_REST
        r0 = np.fmod(x, TWO_PI)
        if abs(x) < TURNS_LIMIT:  # else n itself is rounded: x modulo TWO_PI only
            c = np.floor((x - r0) / TWO_PI + 0.5) * TWO_PI_REST
        x = r0
    k = math.floor((x - c) * TWO_OVER_PI + 0.5)
    r = ((x - k * PIO2_1) - k * PIO2_2) - (k * PIO2_3 + c)
    return r, int(k) & 3


@numba.njit(cache=True, nogil=True)
def _sin_kernel(r: float) -> float:
    """sin r for |r| <= pi/4 + a little: r + r z P(z), z = r^2, to r^17 / 17!."""
    z = r * r
    p = FACTORIAL_INV[17]
    for n in range(15, 2, -2):  # P(z) = -1/3! + z/5! - ... + z^7/17!, Horner in z
        p = -p * z + FACTORIAL_INV[n]
    return r - r * z * p


@numba.njit(cache=True, nogil=True)
def _cos_kernel(r: float) -> float:
    """cos r for |r| <= pi/4 + a little: 1 - z/2 + z^2 Q(z), z = r^2, to r^18 / 18!."""
    z = r * r
    q = FACTORIAL_INV[18]
    for n in range(16, 3, -2):  # Q(z) = 1/4! - z/6! + ... + z^7/18!
        q = -q * z + FACTORIAL_INV[n]
    return (1.0 - 0.5 * z) + z * z * q


@numba.njit("float64(float64)", cache=True, nogil=True)
def sin(x: float) -> float:
    """sin x (x in rad, a float); NaN for NaN and +-inf."""
    if not math.isfinite(x):
        return math.nan
    if x == 0.0:  # keeps the sign of zero
        return x
    r, k = _reduce(x)
    if k == 0:
        return _sin_kernel(r)
    if k == 1:
        return _cos_kernel(r)
    if k == 2:
        return -_sin_kernel(r)
    return -_cos_kernel(r)


@numba.njit("float64(float64)", cache=True, nogil=True)
def cos(x: float) -> float:
    """cos x (x in rad, a float); NaN for NaN and +-inf."""
    if not math.isfinite(x):
        return math.nan
    r, k = _reduce(x)
    if k == 0:
        return _cos_kernel(r)
    if k == 1:
        return -_sin_kernel(r)
    if k == 2:
        return -_cos_kernel(r)
    return _sin_kernel(r)


@numba.njit("UniTuple(float64, 2)(float64)", cache=True, nogil=True)
def sincos(x: float) -> tuple[float, float]:
    """(sin x, cos x) with one reduction; the same bits as :func:`sin` and :func:`cos`."""
    if not math.isfinite(x):
        return math.nan, math.nan
    if x == 0.0:
        return x, 1.0
    r, k = _reduce(x)
    s, c = _sin_kernel(r), _cos_kernel(r)
    if k == 0:
        return s, c
    if k == 1:
        return c, -s
    if k == 2:
        return -s, -c
    return -c, s


@numba.njit(cache=True, nogil=True)
def _atan_unit(t: float) -> float:
    """atan t for 0 <= t <= 1: halve the angle until t <= 0.2, then the series to t^25/25."""
    halvings = 0
    while t > 0.2:
        t = t / (1.0 + math.sqrt(1.0 + t * t))
        halvings += 1
    z = t * t
    p = ATAN_SERIES[12]
    for n in range(11, 0, -1):
        p = p * z + ATAN_SERIES[n]
    a = t + t * z * p
    return a * (1 << halvings)


@numba.njit("float64(float64, float64)", cache=True, nogil=True)
def atan2(y: float, x: float) -> float:
    """The angle of (x, y) in rad, in [-pi, pi], with the C library's conventions for signed
    zeros and infinities; NaN if either is NaN."""
    if x != x or y != y:
        return math.nan
    ax, ay = abs(x), abs(y)
    if ax == math.inf or ay == math.inf:
        if ax == math.inf and ay == math.inf:
            a = 0.5 * PIO2_HI if x > 0.0 else 1.5 * PIO2_HI
        elif ay == math.inf:
            a = PIO2_HI
        else:
            a = 0.0 if x > 0.0 else PI_HI
        return math.copysign(a, y)
    if ay == 0.0:
        return y if math.copysign(1.0, x) > 0.0 else math.copysign(PI_HI, y)
    if ax == 0.0:
        return math.copysign(PIO2_HI, y)
    if ay <= ax:
        a = _atan_unit(ay / ax)
    else:
        a = (PIO2_HI - _atan_unit(ax / ay)) + PIO2_LO
    if x < 0.0:
        a = (PI_HI - a) + PI_LO
    return math.copysign(a, y)


@numba.njit(cache=True, nogil=True)
def _each(values: np.ndarray, which: int) -> np.ndarray:
    out = np.empty_like(values)
    for k in range(values.shape[0]):
        v = values[k]
        out[k] = sin(v) if which == 0 else cos(v) if which == 1 else exp(v)
    return out


@numba.njit(cache=True, nogil=True)
def _atan2_each(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    out = np.empty_like(y)
    for k in range(y.shape[0]):
        out[k] = atan2(y[k], x[k])
    return out


def _flat(values: object) -> np.ndarray:
    return np.asarray(values, dtype=np.float64)


@numba.njit(cache=True, nogil=True)
def z_rotations(yaw: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out (N, 4) = the unit quaternions (x, y, z, w) = (0, 0, sin(yaw / 2), cos(yaw / 2)) of
    rotations by yaw (N,) rad about z: the half angle 0.5 yaw, then :func:`sincos` (the bits
    of :func:`sin_of` and :func:`cos_of` of 0.5 yaw)."""
    for k in range(yaw.shape[0]):
        s, c = sincos(0.5 * yaw[k])
        out[k, 0] = 0.0
        out[k, 1] = 0.0
        out[k, 2] = s
        out[k, 3] = c


def sin_of(values: object) -> np.ndarray:
    """sin of each entry (any shape, rad) as float64, the same bits on every CPU."""
    a = _flat(values)
    return _each(a.ravel(), 0).reshape(a.shape)


def cos_of(values: object) -> np.ndarray:
    """cos of each entry (any shape, rad) as float64, the same bits on every CPU."""
    a = _flat(values)
    return _each(a.ravel(), 1).reshape(a.shape)


def exp_of(values: object) -> np.ndarray:
    """e^x of each entry (any shape) as float64, the same bits on every CPU."""
    a = _flat(values)
    return _each(a.ravel(), 2).reshape(a.shape)


def atan2_of(y: object, x: object) -> np.ndarray:
    """atan2(y, x) of each pair of entries (broadcast shapes, rad) as float64."""
    yy, xx = np.broadcast_arrays(_flat(y), _flat(x))
    return _atan2_each(yy.ravel(), xx.ravel()).reshape(yy.shape)
