"""The safety layer of the bundled planners (docs/robots.md): the fastest speed along a
direction of travel from which the robot can still be at rest before any person it sees ahead
reaches it, the passive motion safety of Fraichard (2007) and Bouraine, Fraichard & Salhi
(2012): if a contact happens, the robot is not advancing into the person.

Moving at speed v along the unit direction u, the robot advances towards a person j at
v c_j (c_j = <u, e_j>, e_j the unit vector from the robot's centre to j's). Braking at its
max_acceleration a it stops after v / a s, having advanced c_j v^2 / (2 a) towards j, while j
may come v_h v / a closer (v_h = ``people_speed``, the speed at which people are assumed to
close in). The gap g_j (edge to edge, m) less ``stop_margin`` g_0 must cover both:

    c_j v^2 / (2 a) + v_h v / a <= g_j - g_0,
    v <= 2 a (g_j - g_0) / (v_h + sqrt(v_h^2 + 2 a c_j (g_j - g_0))),

for every person with c_j > 0 (the robot's motion takes it away from the others); 0 when
g_j <= g_0. With v_h = 0 this is the braking bound sqrt(2 a (g_j - g_0) / c_j) of a person
standing still.

People who move by noise (Brownian motion of sigma m/sqrt(s) per axis) come closer over a
short time t by about sigma sqrt(t), far more than v_h t: over the 0.1 s a robot at 0.1 m/s
takes to stop, sigma = 0.3 m/sqrt(s) gives 0.095 m, v_h = 0.3 m/s 0.03 m. With
``people_noise`` n (m/sqrt(s)) a person's reach over t s is v_h t + n sqrt(t), and the bound
is the largest v with

    c_j v^2 / (2 a) + v_h v / a + n sqrt(v / a) <= g_j - g_0,

found in s = sqrt(v / a) (the left side c_j a s^4 / 2 + v_h s^2 + n s, increasing and convex
in s >= 0) by Newton's method from above (:func:`noise_bounds`); n = 0 gives the closed form.

Walls and obstacles stand still: along u the robot's disk can run d m before it touches one
(:func:`free_run`), and v <= sqrt(2 a (d - g_0)) keeps it able to stop g_0 short of it
(:class:`Walls`; the admissible velocities of the dynamic window approach, Fox, Burgard and
Thrun 1997).
"""
from __future__ import annotations

import math

import numba
import numpy as np

from sweep_core.model.elementary import atan2, sincos

#: a direction whose cosine to a person is at most this is not towards them (a sideways
#: direction's cosine of 1e-17 is rounding, not an advance)
AHEAD = 1e-9


#: Newton steps of :func:`noise_bounds` (from within a factor 3 of the root, quadratic
#: convergence: machine precision well before)
NEWTON_STEPS = 12


def safe_speeds(pose: tuple[float, float, float], directions: np.ndarray, radius: float,
                people: np.ndarray, people_radii: np.ndarray, accel: float, margin: float,
                people_speed: float, people_noise: float = 0.0) -> np.ndarray:
    """(K,) the largest speed (m/s; inf when no person is ahead) along each unit direction of
    ``directions`` (K, 2) from the robot at ``pose`` (x, y, yaw) m, rad with ``radius`` m that
    keeps passive safety (module docstring) against ``people`` (M, 2) m of radii
    ``people_radii`` (M,) m; ``accel`` m/s^2, ``margin`` m, ``people_speed`` m/s,
    ``people_noise`` m/sqrt(s)."""
    out = np.full(len(directions), math.inf)
    if not len(people):
        return out
    if people_noise > 0:
        noise_bounds(float(pose[0]), float(pose[1]),
                     np.ascontiguousarray(directions, dtype=np.float64), float(radius),
                     np.ascontiguousarray(people, dtype=np.float64),
                     np.ascontiguousarray(people_radii, dtype=np.float64), float(accel),
                     float(margin), float(people_speed), float(people_noise), out)
        return out
    bounds_along(float(pose[0]), float(pose[1]), np.ascontiguousarray(directions, dtype=np.float64),
                 float(radius), np.ascontiguousarray(people, dtype=np.float64),
                 np.ascontiguousarray(people_radii, dtype=np.float64), float(accel),
                 float(margin), float(people_speed), out)
    return out


@numba.njit(cache=True)
def start(room: float, quartic: float, square: float, linear: float) -> float:
    """About the smallest of the one-term roots of quartic s^4 + square s^2 + linear s = room
    (m^(1/2) s^(1/2); the square root of a square root for the quartic's): used only to
    skip people in :func:`noise_bounds`, never in a bound."""
    s = room / linear
    if square > 0:
        s = min(s, math.sqrt(room / square))
    if quartic > 0:
        s = min(s, math.sqrt(math.sqrt(room / quartic)))
    return s


@numba.njit(cache=True)
def noise_bounds(x: float, y: float, directions: np.ndarray, radius: float, people: np.ndarray,
                 radii: np.ndarray, accel: float, margin: float, people_speed: float,
                 people_noise: float, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`safe_speeds` with ``people_noise`` n > 0 into out (K,): for each direction the
    smallest over the people j ahead (cosine > AHEAD) of a s^2, s the root s >= 0 of
    (a c_j / 2) s^4 + v_h s^2 + n s = gap_j (the module docstring's bound), 0 where the gap is
    not positive, inf when no one is ahead, NaN propagated. The root: Newton's method from the
    smallest of the three one-term roots, an upper bound (each term alone is at most the gap);
    the left side is increasing and convex in s >= 0, so the iterates decrease to it. Each
    operation in the order of the numpy form in test_guard, so the bits are the same, and only
    correctly rounded ones (no power, exp or log): the same bits on every CPU."""
    m, k = people.shape[0], directions.shape[0]
    ex, ey, gap = np.empty(m), np.empty(m), np.empty(m)
    cosine, first = np.empty(m), np.empty(m)  # per direction: c_j, the start below
    for j in range(m):
        rx, ry = people[j, 0] - x, people[j, 1] - y
        d = math.hypot(rx, ry)
        if not (d != d or d >= 1e-12):
            d = 1e-12
        ex[j], ey[j] = rx / d, ry / d
        g = ((d - radius) - radii[j]) - margin
        gap[j] = g if (g != g or g >= 0.0) else 0.0
    for i in range(k):
        dx, dy = directions[i, 0], directions[i, 1]
        # People are skipped whose bound is surely above the smallest (the minimum is then
        # unchanged): above it, a s^2 at the smallest one-term root s (the Newton start; the
        # iterates decrease); below each person's, a (g / L)^2 with L = q s^3 + v_h s + n, as
        # the left side is at most L s' for s' <= s. Both only approximate (to rounding), so
        # a person is skipped only when that lower bound exceeds the upper one by 1 %.
        upper = math.inf
        for j in range(m):
            ck = ex[j] * dx + ey[j] * dy
            cosine[j] = ck
            room = gap[j]
            if ck > AHEAD and room == room:
                s = start(room, accel * ck / 2.0, people_speed, people_noise)
                first[j] = s
                upper = min(upper, accel * s * s)
        low = math.inf
        for j in range(m):
            ck = cosine[j]
            if not ck > AHEAD:  # NaN included: numpy's where gave inf there
                continue
            room = gap[j]
            bound = 0.0
            if room > 0.0:
                q = accel * ck / 2.0
                s = first[j]
                s = room / ((q * s * s + people_speed) * s + people_noise)
                if accel * s * s > 1.01 * upper:
                    continue
                s = room / people_noise
                if people_speed > 0:
                    t = math.sqrt(room / people_speed)
                    s = s if (s <= t or s != s) else t
                # the quartic's root by two square roots, rounded alike on every CPU (a
                # power's SIMD variants differ in the last bit)
                t = math.sqrt(math.sqrt(room / (q if q >= 1e-300 else 1e-300))) if q > 0 \
                    else math.inf
                s = s if (s <= t or s != s) else t
                for _ in range(NEWTON_STEPS):
                    f = ((q * s * s + people_speed) * s + people_noise) * s - room
                    t = s - f / ((4.0 * q * s * s + 2.0 * people_speed) * s + people_noise)
                    s = t if (t >= 0.0 or t != t) else 0.0
                bound = accel * s * s
            if bound != bound:
                low = math.nan
                break
            low = min(low, bound)
        out[i] = low


@numba.njit(cache=True)
def bounds_along(x: float, y: float, directions: np.ndarray, radius: float, people: np.ndarray,
                 radii: np.ndarray, accel: float, margin: float, people_speed: float,
                 out: np.ndarray) -> None:  # pragma: no cover - compiled
    """:func:`safe_speeds` without ``people_noise`` into out (K,): each person's distance d
    (at least 1e-12), cosines (x / d) u_x + (y / d) u_y with each unit direction (K, 2) and
    gap max(d - R - r_j - margin, 0) in numpy's order of operations (NaN kept as np.maximum
    keeps it), then :func:`smallest_bounds`; the same bits as the numpy form."""
    m, k = people.shape[0], directions.shape[0]
    c = np.empty((m, k))
    gap = np.empty(m)
    for j in range(m):
        rx, ry = people[j, 0] - x, people[j, 1] - y
        d = math.hypot(rx, ry)
        if not (d != d or d >= 1e-12):
            d = 1e-12
        ex, ey = rx / d, ry / d
        for i in range(k):
            c[j, i] = ex * directions[i, 0] + ey * directions[i, 1]
        g = ((d - radius) - radii[j]) - margin
        gap[j] = g if (g != g or g >= 0.0) else 0.0
    smallest_bounds(c, gap, accel, people_speed, out)


@numba.njit(cache=True)
def smallest_bounds(c: np.ndarray, gap: np.ndarray, accel: float, people_speed: float,
                    out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[k] = the smallest over the people j with c[j, k] > AHEAD of the speed bound
    2 a g_j / max(v_h + sqrt(v_h^2 + 2 a max(c, 0) g_j), 1e-300) (0 where g_j <= 0), inf
    when there is none (a NaN bound propagates, as numpy's min): the module docstring's bound, each
    operation in the order the numpy form took it, so the bits are the same. c (M, K) cosines,
    gap (M,) m clipped at 0, out (K,) m/s."""
    two_a = 2.0 * accel
    for k in range(c.shape[1]):
        low = math.inf
        for j in range(c.shape[0]):
            ck = c[j, k]
            if not ck > AHEAD:  # NaN included: numpy's where gave inf there
                continue
            g = gap[j]
            bound = 0.0
            if g > 0.0:
                root = math.sqrt(people_speed * people_speed + two_a * max(ck, 0.0) * g)
                den = max(people_speed + root, 1e-300)
                bound = two_a * g / den
            if bound != bound:
                low = math.nan
                break
            low = min(low, bound)
        out[k] = low


def safe_speed(pose: tuple[float, float, float], direction: np.ndarray, radius: float,
               people: np.ndarray, people_radii: np.ndarray, accel: float, margin: float,
               people_speed: float, people_noise: float = 0.0) -> float:
    """:func:`safe_speeds` along the one unit ``direction`` (2,)."""
    return float(safe_speeds(pose, np.asarray(direction).reshape(1, 2), radius, people,
                             people_radii, accel, margin, people_speed, people_noise)[0])


def nearest_safe(u: np.ndarray, pose: tuple[float, float, float], radius: float,
                 people: np.ndarray, people_radii: np.ndarray, accel: float, margin: float,
                 people_speed: float, directions: int = 72, people_noise: float = 0.0
                 ) -> np.ndarray:
    """(2,) m/s: the velocity nearest the wished ``u`` (2,) m/s among ``directions`` evenly
    spaced headings (the first one u's own), each at a speed within [0, its safe speed]: the
    minimal change of u that keeps passive safety (a safety filter in the sense of Ames et
    al. 2019, on a sampled velocity set)."""
    speed = float(np.hypot(u[0], u[1]))
    if speed <= 1e-12:
        return np.zeros(2)
    dirs, along = np.empty((directions, 2)), np.empty(directions)
    headings(float(u[0]), float(u[1]), dirs, along)
    out = np.empty(2)
    nearest_of(along, safe_speeds(pose, dirs, radius, people, people_radii, accel, margin,
                                  people_speed, people_noise), dirs, float(u[0]),
               float(u[1]), out)
    return out


@numba.njit(cache=True)
def headings(ux: float, uy: float, dirs: np.ndarray, along: np.ndarray
             ) -> None:  # pragma: no cover - compiled
    """dirs (K, 2): the unit vectors at atan2(uy, ux) + k 2 pi / K (k = 0 .. K-1, cos and sin
    of :mod:`sweep_core.model.elementary`), and along (K,) the components of u along them
    (x-then-y products)."""
    count = dirs.shape[0]
    base = atan2(uy, ux)
    step = 2.0 * math.pi / count
    for k in range(count):
        s, c = sincos(base + k * step)
        dirs[k, 0], dirs[k, 1] = c, s
        along[k] = c * ux + s * uy


@numba.njit(cache=True)
def nearest_of(along: np.ndarray, bound: np.ndarray, dirs: np.ndarray, ux: float, uy: float,
               out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out (2,) m/s: s_k dirs_k for the first k of least (ux - s_k dx_k)^2 + (uy - s_k
    dy_k)^2, s = clip(along, 0, bound) (along (K,) the wished velocity's components along the
    unit dirs (K, 2), bound (K,) their safe speeds); numpy's clip, squares and argmin (the
    first NaN, else the first least), so the bits are the same."""
    best, low = 0, 0.0
    for k in range(len(along)):
        s = along[k]
        if s == s:
            s = s if s > 0.0 else 0.0
            s = s if (s != s or s < bound[k]) else bound[k]
        a = ux - s * dirs[k, 0]
        b = uy - s * dirs[k, 1]
        miss = a * a + b * b
        if k == 0 or (low == low and (miss != miss or miss < low)):
            best, low = k, miss
    s = along[best]
    if s == s:
        s = s if s > 0.0 else 0.0
        s = s if (s != s or s < bound[best]) else bound[best]
    out[0], out[1] = s * dirs[best, 0], s * dirs[best, 1]


class Walls:
    """The walls and obstacles the safety layer keeps the robot able to stop short of: the
    wall segments ``seg_a``, ``seg_b`` (S, 2) m and circle obstacles (``centres`` (C, 2),
    ``radii`` (C,) m) a planner sees, from the robot's centre ``xy`` (2,) m with its
    ``radius`` m, braking at ``acceleration`` m/s^2, to stop ``margin`` m short."""

    def __init__(self, xy: np.ndarray, radius: float, seg_a: np.ndarray, seg_b: np.ndarray,
                 centres: np.ndarray, radii: np.ndarray, acceleration: float,
                 margin: float) -> None:
        self.xy, self.radius = (float(xy[0]), float(xy[1])), float(radius)
        self.arrays = tuple(np.ascontiguousarray(v, dtype=np.float64)
                            for v in (seg_a, seg_b, centres, radii))
        self.none = not (len(seg_a) or len(radii))
        self.acceleration, self.margin = float(acceleration), float(margin)

    def speeds(self, dirs: np.ndarray) -> np.ndarray:
        """(H,) m/s: along each unit direction ``dirs`` (H, 2), the largest speed from which
        the robot, braking at its acceleration a on a straight line, stops before its disk
        comes within the margin g_0 of a wall or obstacle: sqrt(2 a (d - g_0)), d the free
        run (:func:`free_run`), 0 when d <= g_0 (the admissible velocities of the dynamic
        window approach, Fox, Burgard and Thrun 1997); inf with nothing in the way."""
        run = np.full(len(dirs), np.inf)
        if not self.none:
            a, b, c, r = self.arrays
            free_run(self.xy[0], self.xy[1], self.radius,
                     np.ascontiguousarray(dirs, dtype=np.float64), a, b, c, r, run)
        room = run - self.margin
        # room > 0 only: an unbounded acceleration stops at once, but not within the margin
        out = np.zeros(len(room))
        ahead = room > 0.0
        out[ahead] = np.sqrt(2.0 * self.acceleration * room[ahead])
        return out

    def __call__(self, along: np.ndarray) -> float:
        """:meth:`speeds` along one unit direction (2,)."""
        return math.inf if self.none else float(self.speeds(np.reshape(along, (1, 2)))[0])


@numba.njit(cache=True)
def free_run(x: float, y: float, radius: float, dirs: np.ndarray, seg_a: np.ndarray,
             seg_b: np.ndarray, centres: np.ndarray, radii: np.ndarray, out: np.ndarray
             ) -> None:  # pragma: no cover - compiled
    """out (H,): how far (m) the robot's disk (centre (x, y) m, ``radius`` m) can move along
    each unit direction ``dirs`` (H, 2) before it touches a wall segment (``seg_a``,
    ``seg_b`` (S, 2) m) or a circle obstacle (``centres`` (C, 2), ``radii`` (C,) m); inf when
    nothing is in the way. The distance from a point moving on a line to a segment or a disk is
    convex in the distance moved, so a disk already touching something (within 1e-9 m) is
    stopped by it only in the directions that bring it closer (0), never in the others."""
    for h in range(dirs.shape[0]):
        ex, ey = dirs[h, 0], dirs[h, 1]
        best = np.inf
        for k in range(seg_a.shape[0]):
            ax, ay = seg_a[k, 0], seg_a[k, 1]
            dx, dy = seg_b[k, 0] - ax, seg_b[k, 1] - ay
            length = math.hypot(dx, dy)
            px, py = x - ax, y - ay
            # the nearest point of the segment, and whether the disk touches it now
            s = 0.0 if length == 0.0 else min(max((px * dx + py * dy) / (length * length),
                                                  0.0), 1.0)
            nx, ny = px - s * dx, py - s * dy
            if math.hypot(nx, ny) <= radius + 1e-9:
                if ex * nx + ey * ny < 0.0:
                    best = 0.0
                continue
            # the first touch: the disk's centre reaches the capsule of the segment (its
            # two end circles, and its two sides offset by the radius)
            for cx, cy in ((ax, ay), (ax + dx, ay + dy)):
                best = min(best, _ray_circle(x - cx, y - cy, ex, ey, radius))
            if length > 0.0:
                ux, uy = dx / length, dy / length
                side = px * -uy + py * ux  # signed distance from the segment's line
                rate = ex * -uy + ey * ux
                if rate != 0.0 and abs(side) > radius and side * rate < 0.0:
                    t = (math.copysign(radius, side) - side) / rate
                    along = (px + t * ex) * ux + (py + t * ey) * uy
                    if 0.0 <= along <= length:
                        best = min(best, t)
        for k in range(radii.shape[0]):
            mx, my = x - centres[k, 0], y - centres[k, 1]
            reach = radii[k] + radius
            if math.hypot(mx, my) <= reach + 1e-9:
                if ex * mx + ey * my < 0.0:
                    best = 0.0
                continue
            best = min(best, _ray_circle(mx, my, ex, ey, reach))
        out[h] = best


@numba.njit(cache=True)
def _ray_circle(mx: float, my: float, ex: float, ey: float, reach: float
                ) -> float:  # pragma: no cover - compiled
    """The distance along the unit direction (ex, ey) from a point at (mx, my) m from a
    circle's centre, outside it, to the circle of radius ``reach`` m (inf: never)."""
    b = mx * ex + my * ey
    disc = b * b - (mx * mx + my * my - reach * reach)
    if b >= 0.0 or disc < 0.0:  # moving away, or passing by
        return np.inf
    return -b - math.sqrt(disc)
