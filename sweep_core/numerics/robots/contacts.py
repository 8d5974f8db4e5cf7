"""The robots' contacts after a step, from the projection's multipliers (:mod:`.fleet`): each
robot's people touching it (``contact_ids``), their positions (``contact_xy``, m) and the
impulse each row's multiplier gives (``contact_impulse``, lam * gradient / h, m/s).

The rows of one robot are picked in one compiled pass each (:func:`circle_contacts` for a
prescribed robot's disk, :func:`pair_contacts` for a robot of finite weight), with the numpy
expressions' operations in their order: the impulse of a row is (lam * n) / h, or
((-lam) * e) / h for a pair row whose first agent is the robot."""
from __future__ import annotations

from typing import Any

import numba
import numpy as np

from sweep_core.model.geometry import CIRCLE
from sweep_core.numerics.projection import Projection


@numba.njit(cache=True, nogil=True)
def circle_contacts(kind: np.ndarray, item: np.ndarray, agent: np.ndarray, normal: np.ndarray,
                    lam: np.ndarray, circle: int, want: int, h: float, ids: np.ndarray,
                    imp: np.ndarray) -> int:  # pragma: no cover - compiled
    """The single rows of circle item ``want`` (kind ``circle``) with lam > 0, in row order:
    their agents into ``ids`` (M,) and lam * normal / h into ``imp`` (M, 2); their count."""
    m = 0
    for k in range(lam.shape[0]):
        if kind[k] == circle and item[k] == want and lam[k] > 0:
            ids[m] = agent[k]
            imp[m, 0] = lam[k] * normal[k, 0] / h
            imp[m, 1] = lam[k] * normal[k, 1] / h
            m += 1
    return m


@numba.njit(cache=True, nogil=True)
def pair_contacts(pi: np.ndarray, pj: np.ndarray, e: np.ndarray, lam: np.ndarray, me: int,
                  n: int, h: float, ids: np.ndarray, imp: np.ndarray
                  ) -> int:  # pragma: no cover - compiled
    """The pair rows of agent ``me`` with a person (index < n) and lam > 0: first those where
    ``me`` is the first agent (impulse -lam e / h), then the second (lam e / h), each in row
    order; the other agents into ``ids``, the impulses into ``imp`` (M, 2); their count."""
    m = 0
    for k in range(lam.shape[0]):
        if pi[k] == me and pj[k] < n and lam[k] > 0:
            ids[m] = pj[k]
            imp[m, 0] = -lam[k] * e[k, 0] / h
            imp[m, 1] = -lam[k] * e[k, 1] / h
            m += 1
    for k in range(lam.shape[0]):
        if pj[k] == me and pi[k] < n and lam[k] > 0:
            ids[m] = pi[k]
            imp[m, 0] = lam[k] * e[k, 0] / h
            imp[m, 1] = lam[k] * e[k, 1] / h
            m += 1
    return m


def set_contacts(states: list[Any], proj: Projection, n: int, n_circles: int, h: float
                 ) -> None:
    """Sets each ``RobotState``'s contacts with people from ``proj`` (n people first in its
    positions, then the robots that are not prescribed, whose contacts with robots are left
    out; the prescribed ones are circle items after the scene's ``n_circles``), sorted by the
    people's rows in ``proj`` (the simulator names them by id with flows); a step of h s."""
    rows = proj.rows
    lam_p, lam_s = proj.lam_pair, proj.lam_single
    fixed = free = 0
    for st in states:
        if st.robot.prescribed:
            ids = np.empty(len(lam_s), dtype=np.int64)
            imp = np.empty((len(lam_s), 2))
            m = circle_contacts(rows.single_kind, rows.single_item, rows.single_a,
                                rows.single_n, lam_s, CIRCLE, n_circles + fixed, float(h), ids,
                                imp)
            fixed += 1
            person = ids[:m] < n  # a robot of finite weight (a row after the people) is none
            if not person.all():
                ids, imp, m = ids[:m][person], imp[:m][person], int(person.sum())
        else:
            ids = np.empty(len(lam_p), dtype=np.int64)
            imp = np.empty((len(lam_p), 2))
            m = pair_contacts(rows.pair_i, rows.pair_j, rows.pair_e, lam_p, n + free, n,
                              float(h), ids, imp)
            free += 1
        if m == 0:
            st.contact_ids = np.empty(0, dtype=np.int64)
            st.contact_xy = np.empty((0, 2))
            st.contact_impulse = np.empty((0, 2))
            continue
        order = np.argsort(ids[:m], kind="stable")
        st.contact_ids = ids[order]
        st.contact_xy = proj.y[st.contact_ids]
        st.contact_impulse = imp[order]
