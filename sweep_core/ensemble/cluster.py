"""Where an ensemble runs: a given ``distributed.Client`` as is, a running Dask scheduler
(``--scheduler tcp://HOST:PORT``), or a ``LocalCluster`` of K single-threaded worker processes
on 127.0.0.1 started for the ensemble and closed after it."""
from __future__ import annotations

import importlib.util
import os
import re
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from sweep_core.errors import SweepError

#: seconds to wait for a scheduler given by address
CONNECT_TIMEOUT = 10
_ADDRESS = re.compile(r"^(tcp|tls|inproc|ucx)://[^\s/]+(:\d+)?$")


def default_workers() -> int:
    """The cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def dashboard(client: Any) -> str | None:
    """The dashboard's address, or None when there is none (without bokeh the scheduler's
    HTTP server has no dashboard pages)."""
    if importlib.util.find_spec("bokeh") is None:
        return None
    try:
        services = client.scheduler_info().get("services", {})
    except Exception:  # noqa: BLE001 - an address only for display
        return None
    return client.dashboard_link if "dashboard" in services else None


#: the resident memory (bytes) of a local worker once the engine is loaded, its kernels warmed
#: up and a run of the bundled room analysed (measured peak in a new worker: 328 MB;
#: test_ensemble checks it)
WORKER_BYTES = 330_000_000
#: most local worker processes per core this process may use: each takes WORKER_BYTES, and
#: workers beyond the cores only wait their turn; 10000 workers would have asked for 2.4 TB
WORKERS_PER_CORE = 4


def check_workers(workers: int | None) -> int:
    """The worker count of a local cluster (None: the cores), at most WORKERS_PER_CORE per
    core (at least 8)."""
    n = default_workers() if workers is None else workers
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise SweepError(f"--workers: {n!r} is not a positive number of worker processes "
                         "(fix: e.g. --workers 2)")
    most = max(8, WORKERS_PER_CORE * default_workers())
    if n > most:
        raise SweepError(f"--workers: {n} is more than {most} worker processes, "
                         f"{WORKERS_PER_CORE} per core of the {default_workers()} this process "
                         f"may use (each about {WORKER_BYTES / 1e6:.0f} MB) (fix: --workers "
                         f"{default_workers()}, or --scheduler for a cluster of several "
                         "machines)")
    return n


@contextmanager
def sigint_ignored() -> Iterator[None]:
    """SIGINT ignored while the local workers start: they inherit that (an ignored signal stays
    ignored across exec, and Python keeps it so), so Ctrl-C on a terminal, sent to the whole
    process group, interrupts the ensemble only; it then cancels the runs and closes them."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def check_address(scheduler: str) -> None:
    """Refuses a scheduler address that is not ``tcp://HOST:PORT`` (before anything starts)."""
    if not _ADDRESS.match(scheduler):
        raise SweepError(f"--scheduler: {scheduler!r} is not an address like "
                         "tcp://HOST:8786 (fix: give the address `dask scheduler` prints)")


@contextmanager
def connect(client: Any = None, scheduler: str | None = None, workers: int | None = None,
            log: Callable[[str], None] | None = None) -> Iterator[Any]:
    """Yields a ``distributed.Client``; closes what it started (never a given client)."""
    say = log or (lambda _text: None)
    if client is not None:
        yield client
        return
    try:
        from distributed import Client, LocalCluster
    except ImportError as err:
        raise SweepError("sweep ensemble needs Dask's distributed (fix: pip install "
                         "distributed pandas pyarrow)") from err
    if scheduler is not None:
        check_address(scheduler)
        try:
            remote = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError) as err:
            raise SweepError(f"--scheduler: cannot reach {scheduler} within {CONNECT_TIMEOUT} s "
                             f"({' '.join(str(err).split())[:120]}) (fix: start `dask scheduler` "
                             "there, check host, port and firewall, or drop --scheduler to run "
                             "on this machine)") from err
        try:
            n = len(remote.scheduler_info().get("workers", {}))
            say(f"scheduler {scheduler}: {n} workers" + ("" if n else
                " (runs wait until a `dask worker` connects)"))
            link = dashboard(remote)
            if link:
                say(f"dashboard {link}")
            yield remote
        finally:
            remote.close()
        return
    n_workers = check_workers(workers)
    # every server (scheduler, workers, their HTTP servers) on 127.0.0.1, free ports
    with sigint_ignored():
        cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address="127.0.0.1:0")
    try:
        local = Client(cluster)
        try:
            say(f"local cluster: {n_workers} worker processes, scheduler "
                f"{cluster.scheduler_address}")
            link = dashboard(local)
            if link:
                say(f"dashboard {link}")
            yield local
        finally:
            local.close()
    finally:
        cluster.close()
