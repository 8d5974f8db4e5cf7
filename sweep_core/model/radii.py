"""Radius laws r_i(t) = radius_i + law(t), one law shared by every agent.

A law is Lipschitz in t; its constant bounds how much a radius can grow over one step, which
the constraint cutoff needs. Units: metres, seconds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from sweep_core import checks
from sweep_core.model import elementary


@dataclass(frozen=True)
class RadiusLaw:
    """Base class: ``offset(t)`` (m) is added to every agent's base radius."""

    kind = "constant"

    def offset(self, t: float) -> float:
        return 0.0

    @property
    def lipschitz(self) -> float:
        """Bound on |d offset / dt| (m/s)."""
        return 0.0

    @property
    def is_constant(self) -> bool:
        return True

    def min_offset(self, t_end: float) -> float:
        """Minimum of ``offset`` over [0, t_end] (m); t_end may be inf."""
        return 0.0

    def zero_time(self, radius: float) -> float:
        """First time t >= 0 (s) at which radius + offset(t) <= 0, for a base radius > 0 (m);
        inf if never."""
        return math.inf

    def to_spec(self) -> dict:
        return {"kind": self.kind}


@dataclass(frozen=True)
class Constant(RadiusLaw):
    kind = "constant"


@dataclass(frozen=True)
class Linear(RadiusLaw):
    """offset(t) = rate * t."""

    rate: float = 0.0
    kind = "linear"

    def offset(self, t: float) -> float:
        return self.rate * t

    @property
    def lipschitz(self) -> float:
        return abs(self.rate)

    @property
    def is_constant(self) -> bool:
        return self.rate == 0.0

    def min_offset(self, t_end: float) -> float:
        if self.rate >= 0:
            return 0.0
        return -math.inf if math.isinf(t_end) else self.rate * t_end

    def zero_time(self, radius: float) -> float:
        return radius / -self.rate if self.rate < 0 else math.inf

    def to_spec(self) -> dict:
        return {"kind": self.kind, "rate": self.rate}


@dataclass(frozen=True)
class Sine(RadiusLaw):
    """offset(t) = amplitude * sin(2 pi t / period)."""

    amplitude: float = 0.0
    period: float = 1.0
    kind = "sine"

    def offset(self, t: float) -> float:
        return self.amplitude * elementary.sin(2.0 * math.pi * t / self.period)

    @property
    def lipschitz(self) -> float:
        return 2.0 * math.pi * abs(self.amplitude) / self.period

    @property
    def is_constant(self) -> bool:
        return self.amplitude == 0.0

    def min_offset(self, t_end: float) -> float:
        return -abs(self.amplitude)  # conservative: the trough is reached within one period

    def zero_time(self, radius: float) -> float:
        a = abs(self.amplitude)
        if a < radius:
            return math.inf
        # first phase theta > 0 with amplitude sin(theta) = -radius
        theta = math.asin(radius / a) + (math.pi if self.amplitude > 0 else 0.0)
        return self.period * theta / (2.0 * math.pi)

    def to_spec(self) -> dict:
        return {"kind": self.kind, "amplitude": self.amplitude, "period": self.period}


def radius_law_from_spec(spec: dict | None, field: str = "agents.radius_law") -> RadiusLaw:
    """Build a radius law from its scene dict, refusing unknown kinds and bad numbers."""
    if spec is None:
        return Constant()
    keys = {"constant": set(), "linear": {"rate"}, "sine": {"amplitude", "period"}}
    checks.mapping(spec, field)
    kind = checks.kind(spec, field, keys, default="constant")
    checks.mapping(spec, field, allowed={"kind", *keys[kind]}, required=keys[kind])
    if kind == "linear":
        return Linear(rate=checks.number(spec["rate"], f"{field}.rate"))
    if kind == "sine":
        return Sine(amplitude=checks.number(spec["amplitude"], f"{field}.amplitude"),
                    period=checks.number(spec["period"], f"{field}.period", positive=True))
    return Constant()
