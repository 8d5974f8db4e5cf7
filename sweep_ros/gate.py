"""The lock between the node's steps (:class:`StepGate`): the step thread holds it for one
step at a time, and a service, command or parameter callback waiting for it goes first at the
next step boundary, so it waits at most one step, never a whole tick."""
from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager


class StepGate:
    """A mutual-exclusion lock with priority for control callbacks over the stepping loop.

    ``with gate.step():`` wraps one step of the step thread's tick; ``with gate.control():`` wraps a
    service or parameter change. A plain lock is not enough: Python's locks are not fair, so
    a loop that releases and at once re-acquires one would keep it for the whole tick. Here
    :meth:`step` first waits until no control callback is waiting, so a control callback gets
    the lock at the next step boundary. Not re-entrant: the ``step`` service, which holds the
    control side, steps the engine itself instead of nesting :meth:`step`.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._cond = threading.Condition()
        self._waiting = 0

    @contextmanager
    def control(self) -> Iterator[None]:
        """Holds the gate between two steps; waits at most for the step in progress."""
        with self._cond:
            self._waiting += 1
        try:
            self._lock.acquire()
        finally:
            with self._cond:
                self._waiting -= 1
                self._cond.notify_all()
        try:
            yield
        finally:
            self._lock.release()

    @contextmanager
    def step(self) -> Iterator[None]:
        """Holds the gate for one step, after every control callback waiting for it."""
        with self._cond:
            while self._waiting:
                self._cond.wait()
        with self._lock:
            yield

    @property
    def waiting(self) -> int:
        """Control callbacks waiting for the gate now."""
        return self._waiting
