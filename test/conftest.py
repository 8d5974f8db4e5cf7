"""Test set-up: DDS stays on this machine, each test process on its own domain."""
import os
import sys
from pathlib import Path

# Fast DDS must never multicast off the machine.
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
# A domain per test process. pytest-xdist's controller imports this file before it starts the
# workers (gw0, gw1, ...), which inherit its environment: so the controller picks a base slot
# (from its pid) and every process, controller or worker, sets its own domain from that base
# and its worker index, unconditionally (a setdefault would leave every worker on the
# controller's domain, and their nodes would hear each other).
_worker = os.environ.get("PYTEST_XDIST_WORKER", "")
_index = int(_worker[2:]) if _worker.startswith("gw") and _worker[2:].isdigit() else 0
os.environ.setdefault("SWEEP_TEST_DOMAIN_BASE", str(os.getpid() % 25))
os.environ["ROS_DOMAIN_ID"] = str(1 + 4 * int(os.environ["SWEEP_TEST_DOMAIN_BASE"]) + _index % 4)

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def pytest_configure(config) -> None:
    """Compiles the engine's kernels into the shared cache once, before the test processes
    start (each would otherwise compile them itself at its first step: minutes on a loaded
    2-core machine), and says so when it does."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    from sweep_core.numerics import kernels

    kernels.warm_up(lambda line: print(f"sweep tests: {line}", file=sys.stderr, flush=True))
