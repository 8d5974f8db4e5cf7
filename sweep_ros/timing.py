"""Timing of the node's ticks and steps between two diagnostics messages."""
from __future__ import annotations

import time


class Window:
    """Timing accumulated between two diagnostics messages."""

    def __init__(self, sim_t: float) -> None:
        self.wall0 = time.monotonic()
        self.sim0 = sim_t
        self.ticks = 0
        self.tick_s = 0.0
        self.steps = 0
        self.step_s = 0.0
        self.overruns = 0
