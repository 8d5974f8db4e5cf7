"""The actions of ``sweep/CrowdNav-v0`` checked and turned into the robot's command.

:class:`Actions` refuses what is not the box's number of finite numbers (a string, a dict,
complex numbers, NaN, the wrong length), clips the rest to the box (np.clip's values) and
gives the command (vx, vy, omega) the engine holds for a step. An action of finite numbers
given as a float64 array of the box's shape (what ``action_space.sample()`` and the vector
environment's rows are) is checked and clipped without numpy's calls, to the same values, bit
for bit (the box's bounds nonzero: no signed zero to tell apart); any other goes through
numpy's.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from gymnasium import spaces

from sweep_core.errors import SceneError, show

#: the dtype of the actions the fast path takes as they are
_FLOAT64 = np.dtype(np.float64)


class Actions:
    """The checks of a robot's actions: ``box`` the action space ((v, omega) of a
    ``diff_drive`` robot, (vx, vy, omega) of a ``holonomic`` one, m/s and rad/s)."""

    def __init__(self, box: spaces.Box, holonomic: bool) -> None:
        self.box, self.holonomic = box, holonomic
        #: the box's bounds as floats (the fast path's)
        self.low: tuple[float, ...] = tuple(box.low.tolist())
        self.high: tuple[float, ...] = tuple(box.high.tolist())
        #: the fast path holds: each bound is nonzero, the lower below 0, the upper above
        self.fast = all(low < 0.0 < high for low, high in zip(self.low, self.high))

    def command(self, action: Any) -> tuple[float, float, float]:
        """The robot's command (vx, vy, omega) (m/s, m/s, rad/s) of an action, clipped to the
        box; refused (SceneError) unless the action is the box's number of finite numbers."""
        if self.fast and type(action) is np.ndarray and action.dtype is _FLOAT64 \
                and action.shape == self.box.shape:
            # the common case, finite numbers: clipped here (the bounds are nonzero, so
            # where a value equals one the two are the same float, whichever numpy returns)
            clipped = []
            for v, low, high in zip(action.tolist(), self.low, self.high):
                if not -math.inf < v < math.inf:  # NaN or infinite: refused below
                    break
                clipped.append(low if v < low else high if v > high else v)
            else:
                return ((clipped[0], clipped[1], clipped[2]) if self.holonomic
                        else (clipped[0], 0.0, clipped[1]))
        n = self.box.shape[0]
        try:
            if np.iscomplexobj(action):  # numpy would drop the imaginary parts, silently
                raise TypeError(action)
            a = np.asarray(action, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):  # a string, a dict, complex numbers
            raise SceneError("action", f"must be {n} finite numbers, got {show(action)}",
                             "give an element of env.action_space") from None
        if a.shape != self.box.shape or not np.isfinite(a).all():
            raise SceneError("action", f"must be {n} finite numbers, got {show(a)}",
                             "give an element of env.action_space")
        # np.clip's values on finite actions, without its Python wrapper
        a = np.minimum(np.maximum(a, self.box.low), self.box.high)
        cmd = (a[0], a[1], a[2]) if self.holonomic else (a[0], 0.0, a[1])
        return float(cmd[0]), float(cmd[1]), float(cmd[2])
