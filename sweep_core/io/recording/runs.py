"""A simulator run recorded to MCAP as ``sweep run`` records it, shared by the CLI and the
ensemble's workers: the ``/poses`` and ``/agents`` channels, every ``record_every``-th state
(the first included), and a final ``sweep_status`` record however the run ends. When the
drift has a navigation field (geodesic, exits), ``/navigation_field`` holds it too, as the node
publishes it (:func:`~sweep_core.io.topics.encode_navigation`): with the first state, and again
with the first recorded state of each period a field with ``update_every`` is recomputed for.

What the bundled Foxglove layout and RViz config draw is recorded as the node publishes it
(:mod:`sweep_core.io.markers`): ``/walls`` (MarkerArray, latched) with the first state, again
whenever the simulator's walls change (``Simulator.set_scene``), and with every ``/markers``
while a wall or obstacle moves; ``/markers`` (people as disks of their radii coloured by
group, robots' footprints and headings) with every ``markers_every``-th recorded state (by
default at 10 Hz of simulated time: a message of N people weighs about 230 N bytes)."""
from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from sweep_core.errors import RecordingError, SweepError
from sweep_core.io import cdr, markers, robot_topics, topics
from sweep_core.io.cdr.markers import encode_marker_array
from sweep_core.io.live import LiveView
from sweep_core.io.metadata import STATUS_RECORD, status_metadata
from sweep_core.io.recording.background import BackgroundRecorder
from sweep_core.io.recording.format import qos_profiles
from sweep_core.model.geodesic import navigation_fields
from sweep_core.numerics import paths
from sweep_core.numerics.simulator import Simulator, State


@dataclass
class RecordedRun:
    """How a recorded run ended: ``status`` (completed, interrupted, failed), ``error`` (the
    signal or the error message; empty when completed), ``failure`` (the exception that ended
    it, for the caller to raise or report), ``steps`` taken and ``wall_s`` (s) stepping."""

    status: str
    error: str
    failure: BaseException | None
    steps: int
    wall_s: float


class Walls:
    """``/walls`` of a recorded run: written when the simulator's scene is another than the
    last written (the first state, ``set_scene``) and, while a wall moves, with the markers."""

    def __init__(self, frame_id: str, height: float) -> None:
        self.frame_id, self.height = frame_id, height
        self.scene: object = None
        self.moving = False

    def record(self, write: Callable[[str, int, bytes], None], sim: Simulator, ns: int,
               with_markers: bool) -> None:
        """Write ``/walls`` at stamp ``ns`` if they changed (or move and markers are due)."""
        changed = sim.scene is not self.scene
        if not (changed or (self.moving and with_markers)):
            return
        if changed:
            self.moving = markers.moving_walls(sim.scene.geometry)
        batches = markers.wall_batches(sim.scene.geometry, sim.scene.positions, sim.t,
                                       self.height, clear=self.scene is not None and changed)
        self.scene = sim.scene
        write(markers.WALLS, ns, encode_marker_array(ns, self.frame_id, batches))


def record_run(sim: Simulator, t_end: float, out: Path, metadata: dict[str, str], *,
               record_every: int = 1, frame_id: str = "map", path_dt: float | None = None,
               progress: bool = False, markers_every: int | None = None,
               marker_height: float = 1.0, live: LiveView | None = None,
               on_state: Callable[[Simulator], None] | None = None,
               inputs: Iterable[str | os.PathLike[str] | None] = ()) -> RecordedRun:
    """Steps ``sim`` to ``t_end`` (s), on a Brownian path drawn at ``path_dt`` when given,
    recording to ``out`` (a writer thread compresses and writes; each state's messages are
    handed to it at once, and at most 16 states' wait, so a writer that falls behind slows the
    run instead of filling the memory). ``on_state(sim)``
    is called after each state is recorded, the first included; a KeyboardInterrupt (or
    subclass, e.g. a signal turned into one) it raises ends the run as ``interrupted``. The
    run never raises once the recording is open: the outcome, written as the ``sweep_status``
    record too, is returned. ``out`` may be none of ``inputs`` (the scene and map files) and is
    locked while written (:mod:`sweep_core.io.outputs`): an OutputError is raised before the
    first step if it cannot be. ``markers_every`` (>= 1): ``/markers`` with every that many
    recorded states (``marker_height`` m tall); None: at
    :data:`~sweep_core.io.markers.MARKER_RATE_HZ` of simulated time. ``live``: every channel
    served to Foxglove too (:mod:`sweep_core.io.live`), paced after each recorded state."""
    status, error = "completed", ""
    failure: BaseException | None = None
    steps = 0
    wall = 0.0
    with BackgroundRecorder(out, metadata=metadata, max_backlog=16, inputs=inputs) as rec:
        def channel(name: str, msgtype: str, latched: bool = False) -> None:
            if latched:
                rec.add_channel(name, msgtype,
                                offered_qos_profiles=qos_profiles(1, transient_local=True))
            else:
                rec.add_channel(name, msgtype)
            if live is not None:
                live.add_channel(name, msgtype, latched)

        pending: list[tuple[str, int, bytes]] = []  # a state's messages, handed over at once

        def write(name: str, ns: int, data: bytes) -> None:
            pending.append((name, ns, data))
            if live is not None:
                live.write(name, ns, data)

        def hand_over() -> None:
            """The messages written since the last call to the writer thread, in one entry."""
            if pending:
                rec.write_many(pending.copy())
                pending.clear()

        for name, msgtype in topics.TYPES.items():
            channel("/" + name, msgtype)
        navigation: list[tuple | None] = []  # the key of the field last recorded, once there is one
        if navigation_fields(sim.drift):
            channel("/" + topics.NAVIGATION, cdr.POINT_CLOUD2, latched=True)
            navigation.append(None)
        for name, msgtype in robot_topics.channels(sim.scene).items():  # robots, if any
            channel(name, msgtype, latched=name == robot_topics.TF_STATIC)
        channel(markers.MARKERS, cdr.MARKER_ARRAY)
        channel(markers.WALLS, cdr.MARKER_ARRAY, latched=True)
        walls = Walls(frame_id, marker_height)
        every = (markers.markers_every(sim.dt, record_every) if markers_every is None
                 else max(int(markers_every), 1))
        recorded = 0  # states recorded so far
        if sim.robots is not None:
            ns0 = topics.stamp_ns(sim.t)
            write(robot_topics.TF_STATIC, ns0,
                      robot_topics.encode_static(sim.scene, ns0, frame_id))
            hand_over()

        def record(s: Simulator) -> None:
            nonlocal steps
            try:
                state = encode(s)
            finally:
                hand_over()
            if rec.error:
                raise RecordingError(rec.error)
            if live is not None and state.step % record_every == 0:
                live.pace(state.t)
            if state.step:
                steps += 1
            if on_state is not None:
                on_state(s)

        def encode(s: Simulator) -> State:
            """The messages of the state ``s`` is in, to ``write``; that state."""
            nonlocal recorded
            state = s.state
            if s.robots is not None:  # their messages; the applied commands every step
                ns = topics.stamp_ns(state.t)
                messages = (robot_topics.encode_step(s.robots, ns, frame_id)
                            if state.step % record_every == 0
                            else robot_topics.encode_commands(s.robots, ns))
                for name, data in messages:
                    write(name, ns, data)
            if state.step % record_every == 0:
                topics.record_state(write, state, frame_id)
                ns = topics.stamp_ns(state.t)
                with_markers = recorded % every == 0
                walls.record(write, s, ns, with_markers)
                if with_markers:
                    write(markers.MARKERS, ns, encode_marker_array(
                        ns, frame_id, markers.state_batches(s, height=marker_height,
                                                            state=state)))
                recorded += 1
                if navigation and topics.navigation_key(s.drift, state.t) != navigation[0]:
                    navigation[0] = topics.navigation_key(s.drift, state.t)
                    ns = topics.stamp_ns(state.t)
                    write("/" + topics.NAVIGATION, ns,
                              topics.encode_navigation(ns, frame_id, s.drift, state.t))
            return state

        start = time.perf_counter()
        try:
            record(sim)
            if path_dt:
                paths.run(sim, t_end, path_dt, progress=progress, callback=record)
            else:
                sim.run(t_end, progress=progress, callback=record)
        except KeyboardInterrupt as err:  # SIGINT, or a signal the caller turned into one
            status, error, failure = "interrupted", str(err) or "SIGINT", err
        except Exception as err:  # noqa: BLE001 - recorded as the run's status, returned
            status, failure = "failed", err
            error = str(err) if isinstance(err, SweepError) else f"{type(err).__name__}: {err}"
        wall = time.perf_counter() - start
        rec.metadata(STATUS_RECORD, status_metadata(status, steps=steps, t=sim.t, error=error))
    if rec.error and status == "completed":
        status, error = "failed", rec.error
        failure = RecordingError(rec.error)
    return RecordedRun(status, error, failure, steps, wall)
