"""Versions of the software that produced a run, for recordings and summaries."""
from __future__ import annotations

import platform
from importlib import metadata


def versions() -> dict[str, str]:
    """Name -> version of sweep_ros and the libraries that shape its results."""
    out = {"python": platform.python_version()}
    for dist in ("sweep_ros", "numpy", "scipy", "proxsuite", "clarabel", "qpsolvers", "mcap",
                 "PyYAML"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out
