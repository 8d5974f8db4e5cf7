"""What a run publishes and records: topic names, types and the CDR payloads of a state.

Shared by ``sweep run`` and the ROS node, so a recording looks the same whichever made it.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from sweep_core.io import cdr
from sweep_core.model.fields import Field
from sweep_core.model.geodesic import Geodesic, navigation_fields
from sweep_core.numerics.simulator import State

POSES = "poses"
AGENTS = "agents"
#: float32 fields of the ``agents`` PointCloud2, in order
AGENT_FIELDS = ("id", "x", "y", "radius", "vx", "vy", "reaction_x", "reaction_y")
TYPES = {POSES: cdr.POSE_ARRAY, AGENTS: cdr.POINT_CLOUD2}
#: the navigation field of the drift in effect (latched): see :func:`encode_navigation`
NAVIGATION = "navigation_field"
#: float32 fields of the ``navigation_field`` PointCloud2, in order
NAVIGATION_FIELDS = ("x", "y", "z", "T", "vx", "vy", "group")


def agent_fields(state: State) -> dict[str, np.ndarray]:
    """The ``agents`` cloud columns of a state (float32 each, shape (N,)); ``id``: the
    agents' ids (with flows, agents enter and leave: ids are kept, exact up to 2^24)."""
    q, v, k = state.positions, state.velocities, state.reaction
    ids = np.arange(len(q)) if state.ids is None else state.ids
    return {"id": ids.astype(np.float32), "x": q[:, 0], "y": q[:, 1],
            "radius": state.radii, "vx": v[:, 0], "vy": v[:, 1],
            "reaction_x": k[:, 0], "reaction_y": k[:, 1]}


def stamp_ns(t: float) -> int:
    """Simulation time t (s) as integer nanoseconds."""
    return int(round(t * 1e9))


#: states of at most this many agents have their ``agents`` cloud filled as one float32 block
_BLOCK_UP_TO = 1024


def _agents_cloud(ns: int, frame_id: str, state: State) -> bytes:
    """The ``agents`` cloud of a state (:func:`agent_fields`), its columns cast to float32 in
    five assignments (positions, velocities and reactions two columns at once)."""
    q = state.positions
    n = len(q)
    if n > _BLOCK_UP_TO or q.shape != (n, 2) or state.velocities.shape != (n, 2) \
            or state.reaction.shape != (n, 2) or state.radii.shape != (n,) \
            or (state.ids is not None and state.ids.shape != (n,)):
        return cdr.encode_point_cloud2(ns, frame_id, agent_fields(state))
    block = np.empty((n, len(AGENT_FIELDS)), dtype=np.float32)
    with np.errstate(over="ignore", invalid="ignore"):  # as encode_point_cloud2 casts
        block[:, 0] = np.arange(n) if state.ids is None else state.ids
        block[:, 1:3] = q
        block[:, 3] = state.radii
        block[:, 4:6] = state.velocities
        block[:, 6:8] = state.reaction
    return cdr.encode_float32_cloud(ns, frame_id, AGENT_FIELDS, block)


def encode_state(state: State, frame_id: str = "map") -> dict[str, bytes]:
    """CDR payloads of ``poses`` and ``agents`` for a state, stamped with simulation time."""
    ns = stamp_ns(state.t)
    return {POSES: cdr.encode_pose_array(ns, frame_id, state.positions),
            AGENTS: _agents_cloud(ns, frame_id, state)}


def record_state(write: Callable[[str, int, bytes], None], state: State,
                 frame_id: str = "map") -> None:
    """Hand the payloads of a state to ``write("/" + topic, stamp_ns, data)``: what ``sweep run``
    does on the stepping thread for every recorded step (``sweep bench recording`` times it)."""
    ns = stamp_ns(state.t)
    for name, data in encode_state(state, frame_id).items():
        write("/" + name, ns, data)


def navigation_epoch(field: Geodesic, t: float) -> int:
    """The recomputation period of a navigation field holding time t (s): 0 for a field
    computed once; with ``update_every`` the k of [k s, (k + 1) s) (as Geodesic.arrays)."""
    if field.update_every is None:
        return 0
    return max(int(math.floor(t / field.update_every + 1e-9)), 0)


def navigation_key(drift: Field, t: float) -> tuple:
    """What the ``navigation_field`` message of a drift at t depends on: it needs publishing
    again exactly when this changes (another field object, or another period of one that is
    recomputed)."""
    return tuple((k, id(f), navigation_epoch(f, t)) for k, f in navigation_fields(drift))


def encode_navigation(stamp_ns: int, frame_id: str, drift: Field, t: float) -> bytes:
    """CDR ``navigation_field`` of a drift at t (s): a PointCloud2 of the grid nodes of each of
    its navigation fields, fields x, y, z = 0 (m), T (the travel distance to the goal, m;
    travel time = T / speed), vx, vy (the drift there, m/s) and group (-1 for the whole drift
    or the rest of a groups drift, k for group k). One field: an organised cloud, a row per y
    node (rows along y, columns along x, as ``velocity_field`` reads it); several: their
    nodes one after the other (height 1); none: an empty cloud (viewers clear it)."""
    found = navigation_fields(drift)
    cols: dict[str, list[np.ndarray]] = {name: [] for name in NAVIGATION_FIELDS}
    for k, f in found:
        _, distance = f.arrays(t)
        X, Y = np.meshgrid(f.x, f.y)
        nodes = np.stack([X.ravel(), Y.ravel()], axis=1)
        v = f(t, nodes)
        cols["x"].append(nodes[:, 0])
        cols["y"].append(nodes[:, 1])
        cols["z"].append(np.zeros(len(nodes)))
        cols["T"].append(distance.ravel())
        cols["vx"].append(v[:, 0])
        cols["vy"].append(v[:, 1])
        cols["group"].append(np.full(len(nodes), float(k)))
    fields = {name: (np.concatenate(c) if c else np.zeros(0, dtype=np.float32))
              for name, c in cols.items()}
    height = len(found[0][1].y) if len(found) == 1 else 1
    return cdr.encode_point_cloud2(stamp_ns, frame_id, fields, height=height)
