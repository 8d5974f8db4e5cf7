"""Test set-up: DDS stays on this machine, each test process on its own domain."""
import os
import sys
from pathlib import Path

# Fast DDS must never multicast off the machine; a unique domain per test process.
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 100))

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
