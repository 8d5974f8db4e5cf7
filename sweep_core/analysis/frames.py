"""The frames of a recording, one per recorded step (:class:`FrameReader`)."""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from sweep_core.analysis.run import RunMeta
from sweep_core.io import cdr
from sweep_core.io.recording import RecordedMessage, read_recording


@dataclass
class Frame:
    """One recorded state: log time and stamp (ns), float64 centres (N, 2) and the float32
    ``/agents`` columns (None if that message is missing or unreadable); ``sequence`` of its
    ``/poses`` message (0 if the writer does not count) and ``missing_before``, how many
    ``/poses`` messages the sequence numbers say are missing between the previous one read
    and this one (0: none)."""

    log_ns: int
    stamp_ns: int
    positions: np.ndarray
    agents: dict[str, np.ndarray] | None
    sequence: int = 0
    missing_before: int = 0


#: at most this many bad messages are described one by one (the rest are counted)
SHOW_BAD = 5


class FrameReader:
    """Iterates the frames of a recording in file order; after the iteration ``truncated``
    and ``error`` tell whether (and where) the file was cut short.

    A message that cannot be decoded (damaged CDR, another encoding) is skipped, and so is an
    unreadable chunk: the rest of the file is read. ``bad`` counts the skipped messages and
    ``problems`` describes them and the skipped chunks, one line each (topic, message index,
    byte offset, why; at most :data:`SHOW_BAD` messages one by one). ``missing`` counts the
    ``/poses`` messages the sequence numbers say were never there (removed, lost)."""

    def __init__(self, meta: RunMeta, agents: bool = True) -> None:
        self.meta = meta
        self.want_agents = agents and meta.agents_topic is not None
        topics = [meta.poses_topic] + ([meta.agents_topic] if self.want_agents else [])
        self._reader = read_recording(meta.path, topics)
        self.truncated: bool | None = None
        self.error: str | None = None
        self.bad = 0
        self.missing = 0
        self.problems: list[str] = []
        #: the chunks that could not be read and were skipped, one line each (after the
        #: iteration)
        self.skipped_chunks: list[str] = []
        self._bad_lines: list[str] = []
        #: the states left out for want of their /agents ids, one line each (without the path)
        self.left_out: list[str] = []
        self._last_sequence = 0

    def _skip(self, msg: RecordedMessage, err: Exception) -> None:
        self.bad += 1
        if len(self._bad_lines) < SHOW_BAD:
            text = str(err).splitlines()[0] if str(err) else ""
            text = text if len(text) <= 160 else text[:157] + "..."
            self._bad_lines.append(f"{self.meta.path}: {msg.where()}: skipped, it cannot be "
                                   f"decoded ({type(err).__name__}: {text})")

    def _decode(self, msg: RecordedMessage) -> Any:
        if msg.encoding != "cdr":
            raise ValueError(f"its encoding is {msg.encoding!r}, not cdr")
        if msg.topic == self.meta.poses_topic:
            stamp, _, q = cdr.decode_pose_array(msg.data)
            return stamp, q
        return cdr.decode_point_cloud2(msg.data).fields

    def _gap(self, msg: RecordedMessage) -> int:
        """/poses messages missing before ``msg`` by the sequence numbers (0 if not counted)."""
        last, self._last_sequence = self._last_sequence, msg.sequence
        if not last or not msg.sequence:
            return 0
        missing = (msg.sequence - last - 1) & 0xFFFFFFFF
        return missing if missing < 1 << 31 else 0  # backwards: another writer, not a gap

    def _lost_ids(self, key: int, done: list) -> bool:
        """True (and a note) when the state at log time ``key`` has no ``/agents`` because
        its message was in a skipped chunk, where agents come and go: without its ids that
        state is left out, as the chunk's own states are."""
        if done[1] is not None or not self.want_agents or not self.meta.changes_population:
            return False
        if not any(a <= key <= b for a, b in self._reader.lost_spans):
            return False
        self._leave_out(f"the /poses at t = {key / 1e9:g} s has no /agents: it was in a "
                        "skipped chunk; that state is left out")
        return True

    def _leave_out(self, why: str) -> None:
        self.left_out.append(why)
        self._bad_lines.append(f"{self.meta.path}: {why}")

    def none_read(self) -> str:
        """Why no state was read, for an error that there is none: the file's own error and
        the first state left out (empty when neither)."""
        why = [w for w in (self.error, *self.left_out[:1]) if w]
        return f" ({'; '.join(why)})" if why else ""

    def __iter__(self) -> Iterator[Frame]:
        pending: dict[int, list] = {}
        poses_topic = self.meta.poses_topic
        try:
            for msg in self._reader:
                is_poses = msg.topic == poses_topic
                missing = self._gap(msg) if is_poses else 0
                self.missing += missing
                try:
                    decoded = self._decode(msg)
                except Exception as err:  # noqa: BLE001 - any decoding failure: skip, report
                    self._skip(msg, err)
                    continue
                slot = pending.setdefault(msg.log_time_ns, [None, None, 0, 0])
                if is_poses:
                    slot[0], slot[2], slot[3] = decoded, msg.sequence, missing
                else:
                    slot[1] = decoded
                if slot[0] is not None and (slot[1] is not None or not self.want_agents):
                    for key in sorted(k for k in pending if k <= msg.log_time_ns):
                        done = pending.pop(key)
                        if done[0] is not None and not self._lost_ids(key, done):
                            yield Frame(key, done[0][0], done[0][1], done[1], done[2], done[3])
            # without sources or sinks the ids are 0 .. N - 1 in every state, so a last state
            # cut from its /agents is still whole; where agents come and go it is not
            # (in a file cut short, or in sweep recover's copy of one, the cut may fall there)
            short = self._reader.truncated or self.meta.recovered_short
            cut = short and self.want_agents and self.meta.changes_population
            for key in sorted(pending):
                done = pending[key]
                if done[0] is None:
                    continue
                if cut and done[1] is None and key == max(pending):
                    # the file ends between this state's /poses and its /agents: the cut
                    where = ("the file was cut" if self._reader.truncated else "the file "
                             "this copy was recovered from was cut or damaged")
                    self._leave_out(f"the last /poses (t = {key / 1e9:g} s) has no /agents: "
                                    f"{where} between them; that state is left out")
                    continue
                if not self._lost_ids(key, done):
                    yield Frame(key, done[0][0], done[0][1], done[1], done[2], done[3])
        finally:
            self._reader.close()
            self.truncated = self._reader.truncated
            self.error = self._reader.error
            self.skipped_chunks = list(self._reader.problems)
            self.problems = [f"{self.meta.path}: {p}" for p in self._reader.problems]
            self.problems += self._bad_lines
            if self.bad > len(self._bad_lines):
                self.problems.append(f"{self.meta.path}: {self.bad - len(self._bad_lines)} "
                                     "more messages skipped: they cannot be decoded")


@dataclass
class Gap:
    """Recorded states missing from a recording: ``missing`` ``/poses`` messages between the
    frames of steps ``after`` and ``before`` of segment ``segment`` (their steps were not read,
    so not analysed nor compared)."""

    segment: int
    after: int
    before: int
    missing: int

    def describe(self) -> str:
        seg = f" of segment {self.segment}" if self.segment else ""
        return (f"{self.missing} /poses message{'s' if self.missing != 1 else ''} missing "
                f"between the recorded steps {self.after} and {self.before}{seg}")


class GapFinder:
    """Finds the recorded states missing between consecutive frames: by the ``/poses``
    sequence numbers (:attr:`Frame.missing_before`), or, for a writer that does not number its
    messages, by steps further apart than ``record_every`` (when the recording says it)."""

    def __init__(self, record_every: int | None) -> None:
        self.record_every = record_every
        self.gaps: list[Gap] = []
        self._prev: tuple[int, int] | None = None  # (segment, step) of the previous frame

    def add(self, fr: Frame, segment: int, step: int) -> None:
        prev, self._prev = self._prev, (segment, step)
        if prev is None:
            return
        missing = fr.missing_before
        k = self.record_every
        if not fr.sequence and k and prev[0] == segment and step - prev[1] > k:
            missing = (step - prev[1]) // k - 1
        if missing > 0:
            self.gaps.append(Gap(segment, prev[1], step, missing))

    @property
    def missing(self) -> int:
        return sum(g.missing for g in self.gaps)

    def to_dict(self) -> dict | None:
        """JSON: the total and the gaps (segment, after_step, before_step, missing), or None."""
        if not self.gaps:
            return None
        return {"missing_messages": self.missing,
                "gaps": [[g.segment, g.after, g.before, g.missing] for g in self.gaps[:100]],
                "columns": ["segment", "after_step", "before_step", "missing"]}

    def lines(self, path: str, limit: int = 5) -> list[str]:
        """One line per gap (at most ``limit``, then a count)."""
        out = [f"{path}: {g.describe()}; those steps were not read" for g in self.gaps[:limit]]
        if len(self.gaps) > limit:
            out.append(f"{path}: {len(self.gaps) - limit} more gaps "
                       f"({self.missing} /poses messages missing in all)")
        return out


def progress_bar(total: int | None, unit: str, enabled: bool) -> Any:
    """A tqdm bar on stderr (only on a terminal), or a no-op."""
    from tqdm import tqdm
    return tqdm(total=total, unit=unit, dynamic_ncols=True, disable=None if enabled else True,
                leave=False)
