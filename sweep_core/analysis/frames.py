"""The frames of a recording, one per recorded step (:class:`FrameReader`)."""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core.analysis.run import RunMeta
from sweep_core.io import cdr
from sweep_core.io.recording import read_recording


@dataclass
class Frame:
    """One recorded state: log time and stamp (ns), float64 centres (N, 2) and the float32
    ``/agents`` columns (None if that message is missing)."""

    log_ns: int
    stamp_ns: int
    positions: np.ndarray
    agents: dict[str, np.ndarray] | None


class FrameReader:
    """Iterates the frames of a recording in file order; after the iteration ``truncated``
    and ``error`` tell whether (and where) the file was cut short."""

    def __init__(self, meta: RunMeta, agents: bool = True) -> None:
        self.meta = meta
        self.want_agents = agents and meta.agents_topic is not None
        topics = [meta.poses_topic] + ([meta.agents_topic] if self.want_agents else [])
        self._reader = read_recording(meta.path, topics)
        self.truncated: bool | None = None
        self.error: str | None = None

    def __iter__(self) -> Iterator[Frame]:
        pending: dict[int, list] = {}
        poses_topic = self.meta.poses_topic
        try:
            for msg in self._reader:
                slot = pending.setdefault(msg.log_time_ns, [None, None])
                if msg.topic == poses_topic:
                    stamp, _, q = cdr.decode_pose_array(msg.data)
                    slot[0] = (stamp, q)
                else:
                    slot[1] = cdr.decode_point_cloud2(msg.data).fields
                if slot[0] is not None and (slot[1] is not None or not self.want_agents):
                    for key in sorted(k for k in pending if k <= msg.log_time_ns):
                        done = pending.pop(key)
                        if done[0] is not None:
                            yield Frame(key, done[0][0], done[0][1], done[1])
            for key in sorted(pending):
                done = pending[key]
                if done[0] is not None:
                    yield Frame(key, done[0][0], done[0][1], done[1])
        finally:
            self._reader.close()
            self.truncated = self._reader.truncated
            self.error = self._reader.error


def progress_bar(total: int | None, unit: str, enabled: bool) -> Any:
    """A tqdm bar on stderr (only on a terminal), or a no-op."""
    from tqdm import tqdm
    return tqdm(total=total, unit=unit, dynamic_ncols=True, disable=None if enabled else True,
                leave=False)
