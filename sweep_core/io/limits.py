"""Bounds on the size of a run, shared by ``sweep run`` and the node: the time-step range, the
step count and the recording size a run may reach without ``--force``
(:func:`check_dt`, :func:`check_some_step`, :func:`check_run_size`, :func:`frame_bytes`).

The node's ``dt`` parameter range is [:data:`DT_MIN`, :data:`DT_MAX`]; ``sweep run --dt`` uses
the same range, so a scene that runs in one runs in the other.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sweep_core import checks
from sweep_core.errors import SceneError
from sweep_core.io import cdr, topics

#: smallest time step, s (the node's ``dt`` parameter range starts here)
DT_MIN = 1e-5
#: largest time step, s (the node's ``dt`` parameter range ends here)
DT_MAX = 1.0
#: most steps (or fine Brownian increments, ``--path-dt``) a run takes without ``--force``
MAX_STEPS = 1_000_000
#: largest recording a run writes without ``--force``, bytes (uncompressed message payloads)
MAX_RECORDING_BYTES = 2_000_000_000
#: bytes an MCAP message record adds to its payload (opcode, length, channel, sequence, times)
_RECORD_OVERHEAD = 1 + 8 + 2 + 4 + 8 + 8


def _fmt_bytes(n: float) -> str:
    """Bytes in decimal units: ``2 GB``, ``35.2 MB``."""
    for unit, size in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:g} B"


def check_dt(dt: object, field: str = "dt") -> float:
    """``dt`` (s) as a float in [DT_MIN, DT_MAX]; else a SceneError naming ``field``."""
    value = checks.number(dt, field, positive=True)
    if not DT_MIN <= value <= DT_MAX:
        raise SceneError(field, f"{value:g} s is outside [{DT_MIN:g}, {DT_MAX:g}] s, the time "
                                "steps sweep run and sweep_node accept",
                         f"a time step between {DT_MIN:g} and {DT_MAX:g} s")
    return value


def check_some_step(t_end: float, dt: float, outcome: str, field: str = "--t-end") -> int:
    """The steps of a run of ``t_end`` s at ``dt`` s, ``round(t_end / dt)`` as
    ``Simulator.run`` takes them; a SceneError naming ``field`` when that is none (``t_end``
    below half a step). ``outcome`` says what such a run would give, e.g. "the recording would
    hold its start only"; the fix given is ``dt`` itself, the shortest time of one step."""
    steps = int(round(t_end / dt))
    if steps == 0:
        raise SceneError(field, f"{t_end:g} s at dt = {dt:g} s is no step: {outcome}",
                         f"{field} {dt:g} or more")
    return steps


def frame_bytes(n_agents: int, frame_id: str = "map") -> int:
    """Bytes one recorded state adds to a recording before compression: the ``poses`` and
    ``agents`` messages of ``n_agents`` agents (88 bytes per agent) with their MCAP records."""
    fields = {name: np.zeros(n_agents, dtype=np.float32) for name in topics.AGENT_FIELDS}
    payload = (len(cdr.encode_pose_array(0, frame_id, np.zeros((n_agents, 2))))
               + len(cdr.encode_point_cloud2(0, frame_id, fields)))
    return payload + len(topics.TYPES) * _RECORD_OVERHEAD


@dataclass(frozen=True)
class RunSize:
    """What a run will do: ``steps`` of dt, ``frames`` recorded, ``recording_bytes`` estimated
    (uncompressed; zstd usually writes less)."""

    steps: int
    frames: int
    recording_bytes: int


def recording_bytes(n_agents: int, frames: int, every_s: float,
                    entries: np.ndarray | None = None, frame_id: str = "map",
                    most: int | None = None) -> int:
    """Bytes (uncompressed) of ``frames`` states recorded every ``every_s`` s from t = 0 of a
    run of ``n_agents`` initial agents, and of the agents entering at their sources: an agent
    counts from its source time on (``entries``, s; it enters then or later, never before),
    as if it never left (sinks are not counted), and never more than ``most`` agents at once
    (what the room holds, :func:`sweep_core.model.room.most_present`; None: no bound): an
    upper bound."""
    if entries is None or not len(entries):
        return frames * frame_bytes(n_agents, frame_id)
    base = frame_bytes(n_agents, frame_id)
    per_agent = frame_bytes(n_agents + 1, frame_id) - base
    t = np.arange(frames, dtype=np.float64) * every_s
    entered = np.searchsorted(np.sort(entries), t * (1 + 1e-12), side="right")
    if most is not None:
        entered = np.minimum(entered, max(most - n_agents, 0))
    return frames * base + int(entered.sum()) * per_agent


def check_run_size(n_agents: int, dt: float, t_end: float, record_every: int = 1, *,
                   path_dt: float | None = None, frame_id: str = "map",
                   force: bool = False, entries: np.ndarray | None = None,
                   most: int | None = None) -> RunSize:
    """The size of a run of ``t_end`` s at ``dt`` s recording every ``record_every``-th step,
    with ``n_agents`` initial agents and agents entering at the times ``entries`` (s; a
    source's times), at most ``most`` present at once (:func:`recording_bytes`).

    Raises:
        SceneError: unless ``force``, when the run takes more than :data:`MAX_STEPS` steps (or
            fine increments at ``path_dt``) or its recording would exceed
            :data:`MAX_RECORDING_BYTES`; the message names the option, the value, the limit and
            the fix. (``--t-end``, ``--dt``, ``--record-every`` name the CLI's options.)
    """
    steps = int(round(t_end / dt))
    frames = steps // record_every + 1
    # frames counted one by one up to MAX_STEPS + 1 of them (a forced longer run: scaled)
    counted = min(frames, MAX_STEPS + 1)
    size = RunSize(steps, frames, recording_bytes(n_agents, counted, record_every * dt,
                                                  entries, frame_id, most) * frames // counted)
    if force:
        return size
    if steps > MAX_STEPS:
        shorter = f"a shorter --t-end (<= {MAX_STEPS * dt:g} s)"
        if t_end / MAX_STEPS <= DT_MAX:
            fix = f"a larger --dt (>= {t_end / MAX_STEPS:g} s), {shorter}, or --force"
        else:  # no time step takes it within the limit
            fix = (f"{shorter}; at most {MAX_STEPS * DT_MAX:g} s, at the largest --dt "
                   f"{DT_MAX:g} s")
        raise SceneError("--t-end/--dt", f"{t_end:g} s at dt = {dt:g} s is {steps:g} steps, "
                         f"more than the limit {MAX_STEPS:g}", fix)
    if path_dt is not None:
        fine = int(round(t_end / path_dt))
        if fine > MAX_STEPS:
            raise SceneError("--path-dt", f"{path_dt:g} s over {t_end:g} s draws {fine:g} fine "
                             f"increments, more than the limit {MAX_STEPS:g}",
                             f"a larger --path-dt (>= {t_end / MAX_STEPS:g} s, at most --dt), "
                             "a shorter --t-end, or --force")
    if size.recording_bytes > MAX_RECORDING_BYTES:
        room = MAX_RECORDING_BYTES * frames // size.recording_bytes - 1  # frames after 0
        fix = "fewer agents or --force"
        more = (f" and up to {len(entries)} entering at sources" if entries is not None
                and len(entries) else "")
        if most is not None and more:
            more += f", at most {most} present at once in the room"
        if room > 0:
            k = max(record_every + 1, math.ceil(steps / room))
            fix = f"--record-every {k} or more, a shorter --t-end, or --force"
        raise SceneError("--record-every", f"{record_every} records {frames:g} states of "
                         f"{n_agents} agents{more}, about {_fmt_bytes(size.recording_bytes)} "
                         f"uncompressed, more than the limit {_fmt_bytes(MAX_RECORDING_BYTES)}",
                         fix)
    return size
