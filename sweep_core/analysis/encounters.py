"""A robot's encounters with people, frame by frame (vectorised over people): surface-to-surface
clearance, time to collision of moving disks, the nearest person, heading wrap and jerk. Used by
:mod:`sweep_core.analysis.social` and the Gymnasium environment."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["clearance", "jerk", "nearest", "time_to_collision", "wrap"]


def clearance(robot: np.ndarray, robot_radius: np.ndarray, people: np.ndarray,
              radii: np.ndarray) -> np.ndarray:
    """(R, N) m: surface-to-surface distance between R robots (positions (R, 2), radii (R,))
    and N people (positions (N, 2), radii (N,))."""
    d = robot[:, None, :] - people[None, :, :]
    return np.hypot(d[..., 0], d[..., 1]) - robot_radius[:, None] - radii[None, :]


def time_to_collision(rel_pos: np.ndarray, rel_vel: np.ndarray, reach: np.ndarray
                      ) -> np.ndarray:
    """Time (s) until two disks moving at constant velocity first touch, elementwise.

    Args:
        rel_pos: (..., 2) m, one centre minus the other.
        rel_vel: (..., 2) m/s, the first's velocity minus the other's.
        reach: (...) m, the sum of the radii.

    Returns:
        (...) s: 0 where they already touch or overlap, inf where they never touch (moving
        apart, parallel, or passing clear), else the smallest tau > 0 with
        |rel_pos + tau rel_vel| = reach.
    """
    pw = np.einsum("...c,...c->...", rel_pos, rel_vel)
    ww = np.einsum("...c,...c->...", rel_vel, rel_vel)
    c = np.einsum("...c,...c->...", rel_pos, rel_pos) - reach * reach
    disc = pw * pw - ww * c
    approaching = (pw < 0) & (disc >= 0) & (ww > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        # the smaller root in the form that does not cancel: c / (-pw + sqrt(disc))
        tau = np.where(approaching, c / (-pw + np.sqrt(np.where(approaching, disc, 0.0))),
                       np.inf)
    return np.where(c <= 0, 0.0, tau)


def nearest(position: np.ndarray, velocity: np.ndarray, radius: float, people: np.ndarray,
            radii: np.ndarray, velocities: np.ndarray) -> tuple[float, float]:
    """One robot at one instant: the clearance (m) to the nearest of the people and the
    smallest time to collision (s) with any of them (:func:`time_to_collision`); inf, inf
    without people. ``position`` (2,) m, ``velocity`` (2,) m/s, ``people`` (N, 2) m,
    ``radii`` (N,) m, ``velocities`` (N, 2) m/s (NaN: unknown, no time to collision)."""
    if len(people) == 0:
        return math.inf, math.inf
    cl = clearance(position[None, :], np.array([radius]), people, radii)[0]
    ttc = time_to_collision(people - position, velocities - velocity, radius + radii)
    return float(cl.min()), float(np.nanmin(ttc)) if np.isfinite(velocities).all() else math.nan


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles (rad) wrapped to [-pi, pi)."""
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


def jerk(t: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(M - 3, 2) m/s^3: the third derivative of positions p (M, 2) at times t (M,) s by
    divided differences (exact for cubic motion, any spacing); empty below 4 samples."""
    if len(t) < 4:
        return np.zeros((0, 2))
    d1 = np.diff(p, axis=0) / np.diff(t)[:, None]
    d2 = np.diff(d1, axis=0) / (t[2:] - t[:-2])[:, None]
    d3 = np.diff(d2, axis=0) / (t[3:] - t[:-3])[:, None]
    return 6.0 * d3  # divided differences carry 1/k!
