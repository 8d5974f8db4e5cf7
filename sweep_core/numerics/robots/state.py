"""One robot's state in a running simulation (:class:`RobotState`, what
:class:`.fleet.Fleet` keeps per robot and steps), and the command triple."""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from sweep_core.model.robots import Robot
from sweep_core.numerics.robots.scan import Scan

Command = tuple[float, float, float]


@dataclass
class RobotState:
    """One robot now: ``pose`` (x, y, yaw) m, rad; ``twist`` (vx, vy, omega) in its own frame
    over the last step (the applied command, plus the push of the crowd for a robot of finite
    weight: its reaction / h turned into the robot's frame); ``command`` the command applied in
    the last step (after clipping); ``held`` the command held for the next steps; ``clipped``
    commands changed by clipping so far; ``blocked`` steps its prescribed motion was refused so
    far; ``stopped`` the last step was one; ``contact_ids`` (K,) the ids of the people touching
    it in the last step (``Simulator.ids``: with flows an agent's id, not its row, which
    changes as others leave), ``contact_xy`` (K, 2) m their positions at its end,
    ``contact_impulse`` (K, 2) m/s (module docstring); ``scan`` the latest scan or None."""

    robot: Robot
    pose: tuple[float, float, float]
    twist: Command = (0.0, 0.0, 0.0)
    command: Command = (0.0, 0.0, 0.0)
    held: Command = (0.0, 0.0, 0.0)
    raw: bool = False
    clipped: int = 0
    blocked: int = 0
    stopped: bool = False
    contact_ids: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    contact_xy: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    contact_impulse: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    scan: Scan | None = None

    def copy(self) -> RobotState:
        """A shallow copy (what ``dataclasses.replace(self)`` gives, without its checks)."""
        new = object.__new__(RobotState)
        new.__dict__.update(self.__dict__)
        return new

    @property
    def goal_reached(self) -> bool:
        g = self.robot.goal
        return g is not None and math.hypot(self.pose[0] - g[0],
                                            self.pose[1] - g[1]) <= self.robot.goal_radius
