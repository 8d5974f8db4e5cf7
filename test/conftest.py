"""Test set-up: DDS stays on this machine, each test process on its own domain."""
import os
import sys
from pathlib import Path

# Fast DDS must never multicast off the machine.
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
# A domain per test process: pytest-xdist workers (gw0, gw1, ...) share their parent's pid, so
# their domains are that pid's slot plus the worker's index, never equal within one run.
_worker = os.environ.get("PYTEST_XDIST_WORKER", "")
_index = int(_worker[2:]) if _worker.startswith("gw") and _worker[2:].isdigit() else 0
_base = os.getppid() if _worker else os.getpid()
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + (_base * 4 + _index) % 100))

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
