"""The robots' contacts after a step, from the projection's multipliers (:mod:`.fleet`): each
robot's people touching it (``contact_ids``), their positions (``contact_xy``, m) and the
impulse each row's multiplier gives (``contact_impulse``, lam * gradient / h, m/s)."""
from __future__ import annotations

from typing import Any

import numpy as np

from sweep_core.model.geometry import CIRCLE
from sweep_core.numerics.projection import Projection


def set_contacts(states: list[Any], proj: Projection, n: int, n_circles: int, h: float
                 ) -> None:
    """Sets each ``RobotState``'s contacts from ``proj`` (n people first in its positions,
    then the robots that are not prescribed; the prescribed ones are circle items after the
    scene's ``n_circles``), sorted by person id; a step of h s."""
    free = [k for k, st in enumerate(states) if not st.robot.prescribed]
    fixed = [k for k, st in enumerate(states) if st.robot.prescribed]
    rows = proj.rows
    lam_p, lam_s = proj.lam_pair, proj.lam_single
    if not (np.any(lam_p > 0) or np.any(lam_s > 0)):  # no row pushes: no contact
        for st in states:
            st.contact_ids = np.empty(0, dtype=np.int64)
            st.contact_xy = np.empty((0, 2))
            st.contact_impulse = np.empty((0, 2))
        return
    for k, st in enumerate(states):
        if st.robot.prescribed:
            item = n_circles + fixed.index(k)
            pick = np.flatnonzero((rows.single_kind == CIRCLE) & (rows.single_item == item)
                                  & (lam_s > 0))
            ids = rows.single_a[pick]
            imp = lam_s[pick, None] * rows.single_n[pick] / h
        else:
            me = n + free.index(k)
            as_i = np.flatnonzero((rows.pair_i == me) & (rows.pair_j < n) & (lam_p > 0))
            as_j = np.flatnonzero((rows.pair_j == me) & (rows.pair_i < n) & (lam_p > 0))
            ids = np.concatenate([rows.pair_j[as_i], rows.pair_i[as_j]])
            imp = np.concatenate([-lam_p[as_i, None] * rows.pair_e[as_i],
                                  lam_p[as_j, None] * rows.pair_e[as_j]]) / h
        order = np.argsort(ids, kind="stable")
        st.contact_ids = ids[order].astype(np.int64)
        st.contact_xy = proj.y[st.contact_ids].copy()
        st.contact_impulse = imp[order].reshape(-1, 2)
