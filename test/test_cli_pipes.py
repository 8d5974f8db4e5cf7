"""A ``sweep`` command whose reader closed the pipe (``sweep compare A B | head``) ends
quietly: no traceback, status 141 (128 + SIGPIPE, as the shell reports a command it ended),
handled once in the command's ``main``."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_a_closed_pipe_ends_the_command_quietly():
    """Before: a BrokenPipeError traceback on stderr and status 1."""
    read, write = os.pipe()
    os.close(read)  # the reader is gone before the first line: every write meets EPIPE
    try:
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        done = subprocess.run([sys.executable, "-m", "sweep_core.cli", "scenes"], stdout=write,
                              stderr=subprocess.PIPE, env=env, cwd=ROOT, timeout=600)
    finally:
        os.close(write)
    err = done.stderr.decode()
    assert "Traceback" not in err and "BrokenPipeError" not in err, err
    assert "Exception ignored" not in err, err
    assert done.returncode == 141, (done.returncode, err)
