"""Who caused a robot-person contact, decided by the contact impulse the engine reports
(docs/social_bench.md).

A contact row between a robot and a person has multiplier lam (m) >= 0 along the unit normal e
from the robot to the person; the engine reports the impulse lam e / h (m/s) per person in
contact (``RobotState.contact_impulse``). The robot's displacement d (m) over the step (its
applied motion) contributes s_r = min(lam, max(0, <e, d>)) of lam: how far the robot itself
advanced towards the person along the contact normal; the rest, lam - s_r, is the person's own
push into the robot (drift, noise, the crowd). A contact row is **robot-on-person** when the
robot's share is the larger, s_r > lam / 2, else **person-on-robot** (the person's push was
at least as large; the robot may have stood still or moved away). A contact event (a person in
contact at a step who was not at the step before) is robot-on-person when any of its rows is:
a robot that keeps pushing into a person is found out within a few steps even among people
whose noise moves them farther per step than the robot.
"""
from __future__ import annotations

import numpy as np


def robot_shares(impulse: np.ndarray, displacement: np.ndarray, h: float) -> np.ndarray:
    """(K,) m: the robot's share s_r of each contact row's multiplier (module docstring).

    Args:
        impulse: (K, 2) m/s, the reported impulses lam e / h.
        displacement: (2,) m, the robot's displacement over the step.
        h: the step (s).
    """
    imp = np.asarray(impulse, dtype=np.float64).reshape(-1, 2)
    lam = np.hypot(imp[:, 0], imp[:, 1]) * h
    safe = np.where(lam > 0, lam, 1.0)
    e = imp * h / safe[:, None]
    move = np.asarray(displacement, dtype=np.float64)
    advance = e[:, 0] * move[0] + e[:, 1] * move[1]  # x-then-y, not BLAS
    return np.where(lam > 0, np.clip(advance, 0.0, lam), 0.0)


class ContactLog:
    """Contact events of one robot, fed step by step (:meth:`add`), split by cause."""

    def __init__(self) -> None:
        self.open: dict[int, bool] = {}
        self.robot_events = 0
        self.person_events = 0
        self.robot_impulse = 0.0
        self.person_impulse = 0.0

    def add(self, ids: np.ndarray, impulse: np.ndarray, displacement: np.ndarray,
            h: float) -> None:
        """One step's contacts: person ``ids`` (K,), their ``impulse`` (K, 2) m/s, the robot's
        ``displacement`` (2,) m over the step of h s."""
        if not len(ids):  # no contact: every open event ends
            self.open = {}
            return
        share = robot_shares(impulse, displacement, h)
        lam = np.hypot(*np.asarray(impulse, dtype=np.float64).reshape(-1, 2).T) * h
        self.robot_impulse += float(share.sum()) / h
        self.person_impulse += float((lam - share).sum()) / h
        now: dict[int, bool] = {}
        for i, robot in zip(np.asarray(ids).tolist(), (share > lam / 2).tolist(), strict=True):
            now[int(i)] = now.get(int(i), False) or bool(robot)
        for i, robot in now.items():
            if i not in self.open:
                if robot:
                    self.robot_events += 1
                else:
                    self.person_events += 1
            elif robot and not self.open[i]:  # an event found robot-caused later: moved over
                self.person_events -= 1
                self.robot_events += 1
            now[i] = robot or self.open.get(i, False)
        self.open = now
