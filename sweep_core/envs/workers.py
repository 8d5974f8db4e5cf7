"""Worker processes of a vector environment (``workers`` > 1 in
:class:`~sweep_core.envs.vector.CrowdNavVectorEnv`): the K environments split into W
contiguous shares, each share held and stepped by its own process, so that W cores step the
batch at once.

A worker builds its share as the in-process vector environment would (the same scene and
arguments), resets each environment with the seed the parent computed for it and steps it with
its row of the parent's checked actions; it returns its share's step packed as the
in-process vector environment packs all of its own (:func:`step_share`: the observations
stacked, the rewards and flags as arrays, the infos), and the parent joins the shares in
order. So environment i's episodes are the same, bit for bit, with any number of workers.
Workers are forked where the platform forks safely (Linux: they start at once, with the
parent's imports and compiled kernels, and a script needs no ``__main__`` guard), else
spawned (macOS, Windows: a script must then create the vector environment under
``if __name__ == "__main__":``); they end with the vector environment's ``close`` or its
process. Every kernel is loaded before a worker's first step: by the parent before it forks
the workers, and by each worker after building its share (at once when forked, the whole load
when spawned).
"""
from __future__ import annotations

import multiprocessing
import signal
import sys
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from sweep_core.errors import SceneError, WorkerError

#: seconds a worker is given to finish after ``close`` before it is terminated
CLOSE_WAIT = 5.0
#: bytes a worker process takes beside its environments, by start method: the pages it
#: writes of its own (measured on Linux: about 8.4 MB forked, 100 MB spawned), rounded up
WORKER_BYTES = {"fork": 16_000_000, "spawn": 128_000_000}


def shares(k: int, w: int) -> list[range]:
    """The environments (indices into 0..k-1) of each of w workers: contiguous, sizes
    differing by at most one, the larger first."""
    return [range(i * k // w, (i + 1) * k // w) for i in range(w)]


def start_method() -> str:
    """How workers start: "fork" on Linux, else "spawn" (module docstring)."""
    return "fork" if sys.platform.startswith("linux") else "spawn"


def step_all(envs: list[Any], done: np.ndarray, actions: np.ndarray) -> list[tuple]:
    """One step of each environment (next-step autoreset: one whose episode ended, ``done``,
    is reset instead and its action ignored): (obs, reward, terminated, truncated, info)
    each, in order."""
    out = []
    for i, env in enumerate(envs):
        if done[i]:
            obs, info = env.reset()
            out.append((obs, 0.0, False, False, info))
        else:
            out.append(env.step(actions[i]))
    return out


#: a share's step, packed (:func:`step_share`): the observations stacked per key, the rewards,
#: terminations and truncations (n,) and the infos in order
Packed = tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]


def stack(obs: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Environments' observations (one dict each, in order) stacked key by key."""
    return {key: np.stack([o[key] for o in obs]) for key in obs[0]}


def step_share(envs: list[Any], done: np.ndarray, actions: np.ndarray) -> Packed:
    """:func:`step_all` packed for the parent: a worker sends a few arrays instead of one
    small array per environment and key, and the parent joins the shares (:func:`join`)."""
    results = step_all(envs, done, actions)
    return (stack([r[0] for r in results]), np.array([r[1] for r in results], dtype=np.float64),
            np.array([r[2] for r in results], dtype=np.bool_),
            np.array([r[3] for r in results], dtype=np.bool_), [r[4] for r in results])


def join(parts: list[Packed]) -> Packed:
    """The packed steps of consecutive shares as one (the environments in order)."""
    if len(parts) == 1:
        return parts[0]
    obs = {key: np.concatenate([p[0][key] for p in parts]) for key in parts[0][0]}
    return (obs, np.concatenate([p[1] for p in parts]), np.concatenate([p[2] for p in parts]),
            np.concatenate([p[3] for p in parts]), [i for p in parts for i in p[4]])


def reset_all(envs: list[Any], seeds: list[int | None], options: dict[str, Any] | None,
              marked: list[bool]) -> list[tuple | None]:
    """(obs, info) of each environment ``marked``, reset with its seed; None for the others
    (left as they are)."""
    return [env.reset(seed=s, options=options) if m else None
            for env, s, m in zip(envs, seeds, marked)]


def _serve(conn: Connection, scene: Any, count: int, kwargs: dict[str, Any],
           inherited: list[Connection]) -> None:
    """A worker's loop: builds ``count`` environments, then answers the parent's requests
    ("reset", seeds, options, marked), ("step", done, actions) and ("close",) until "close" or the
    parent is gone. A failure is sent back, not raised. ``inherited``: the parent's ends of
    the pipes, which a forked worker holds copies of and closes, so that a parent that dies
    ends every worker (its pipe reads end of file)."""
    for end in inherited:
        end.close()
    from sweep_core.envs.crowdnav import CrowdNavEnv
    # Ctrl-C is the parent's to handle (it ends the workers); a worker would only print a
    # traceback of its own
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        envs = [CrowdNavEnv(scene=scene, **kwargs) for _ in range(count)]
        # the kernels loaded now, not in the first steps (a forked worker has the parent's:
        # a few milliseconds; a spawned one loads them here)
        from sweep_core.numerics import kernels
        kernels.warm_up()
        conn.send(("ok", None))
    except BaseException as err:  # noqa: BLE001 - reported to the parent
        conn.send(("error", portable(err)))
        return
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg[0] == "close":
            for env in envs:
                env.close()
            conn.send(("ok", None))
            return
        try:
            if msg[0] == "reset":
                answer = reset_all(envs, msg[1], msg[2], msg[3])
            else:
                answer = step_share(envs, msg[1], msg[2])
            conn.send(("ok", answer))
        except BaseException as err:  # noqa: BLE001 - reported to the parent
            conn.send(("error", portable(err)))


def portable(err: BaseException) -> tuple:
    """An exception as the parent can raise it again: a SceneError's three parts, else its
    type's name and message."""
    if isinstance(err, SceneError):
        return ("scene", err.field, err.problem, err.fix)
    return ("other", type(err).__name__, str(err))


def reraise(worker: int, what: tuple) -> None:
    """Raises the failure of worker ``worker`` (:func:`portable`'s tuple) in the parent."""
    if what[0] == "scene":
        raise SceneError(what[1], what[2], what[3])
    raise WorkerError(f"worker {worker} of the vector environment failed: {what[1]}: "
                      f"{what[2]}")


class Workers:
    """W worker processes holding the K environments in contiguous shares (module
    docstring); ``scene`` a Scene or scene dict, ``kwargs`` the environments' arguments."""

    def __init__(self, k: int, w: int, scene: Any, kwargs: dict[str, Any]) -> None:
        self.shares = shares(k, w)
        method = start_method()
        ctx = multiprocessing.get_context(method)
        self.conns: list[Connection] = []
        self.procs: list[Any] = []
        try:
            for share in self.shares:
                mine, theirs = ctx.Pipe()
                inherited = [*self.conns, mine] if method == "fork" else []
                proc = ctx.Process(target=_serve,
                                   args=(theirs, scene, len(share), kwargs, inherited),
                                   daemon=True, name="sweep-env-worker")
                proc.start()
                theirs.close()
                self.conns.append(mine)
                self.procs.append(proc)
            self._gather()
        except BaseException:
            self.close()
            raise

    def reset(self, seeds: list[int | None], options: dict[str, Any] | None,
              marked: list[bool]) -> list[tuple | None]:
        """:func:`reset_all` over the K environments, each share in its worker."""
        for w, share in enumerate(self.shares):
            self._send(w, ("reset", [seeds[i] for i in share], options,
                           [marked[i] for i in share]))
        return [r for answer in self._gather() for r in answer]

    def step(self, done: np.ndarray, actions: np.ndarray) -> Packed:
        """:func:`step_share` over the K environments, each share in its worker, joined."""
        for w, share in enumerate(self.shares):
            self._send(w, ("step", done[share.start:share.stop], actions[share.start:share.stop]))
        return join(self._gather())

    def _send(self, w: int, msg: tuple) -> None:
        if not self.conns:
            raise WorkerError("the vector environment is closed: make a new one")
        try:
            self.conns[w].send(msg)
        except (OSError, ValueError):
            raise self._ended(w) from None

    def _ended(self, w: int) -> WorkerError:
        """The error of worker ``w`` gone (killed from outside): its exit code, once its
        process is reaped (its pipe may close a moment before), and what to do."""
        self.procs[w].join(CLOSE_WAIT)
        return WorkerError(f"worker {w} of the vector environment has ended (exit code "
                            f"{self.procs[w].exitcode}): close it and make a new one")

    def _gather(self) -> list:
        """Each worker's answer, in order (None, a started worker's, left out)."""
        out: list = []
        failed: tuple | None = None
        ended: int | None = None
        for w, conn in enumerate(self.conns):
            try:
                status, answer = conn.recv()
            except (EOFError, OSError):
                ended = w if ended is None else ended
                continue
            if status == "error":
                failed = failed or (w, answer)
            elif answer is not None:
                out.append(answer)
        if ended is not None:
            raise self._ended(ended)
        if failed is not None:
            reraise(*failed)
        return out

    def close(self) -> None:
        """Asks every worker to end; terminates those that have not within CLOSE_WAIT s."""
        for conn in self.conns:
            try:
                conn.send(("close",))
            except (OSError, ValueError):
                pass
        for conn, proc in zip(self.conns, self.procs):
            proc.join(CLOSE_WAIT)
            if proc.is_alive():
                proc.terminate()
                proc.join(CLOSE_WAIT)
            conn.close()
        self.conns, self.procs = [], []
