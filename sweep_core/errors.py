"""Errors raised by sweep_core.

Every error carries the data it is about and builds its own message, so the command-line
boundary can print ``str(err)`` on one line and exit non-zero.
"""
from __future__ import annotations

import re
from typing import Any

#: at most this many items of a list are shown in a message
SHOW_ITEMS = 6


def show(value: Any, items: int = SHOW_ITEMS) -> str:
    """A value as a message shows it: plain numbers (``{:g}``), lists as ``[x, y]``.

    numpy scalars and arrays are shown like Python floats and lists, never as
    ``np.float64(...)`` or ``array(...)``; strings are quoted; lists longer than ``items`` are
    cut with ``...``; any other object is shown by its type name.
    """
    if value is None or isinstance(value, bool):
        return {None: "null", True: "true", False: "false"}[value]
    if isinstance(value, str):
        return repr(value if len(value) <= 60 else value[:57] + "...")
    if hasattr(value, "tolist") and callable(value.tolist):  # numpy scalar or array
        try:
            n = len(value) if getattr(value, "ndim", 0) else 0
            if n > items:
                return show(value[:items].tolist(), items)[:-1] + f", ... ({n} items)]"
            value = value.tolist()
        except (TypeError, ValueError):
            return type(value).__name__
    if isinstance(value, bool):
        return show(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, (list, tuple)):
        shown = [show(v, items) for v in value[:items]]
        if len(value) > items:
            shown.append(f"... ({len(value)} items)")
        return "[" + ", ".join(shown) + "]"
    if isinstance(value, dict):
        keys = list(value)[:items]
        shown = [f"{k}: {show(value[k], items)}" for k in keys]
        if len(value) > items:
            shown.append(f"... ({len(value)} keys)")
        return "{" + ", ".join(shown) + "}"
    return type(value).__name__


class SweepError(Exception):
    """Base class of every error sweep_core raises on purpose."""


class _Arguments:
    """Mixin of the errors built from arguments they keep as attributes (:attr:`ARGUMENTS`, in
    the constructor's order): ``type(err)(err)`` is err's copy (how Gymnasium's AsyncVectorEnv
    raises again the error of one of its worker processes), and a pickle rebuilds err from
    them (a worker process sends it to its parent)."""

    #: the attributes that keep the constructor's arguments, in its order
    ARGUMENTS: tuple[str, ...] = ()

    def _given(self, kind: type, given: tuple, required: int) -> tuple[Any, ...]:
        """The constructor's arguments ``given`` (the first ``required`` of them needed), or,
        when the first is an error of ``kind`` and the other needed ones are None, that
        error's own: its copy. TypeError for any other call."""
        first, needed = given[0], given[1:required]
        if (isinstance(first, kind) and isinstance(first, _Arguments)
                and all(value is None for value in needed)):
            return first.arguments()
        if isinstance(first, kind) or any(value is None for value in needed):
            raise TypeError(f"{kind.__name__}({', '.join(self.ARGUMENTS)}) needs "
                            f"{', '.join(self.ARGUMENTS[:required])}, or an error to copy")
        return given

    def arguments(self) -> tuple:
        """The arguments that build this error again."""
        return tuple(getattr(self, name) for name in self.ARGUMENTS)

    def __reduce__(self) -> tuple:
        """Pickled with its arguments (a worker process sends it to its parent)."""
        return (type(self), self.arguments(), self.__dict__)


class SceneError(_Arguments, SweepError, ValueError):
    """A scene (or a simulator option) is invalid.

    Attributes:
        field: dotted path of the offending key, e.g. ``"agents.radius"``.
        problem: what is wrong with it.
        fix: what to do instead (may be empty).

    ``SceneError(err)`` is err's copy (:class:`_Arguments`).
    """

    ARGUMENTS = ("field", "problem", "fix")

    def __init__(self, field: str | SceneError, problem: str | None = None,
                 fix: str = "") -> None:
        args = self._given(SceneError, (field, problem, fix), 2)
        self.field: str = args[0]
        self.problem: str = args[1]
        self.fix: str = args[2]
        msg = f"{self.field}: {self.problem}"
        if self.fix:
            msg += f" (fix: {self.fix})"
        super().__init__(msg)


class CostError(SceneError):
    """A scene asks for more than a bound on what building it costs (agents a source emits,
    sources, sinks, map cells and walls, grid nodes): refused before the cost is paid. A
    recording whose scene asks for it is refused outright (a recording's metadata is data and
    may claim anything)."""


class InfeasibleError(_Arguments, SweepError):
    """The linearised feasible set of a step is empty or the projection failed.

    The simulator's state is left at the last accepted step.

    Attributes:
        t: time (s) of the step that could not be taken (t_{n+1}).
        agents: the agents involved in the most violated constraints, by id (their indices
            without flows).
        detail: solver status or residual.
        fix: what to do instead (default: the advice for a jam of agents).

    ``InfeasibleError(err)`` is err's copy (:class:`_Arguments`).
    """

    ARGUMENTS = ("t", "agents", "detail", "fix_given")

    def __init__(self, t: float | InfeasibleError, agents: list[int] | None = None,
                 detail: str | None = None, fix: str = "") -> None:
        args = self._given(InfeasibleError, (t, agents, detail, fix), 3)
        self.t: float = args[0]
        self.agents: list[int] = list(args[1])
        self.detail: str = args[2]
        fix = args[3]
        self.fix_given: str = fix  # the fix as given ('': the default below)
        self.fix = fix or "smaller radii or radius growth, more room, or fewer agents"
        shown = ", ".join(str(a) for a in self.agents[:12])
        more = "" if len(self.agents) <= 12 else f" and {len(self.agents) - 12} more"
        what = (f"{self.detail}" if fix and not self.agents else
                f"agents [{shown}{more}] cannot be placed without overlap ({self.detail})")
        super().__init__(
            f"no feasible configuration at t = {self.t:.6g} s: {what}; state kept at the last "
            f"accepted step (fix: {self.fix})"
        )

    def by_ids(self, ids: Any) -> InfeasibleError:
        """This error with the agents named by ``ids`` (ids[i] the id of row i of the step's
        arrays: with flows, the rows of the people present are not their ids): its
        ``agents`` and every "agent N" of its detail and fix."""
        def name(text: str) -> str:
            return re.sub(r"\bagent (\d+)\b", lambda m: f"agent {int(ids[int(m[1])])}", text)

        return InfeasibleError(self.t, [int(ids[a]) for a in self.agents], name(self.detail),
                               name(self.fix_given))


class WorkerError(SweepError, RuntimeError):
    """A worker process of a vector environment failed (the message names the worker and its
    error) or has ended (its exit code, and what to do)."""


class RecordingError(SweepError):
    """An MCAP recording could not be written or read."""


class OutputError(_Arguments, SweepError):
    """An output file cannot be written safely: it is one of the inputs, it is not a regular
    file (a folder, a device, a FIFO), another run is writing it, or the writing failed.

    Attributes:
        path: the output path.
        problem: what is wrong.
        fix: what to do instead.

    ``OutputError(err)`` is err's copy (:class:`_Arguments`).
    """

    ARGUMENTS = ("path", "problem", "fix")

    def __init__(self, path: str | OutputError, problem: str | None = None,
                 fix: str | None = None) -> None:
        args = self._given(OutputError, (path, problem, fix), 3)
        self.path: str = args[0]
        self.problem: str = args[1]
        self.fix: str = args[2]
        super().__init__(f"{self.path}: {self.problem} (fix: {self.fix})")
