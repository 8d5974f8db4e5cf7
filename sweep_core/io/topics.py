"""What a run publishes and records: topic names, types and the CDR payloads of a state.

Shared by ``sweep run`` and the ROS node, so a recording looks the same whichever made it.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sweep_core.io import cdr
from sweep_core.numerics.simulator import State

POSES = "poses"
AGENTS = "agents"
#: float32 fields of the ``agents`` PointCloud2, in order
AGENT_FIELDS = ("id", "x", "y", "radius", "vx", "vy", "reaction_x", "reaction_y")
TYPES = {POSES: cdr.POSE_ARRAY, AGENTS: cdr.POINT_CLOUD2}


def agent_fields(state: State) -> dict[str, np.ndarray]:
    """The ``agents`` cloud columns of a state (float32 each, shape (N,))."""
    q, v, k = state.positions, state.velocities, state.reaction
    return {"id": np.arange(len(q), dtype=np.float32), "x": q[:, 0], "y": q[:, 1],
            "radius": state.radii, "vx": v[:, 0], "vy": v[:, 1],
            "reaction_x": k[:, 0], "reaction_y": k[:, 1]}


def stamp_ns(t: float) -> int:
    """Simulation time t (s) as integer nanoseconds."""
    return int(round(t * 1e9))


def encode_state(state: State, frame_id: str = "map") -> dict[str, bytes]:
    """CDR payloads of ``poses`` and ``agents`` for a state, stamped with simulation time."""
    ns = stamp_ns(state.t)
    return {POSES: cdr.encode_pose_array(ns, frame_id, state.positions),
            AGENTS: cdr.encode_point_cloud2(ns, frame_id, agent_fields(state))}


def record_state(write: Callable[[str, int, bytes], None], state: State,
                 frame_id: str = "map") -> None:
    """Hand the payloads of a state to ``write("/" + topic, stamp_ns, data)``: what ``sweep run``
    does on the stepping thread for every recorded step (``sweep bench recording`` times it)."""
    ns = stamp_ns(state.t)
    for name, data in encode_state(state, frame_id).items():
        write("/" + name, ns, data)
