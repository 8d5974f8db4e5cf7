"""A robot's laser scan: a compiled ray cast from its centre against people's disks, other
robots' disks, wall segments (map cells' boundaries included), half-plane walls and circle
obstacles at the time of the scan (moving obstacles posed there). User constraints written in
Python are not seen by the scan.

Each beam k leaves the robot's centre o along u_k = (cos a_k, sin a_k), a_k = yaw + angle_min +
k increment (cosines and sines from :mod:`sweep_core.model.elementary`, per beam, so the bits
do not depend on the CPU); its range is the smallest s >= 0 with o + s u_k on a disk's circle
(s = b - sqrt(b^2 - |o - c|^2 + R^2), b = <u, c - o>), a segment (solved by cross products)
or a half-plane's line. Noise: a Gaussian of noise_std m added to every return within
range_max, drawn from a generator seeded by (run seed, robot index, step): the stream of
numpy's ``Generator(PCG64([seed, robot, step]))``, drawn in the compiled scan
(:func:`sweep_core.numerics.noise.key_normals`). Then, as REP 117
says, a range (noisy or not) below range_min is -inf (something too close to measure) and one
above range_max +inf (no return within range): every finite range lies in
[range_min, range_max].
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numba
import numpy as np

from sweep_core.model.elementary import sincos
from sweep_core.model.geometry import Geometry
from sweep_core.model.robots import ScanSpec
from sweep_core.numerics import noise


@dataclass(frozen=True)
class Scan:
    """One scan: ``ranges`` (B,) float64 m (+inf: nothing within range_max, -inf: a return
    closer than range_min), taken at time
    ``t`` (s) and step ``step`` from pose (x, y, yaw); ``spec`` its settings."""

    t: float
    step: int
    pose: tuple[float, float, float]
    ranges: np.ndarray
    spec: ScanSpec


@numba.njit(cache=True, nogil=True)
def ray_cast(ox: float, oy: float, ux: np.ndarray, uy: np.ndarray, centers: np.ndarray,
             radii: np.ndarray, seg_a: np.ndarray, seg_b: np.ndarray, hp_n: np.ndarray,
             hp_c: np.ndarray, range_max: float) -> np.ndarray:
    """Ranges (B,) m of the beams (ux, uy) (B,) from (ox, oy) against disks (centers (C, 2),
    radii (C,)), segments [seg_a, seg_b] (S, 2) and half-planes <n, q> >= c (hp_n (H, 2),
    hp_c (H,)); inf where the nearest hit is beyond range_max."""
    nb = len(ux)
    out = np.empty(nb)
    for k in range(nb):
        dx = ux[k]
        dy = uy[k]
        best = np.inf
        for i in range(len(radii)):
            cx = centers[i, 0] - ox
            cy = centers[i, 1] - oy
            b = dx * cx + dy * cy
            c2 = cx * cx + cy * cy - radii[i] * radii[i]
            disc = b * b - c2
            if disc < 0.0:
                continue
            root = math.sqrt(disc)
            s = b - root
            if s < 0.0:
                s = b + root if c2 < 0.0 else -1.0  # inside the disk: its far side
            if 0.0 <= s < best:
                best = s
        for i in range(len(seg_a)):
            ax = seg_a[i, 0] - ox
            ay = seg_a[i, 1] - oy
            ex = seg_b[i, 0] - seg_a[i, 0]
            ey = seg_b[i, 1] - seg_a[i, 1]
            den = dx * ey - dy * ex
            if den == 0.0:
                continue
            s = (ax * ey - ay * ex) / den
            w = (ax * dy - ay * dx) / den
            if 0.0 <= w <= 1.0 and 0.0 <= s < best:
                best = s
        for i in range(len(hp_c)):
            dn = hp_n[i, 0] * dx + hp_n[i, 1] * dy
            if dn >= 0.0:
                continue
            s = (hp_c[i] - hp_n[i, 0] * ox - hp_n[i, 1] * oy) / dn
            if 0.0 <= s < best:
                best = s
        out[k] = best if best <= range_max else np.inf
    return out


@functools.lru_cache(maxsize=64)
def _angles(spec: ScanSpec) -> np.ndarray:
    """spec.angles(), computed once per scanner (read-only)."""
    angles = spec.angles()
    angles.flags.writeable = False
    return angles


def beam_directions(yaw: float, spec: ScanSpec) -> tuple[np.ndarray, np.ndarray]:
    """(B,) cosines and sines of the beams' world angles (:mod:`sweep_core.model.elementary`, per beam)."""
    angles = _angles(spec)
    ux, uy = np.empty(len(angles)), np.empty(len(angles))
    _cos_sin(float(yaw), angles, ux, uy)
    return ux, uy


@numba.njit(cache=True)
def _cos_sin(yaw: float, angles: np.ndarray, ux: np.ndarray, uy: np.ndarray
             ) -> None:  # pragma: no cover - compiled
    """ux, uy (B,) = cos and sin of yaw + angles (B,) rad (the same bits on every CPU)."""
    for k in range(len(angles)):
        a = yaw + angles[k]
        uy[k], ux[k] = sincos(a)


@numba.njit(cache=True, nogil=True)
def finite_count(ranges: np.ndarray) -> int:  # pragma: no cover - compiled
    """The beams with a return (finite ranges)."""
    count = 0
    for v in ranges:
        if np.isfinite(v):
            count += 1
    return count


@numba.njit(cache=True, nogil=True)
def cast_beams(yaw: float, angles: np.ndarray, ox: float, oy: float, centers: np.ndarray,
               radii: np.ndarray, seg_a: np.ndarray, seg_b: np.ndarray, hp_n: np.ndarray,
               hp_c: np.ndarray, range_max: float
               ) -> tuple[np.ndarray, int]:  # pragma: no cover - compiled
    """One call for a scan's geometry: the beams' directions at yaw + angles (B,) rad (as
    :func:`beam_directions`), their ranges (B,) m (:func:`ray_cast`, same arguments after the
    directions) and the count of finite ones (:func:`finite_count`)."""
    ux, uy = np.empty(len(angles)), np.empty(len(angles))
    _cos_sin(yaw, angles, ux, uy)
    ranges = ray_cast(ox, oy, ux, uy, centers, radii, seg_a, seg_b, hp_n, hp_c, range_max)
    return ranges, finite_count(ranges)


@numba.njit(cache=True, nogil=True)
def finish_ranges(ranges: np.ndarray, draws: np.ndarray, noise_std: float, range_min: float,
                  range_max: float) -> None:  # pragma: no cover - compiled
    """In place: the k-th finite range gets noise_std times the k-th draw (none without
    draws), then ranges below range_min read -inf (too close to measure) and above range_max
    +inf (no return within range), REP 117's conventions; the operations of numpy's
    ``ranges[hit] += noise_std * draws`` and masks, in their order."""
    if draws.shape[0]:
        k = 0
        for b in range(ranges.shape[0]):
            if np.isfinite(ranges[b]):
                ranges[b] = ranges[b] + noise_std * draws[k]
                k += 1
    for b in range(ranges.shape[0]):
        if ranges[b] < range_min:
            ranges[b] = -np.inf
    for b in range(ranges.shape[0]):
        if ranges[b] > range_max:
            ranges[b] = np.inf


@numba.njit(cache=True, nogil=True)
def bounded_ranges(ranges: np.ndarray, range_max: float, out: np.ndarray
                   ) -> None:  # pragma: no cover - compiled
    """out (B,) = ranges (B,) m with NaN read as range_max, then clipped to [0, range_max]
    (+inf to range_max, -inf to 0), the values of numpy's ``ranges[isnan] = range_max;
    clip(ranges, 0, range_max)`` (a -0.0 range is kept)."""
    for b in range(ranges.shape[0]):
        v = ranges[b]
        if np.isnan(v):
            v = range_max
        v = 0.0 if v < 0.0 else v
        out[b] = range_max if v > range_max else v


@numba.njit(cache=True, nogil=True)
def scan_ranges(yaw: float, angles: np.ndarray, ox: float, oy: float, centers: np.ndarray,
                radii: np.ndarray, seg_a: np.ndarray, seg_b: np.ndarray, hp_n: np.ndarray,
                hp_c: np.ndarray, range_min: float, range_max: float, noise_std: float,
                head: np.ndarray, robot: int, step: int
                ) -> np.ndarray:  # pragma: no cover - compiled
    """A scan's ranges (B,) m in one call: :func:`cast_beams` (the same arguments up to
    range_max), then, with noise_std > 0 (m), one draw per finite range from
    ``Generator(PCG64([seed, robot, step]))`` (``head`` the seed's words,
    :func:`sweep_core.numerics.noise.seed_words`), then :func:`finish_ranges`."""
    ranges, hits = cast_beams(yaw, angles, ox, oy, centers, radii, seg_a, seg_b, hp_n, hp_c,
                              range_max)
    draws = (noise.key_normals(head, robot, step, hits) if noise_std > 0.0
             else np.empty(0))
    finish_ranges(ranges, draws, noise_std, range_min, range_max)
    return ranges


#: the seed's words of a scan without noise (not read)
_NO_WORDS = np.zeros(1, dtype=np.uint64)


def _pairs(a: np.ndarray) -> np.ndarray:
    """``a`` as (M, 2) rows: itself when 2-D already (the packed arrays mostly are)."""
    return a if a.ndim == 2 and a.shape[1] == 2 else a.reshape(-1, 2)


def scan(spec: ScanSpec, pose: tuple[float, float, float], t: float, step: int,
         geometry: Geometry, disks: np.ndarray, disk_radii: np.ndarray,
         noise_key: tuple[int, int, int] | None = None) -> Scan:
    """The scan from ``pose`` (x, y, yaw) at time t (s): ``disks`` (C, 2) and ``disk_radii`` (C,)
    are the people and the other robots (m); ``noise_key`` (seed, robot index, step), all
    non-negative, seeds the range noise: the draws of ``np.random.Generator(
    np.random.PCG64(list(noise_key)))`` (None: no noise)."""
    geom = geometry.at(t)
    # the geometry's contiguous float64 arrays, made once per geometry; the half-planes'
    # offsets c + v t at t
    normals, _, seg_a, seg_b, circle_c, circle_r = geom.packed
    if len(circle_r):
        disks = np.concatenate([disks, circle_c])
        disk_radii = np.concatenate([disk_radii, circle_r])
    centers = np.ascontiguousarray(disks, dtype=float)
    radii = np.ascontiguousarray(disk_radii, dtype=float)
    x, y, yaw = float(pose[0]), float(pose[1]), float(pose[2])
    if noise_key is not None and spec.noise_std > 0:
        seed, robot, at = noise_key
        head, std = noise.seed_words(seed), float(spec.noise_std)
    else:
        head, std, robot, at = _NO_WORDS, 0.0, 0, 0
    ranges = scan_ranges(yaw, _angles(spec), x, y, _pairs(centers), radii, _pairs(seg_a),
                         _pairs(seg_b), _pairs(normals), geom.offsets(t),
                         float(spec.range_min), float(spec.range_max), std, head, robot, at)
    return Scan(t, step, (x, y, yaw), ranges, spec)
