"""Replays across machines: positions do not depend on the CPU's code paths, and a replay
that does depart (another platform, other versions, a changed recording) says where and how
far."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from test_replay import UNIFORM, record

from sweep_core.analysis import replay
from sweep_core.io.recording import Recorder, read_recording, scan_recording
from sweep_core.io.versions import platform_record

REPO = Path(__file__).resolve().parents[1]


def cpu_variants_off_env(numba_cache: Path | None = None) -> dict[str, str]:
    """This process's environment with every CPU-dependent code path we can switch moved off
    its default: OpenBLAS's kernels for an old core, numpy's SIMD dispatch down to its
    baseline, the C library's FMA and AVX2 variants off, and with ``numba_cache`` numba
    compiling for a generic x86-64 into that cache (else its kernels for this CPU, loaded
    from the cache)."""
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    env = dict(os.environ)
    env["OPENBLAS_CORETYPE"] = ("Sandybridge" if env.get("OPENBLAS_CORETYPE") == "Prescott"
                                else "Prescott")
    found = [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]
    if found:
        env["NPY_DISABLE_CPU_FEATURES"] = " ".join(found)
    env["GLIBC_TUNABLES"] = "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F"
    if numba_cache is not None:
        env["NUMBA_CPU_NAME"] = "generic"
        env["NUMBA_CACHE_DIR"] = str(numba_cache)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), env.get("PYTHONPATH", "")])
    return env


def test_recorded_with_other_cpu_code_paths_replays_bit_for_bit(tmp_path):
    """The bundled scene (200 agents at a door: face steps, clusters, walls) recorded with
    other BLAS, numpy SIMD, libm and numba code paths replays identically with the defaults
    (before: OpenBLAS's kernels for another core changed the face step's last bit, and the
    replay diverged at step 232)."""
    out = tmp_path / "other.mcap"
    done = subprocess.run(
        [sys.executable, "-m", "sweep_core.cli", "run", "--t-end", "3", "--out", str(out),
         "--quiet"], env=cpu_variants_off_env(tmp_path / "generic_kernels"), cwd=tmp_path,
        capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr
    res = replay.replay(out)
    assert res.identical, replay.format_replay(res)
    assert res.frames_compared == 301


def test_a_departed_replay_reports_how_far_and_from_when(tmp_path):
    """After the first difference the replay goes on and reports its largest distance from
    the recording and the first step beyond 1e-9 m (before: it stopped at the first bit)."""
    def shift(step, q):
        if step >= 30:
            q[2, 1] += 1e-6 * (step - 29)
        return q

    f = tmp_path / "shifted.mcap"
    record(f, segments=((60, {10: UNIFORM}, {}),), tamper=shift)
    d = replay.replay(f).divergence
    assert d is not None and (d.step, d.agent) == (30, 2)
    assert d.frames_after == 31 and d.departure_step == 30
    assert abs(d.departure_max_m - 31e-6) < 1e-9
    assert "beyond 1e-09 m from step 30" in replay.format_replay(replay.replay(f))



def _with_metadata(src: Path, dst: Path, change: dict[str, str]) -> None:
    """A copy of src whose ``sweep_ros`` metadata record has ``change`` applied."""
    info = scan_recording(src)
    meta = dict(info.metadata["sweep_ros"], **change)
    with Recorder(dst, metadata=meta, flush_interval_s=None) as rec:
        for topic, channel in info.channels.items():
            rec.add_channel(topic, channel.msgtype)
        for m in read_recording(src):
            rec.write(m.topic, m.log_time_ns, m.data)


def test_the_platform_is_recorded_and_differences_are_named(tmp_path):
    f = tmp_path / "here.mcap"
    record(f, segments=((20, {}, {}),))
    recorded = json.loads(scan_recording(f).metadata["sweep_ros"]["platform"])
    assert recorded == platform_record()
    assert set(recorded) == {"machine", "system", "cpu", "cpu_flags", "blas"}
    res = replay.replay(f)
    assert res.identical and not [n for n in res.notes if n.startswith("recorded on")]

    g = tmp_path / "elsewhere.mcap"
    _with_metadata(f, g, {"platform": json.dumps(dict(recorded, cpu="Other CPU 9000",
                                                      cpu_flags="sse4_2"))})
    res = replay.replay(g)
    assert res.identical
    assert f"recorded on cpu 'Other CPU 9000', replayed on {recorded['cpu']!r}" in res.notes
    assert any(n.startswith("recorded on cpu_flags 'sse4_2'") for n in res.notes) == \
        (recorded["cpu_flags"] != "sse4_2")
    assert "recorded on cpu 'Other CPU 9000'" in replay.format_replay(res)


def test_warm_up_compiles_every_kernel_of_the_engine():
    """Every numba kernel of sweep_core is in the cache once warm_up has run (the test
    session's start runs it on a fresh clone), so no user path meets a compile after it; a
    kernel it does not reach is named here."""
    import importlib
    import pkgutil

    import sweep_core
    from sweep_core.numerics import kernels

    for info in pkgutil.walk_packages(sweep_core.__path__, "sweep_core."):
        if not info.name.startswith(("sweep_core.cli", "sweep_core.bench", "sweep_core.ensemble")):
            importlib.import_module(info.name)
    kernels.warm_up()
    # a kernel compiles into the cache when first called, by Python or by another kernel
    assert len(kernels.dispatchers()) >= 20 and kernels.uncached() == []
