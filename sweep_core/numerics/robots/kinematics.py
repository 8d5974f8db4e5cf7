"""Robot kinematics: commands clipped to the limits, and the exact motion of a step.

A command (vx, vy, omega) is in the robot's frame (m/s, m/s, rad/s); a diff_drive robot has
vy = 0. Held over a step of h s from pose (x, y, theta), the robot turns at omega and its
velocity turns with it, so the displacement is the integral of Rot(theta + omega s) (vx, vy)
over [0, h]:

    Rot(theta + omega h / 2) (vx, vy) h sinc(omega h / 2),   sinc(a) = sin(a) / a (1 at 0),

the arc of a circle (a straight segment when omega = 0), exactly; theta_1 = theta + omega h,
wrapped into (-pi, pi].
Sines and cosines come from :mod:`sweep_core.model.elementary`, so the bits do not depend on
the CPU.
"""
from __future__ import annotations

import math

from sweep_core.model import elementary
from sweep_core.model.robots import Robot


def sinc(a: float) -> float:
    """sin(a) / a, 1 at 0 (the series below 1e-4 rad, exact to rounding there)."""
    if abs(a) < 1e-4:
        return 1.0 - a * a / 6.0
    return elementary.sin(a) / a


def arc(pose: tuple[float, float, float], command: tuple[float, float, float],
        h: float) -> tuple[float, float, float]:
    """The pose after holding ``command`` (vx, vy, omega) for h s from ``pose`` (x, y, yaw)."""
    x, y, theta = pose
    vx, vy, omega = command
    half = 0.5 * omega * h
    mid = theta + half
    s, c = elementary.sincos(mid)
    k = h * sinc(half)
    return (x + k * (c * vx - s * vy), y + k * (s * vx + c * vy), wrap(theta + omega * h))


def wrap(angle: float) -> float:
    """``angle`` (rad) moved by a whole number of turns into (-pi, pi]; an angle already
    there is returned unchanged, bit for bit (IEEE remainder is exact)."""
    a = math.remainder(angle, 2.0 * math.pi)
    return math.pi if a <= -math.pi else a


def clip(robot: Robot, command: tuple[float, float, float],
         last: tuple[float, float, float], h: float) -> tuple[tuple[float, float, float], bool]:
    """The command the robot applies for a step of h s after ``last``: vy = 0 for diff_drive;
    each component's change limited to the acceleration times h; the speed |(vx, vy)| to
    max_speed (scaled along its direction) and |omega| to max_angular_speed. Returns it and
    whether anything was changed."""
    given = (float(command[0]), float(command[1]), float(command[2]))
    vx, vy, omega = given
    if robot.kinematics == "diff_drive":
        vy = 0.0
    dv = robot.max_acceleration * h
    dw = robot.max_angular_acceleration * h
    vx = min(max(vx, last[0] - dv), last[0] + dv)
    vy = min(max(vy, last[1] - dv), last[1] + dv)
    omega = min(max(omega, last[2] - dw), last[2] + dw)
    speed = math.hypot(vx, vy)
    if speed > robot.max_speed:
        scale = robot.max_speed / speed
        vx, vy = vx * scale, vy * scale
    omega = min(max(omega, -robot.max_angular_speed), robot.max_angular_speed)
    out = (vx, vy, omega)
    return out, out != given
