"""Output files that never overwrite by surprise: one check and two ways of writing, shared by
every writer (``sweep run``, ``recover``, ``analyze``, ``compare``, ``map``, ``ensemble``, the
node's ``record`` parameter).

The rules:

* an output that is one of the command's inputs (the same file, by ``os.path.samefile``, or the
  same resolved path) is refused;
* an existing output that is not a regular file (a folder, a device such as ``/dev/full``, a
  FIFO, a socket) is refused: nothing is written to it and it is never replaced;
* an existing regular file is overwritten (as ``cp`` and ``tar -f`` do);
* two writers of one file cannot both write it at once: the first holds an exclusive lock
  (``flock``) on the file it writes; the second is refused, naming the path.

Finished files (tables, figures, a recovered recording) are written to a temporary file
``.NAME.partial`` in the output's folder and renamed over the output at the end
(:func:`replacing`, :func:`write_text`), so an interrupted writer leaves the old output (or
none), never half of one. A live recording (:func:`open_locked`) is written at its final name,
so that it can be read while it grows and a killed writer leaves a file ``sweep recover`` can
complete.
"""
from __future__ import annotations

import errno
import fcntl
import os
import stat
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from pathlib import Path

from sweep_core import checks
from sweep_core.errors import OutputError

kind_of = checks.file_kind


def _same(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.realpath(a) == os.path.realpath(b)


def check_output(path: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str] | None] = (),
                 *, other: str = "--out OTHER") -> Path:
    """``path`` as a Path once it is safe to write: not one of ``inputs`` (None items are
    skipped), and absent or a regular file.

    Raises:
        OutputError: naming the path, what it is and the fix (``other``: how to name
            another output, e.g. ``--out OTHER``).
    """
    p = os.fspath(path)
    for src in inputs:
        if src is not None and _same(p, os.fspath(src)):
            raise OutputError(p, f"is also an input ({os.fspath(src)}); an output never "
                              "overwrites an input", other)
    refuse_package(p, other)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        return Path(p)
    except OSError as err:
        raise OutputError(p, f"cannot be checked ({err.strerror})", other) from None
    if not stat.S_ISREG(st.st_mode):
        raise OutputError(p, f"exists and is {kind_of(st.st_mode)}; only a regular file is "
                          "overwritten", f"{other}, a file path")
    return Path(p)


#: the installed sweep_core package: its bundled scenes, data and code are inputs of every
#: command, so no output goes inside it
PACKAGE = os.path.realpath(Path(__file__).resolve().parents[1])


def refuse_package(path: str | os.PathLike[str], other: str) -> None:
    """OutputError when ``path`` (resolved, symbolic links followed) lies inside
    :data:`PACKAGE`."""
    p = os.path.realpath(os.fspath(path))
    if p == PACKAGE or p.startswith(PACKAGE + os.sep):
        raise OutputError(os.fspath(path), f"lies inside the installed sweep_core package "
                          f"({PACKAGE}), whose bundled scenes and data it could overwrite",
                          f"{other} outside the package")


def check_folder(path: str | os.PathLike[str], other: str = "--out OTHERDIR") -> Path:
    """``path`` as a Path, made (with its parents) when absent, once it is a folder outside
    the package that can be written into.

    Raises:
        OutputError: naming the path, what it is and the fix.
    """
    p = os.fspath(path)
    if not p:  # os.makedirs('') says only "No such file or directory"
        raise OutputError("''", "is an empty path, which names no folder",
                          f"{other}, a folder's path")
    refuse_package(p, other)
    if os.path.lexists(p) and not os.path.isdir(p):
        raise OutputError(p, f"exists and is {kind_of(os.lstat(p).st_mode)}, not a folder",
                          f"{other}, a folder's path")
    try:
        os.makedirs(p, exist_ok=True)
    except OSError as err:
        raise OutputError(p, f"cannot be made as a folder ({err.strerror})", other) from None
    if not os.access(p, os.W_OK | os.X_OK):
        raise OutputError(p, "is a folder this user cannot write into", other)
    return Path(p)


def _lock(fd: int, path: str, other: str) -> None:
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as err:
        os.close(fd)
        if err.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise OutputError(path, "another run is writing it right now",
                              f"wait for it to finish, or {other}") from None
        raise OutputError(path, f"cannot be locked ({err.strerror})", other) from None


def _open_regular(path: str, other: str) -> int:
    """A descriptor of ``path`` opened for writing (created if absent, not truncated, FIFOs not
    waited on), refused unless it is a regular file."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NONBLOCK | os.O_CLOEXEC, 0o666)
    except OSError as err:
        raise OutputError(path, f"cannot be {'opened' if os.path.exists(path) else 'created'} "
                          f"for writing ({err.strerror})", f"{other} in a writable folder") \
            from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise OutputError(path, f"exists and is {kind_of(mode)}; only a regular file is "
                          "overwritten", f"{other}, a file path")
    os.set_blocking(fd, True)
    return fd


def open_locked(path: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str] | None] = (),
                *, other: str = "--out OTHER") -> int:
    """A descriptor of ``path``, emptied and exclusively locked, for a live recording written
    at its final name; the lock lasts until the descriptor is closed (or the process ends).

    The lock is taken before the file is emptied, so a second writer is refused without
    touching the first one's data.

    Raises:
        OutputError: see :func:`check_output`; or another writer holds the lock.
    """
    p = os.fspath(check_output(path, inputs, other=other))
    fd = _open_regular(p, other)
    _lock(fd, p, other)
    try:
        os.ftruncate(fd, 0)
    except OSError as err:
        os.close(fd)
        raise OutputError(p, f"cannot be emptied ({err.strerror})", other) from None
    return fd


def partial_path(path: str | os.PathLike[str]) -> str:
    """``DIR/.NAME.partial``: where :func:`replacing` writes before the rename."""
    p = os.path.abspath(os.fspath(path))
    return os.path.join(os.path.dirname(p), f".{os.path.basename(p)}.partial")


@contextmanager
def replacing(path: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str] | None] = (),
              *, other: str = "--out OTHER") -> Iterator[str]:
    """Yields a temporary path beside ``path`` to write the whole output to; on a clean exit
    it is renamed over ``path`` (which must still be absent or a regular file), on an error
    it is deleted and ``path`` is left as it was. The temporary file is locked while it is
    written, so a second writer of ``path`` is refused.

    Raises:
        OutputError: see :func:`check_output`; another writer; or the rename failed. An
            OSError of the writing itself becomes an OutputError naming ``path``.
    """
    p = os.fspath(check_output(path, inputs, other=other))
    tmp = partial_path(p)
    while True:
        fd = _open_regular(tmp, other)
        _lock(fd, p, other)
        try:  # the previous holder may have renamed or deleted it before we got the lock
            if os.path.samestat(os.fstat(fd), os.stat(tmp)):
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        yield tmp
        check_output(p, other=other)  # it may have become a folder or a device meanwhile
        os.replace(tmp, p)
    except OSError as err:
        raise OutputError(p, f"cannot be written ({err.strerror or err})",
                          "free disk space, or write to another folder") from None
    finally:
        if os.path.exists(tmp) and os.path.samestat(os.fstat(fd), os.stat(tmp)):
            os.unlink(tmp)
        os.close(fd)


def write_text(path: str | os.PathLike[str], text: str,
               inputs: Iterable[str | os.PathLike[str] | None] = (), *, other: str = "--out OTHER") -> Path:
    """Writes ``text`` to ``path`` through :func:`replacing`; returns the path."""
    with replacing(path, inputs, other=other) as tmp, open(tmp, "w") as f:
        f.write(text)
    return Path(os.fspath(path))
