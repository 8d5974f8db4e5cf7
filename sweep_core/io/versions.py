"""Versions of the software and the platform that produced a run, for recordings and
summaries."""
from __future__ import annotations

import platform
from functools import cache
from importlib import metadata
from pathlib import Path

from sweep_core.version import __version__

#: the libraries whose versions can change a run's floats
SHAPING = ("numpy", "scipy", "numba", "llvmlite", "cvxopt", "proxsuite", "clarabel", "piqp",
           "qpsolvers")
#: the CPU features that select a different code path in one of them (numpy's SIMD kernels,
#: OpenBLAS's, the C library's FMA variants, numba's target)
CPU_FLAGS = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512bw", "avx512vl")


def versions() -> dict[str, str]:
    """Name -> version of sweep_ros and the libraries that shape its results. sweep_ros's is
    the version of the code that runs (``sweep_core.version``), not of the installed
    distribution's metadata, which a source tree on the path or a stale install can differ
    from."""
    out = {"python": platform.python_version(), "sweep_ros": __version__}
    for dist in (*SHAPING, "mcap", "PyYAML"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


@cache
def platform_record() -> dict[str, str]:
    """The machine a run was made on: ``machine`` (e.g. x86_64), ``system``, ``cpu`` (model
    name), ``cpu_flags`` (those of :data:`CPU_FLAGS` it has, space-separated), ``blas``
    (numpy's BLAS library and version)."""
    cpu, flags = platform.processor() or "unknown", set()
    try:
        for line in Path("/proc/cpuinfo").read_text(errors="replace").splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and cpu in ("unknown", platform.machine()):
                cpu = value.strip()
            elif key.strip() == "flags":
                flags = set(value.split())
                break
    except OSError:
        pass
    return {"machine": platform.machine(), "system": platform.system(), "cpu": cpu,
            "cpu_flags": " ".join(f for f in CPU_FLAGS if f in flags), "blas": _blas()}


def _blas() -> str:
    try:
        import numpy

        blas = numpy.show_config(mode="dicts")["Build Dependencies"]["blas"]
        return f"{blas.get('name', '?')} {blas.get('version', '?')}"
    except Exception:  # noqa: BLE001 (numpy's build record varies between versions)
        return "unknown"
