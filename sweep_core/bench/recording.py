"""``sweep bench recording``: what recording costs the stepping thread, beside the step time.

For each N, two copies of one free-flow crowd (``speed.crowd``, dt = 0.01 s; ``--jammed`` adds
the jam) are stepped from the same seed after a warm-up, in alternating blocks of ``--block``
steps, so that both see the same states and the same machine load: one without recording, one
recording every step exactly as ``sweep run`` does (:func:`topics.record_state` into a
:class:`~sweep_core.recording.BackgroundRecorder`, zstd chunks, to a temporary file). After
each recorded block the writer is drained (untimed), so the plain block runs beside an idle
writer. Times in ms per step, medians over the measured steps:

* step: ``Simulator.step()`` without recording;
* step_rec: the same steps while the writer thread compresses and writes;
* record: state snapshot + CDR encoding of ``/poses`` and ``/agents`` + hand-off to the writer
  queue, on the stepping thread (median and max); record_pct = 100 record / step;
* markers: the ``/markers`` MarkerArray (:mod:`sweep_core.io.markers`, a disk per person)
  encoded and handed off at ``sweep run``'s default rate (10 Hz of simulated time: every 10th
  step), its mean per step (markers_each_ms: per message encoded, median);
* overhead_pct = 100 ((step_rec + record + markers) / step - 1): the recording cost plus any
  slowdown of the step by the writer thread (GIL, shared caches and cores);
* backlog_max: most messages ever queued; kB_per_step: recorded file size per step.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from sweep_core.bench import options
from sweep_core.bench.speed import crowd
from sweep_core.bench.tables import table_row, write_csv
from sweep_core.io import cdr, markers, topics
from sweep_core.io.cdr.markers import encode_marker_array
from sweep_core.io.recording import BackgroundRecorder
from sweep_core.numerics.simulator import Simulator

COLUMNS = ("N", "scene", "step_ms", "step_rec_ms", "record_ms", "record_max_ms", "record_pct",
           "markers_ms", "markers_each_ms", "overhead_pct", "backlog_max", "kB_per_step")


def measure(n: int, jammed: bool, steps: int, warmup: int, block: int = 20,
            compression: str = "zstd") -> dict:
    """One row of the table (see the module docstring and COLUMNS)."""
    plain_sim, sim = (Simulator(crowd(n, jammed), dt=0.01, seed=0) for _ in range(2))
    plain_sim.step(warmup)
    sim.step(warmup)
    plain, step, record, drawn = [], [], [], []
    backlog = 0
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.mcap"
        with BackgroundRecorder(path, max_backlog=64, compression=compression) as rec:
            for name, msgtype in topics.TYPES.items():
                rec.add_channel("/" + name, msgtype)
            rec.add_channel(markers.MARKERS, cdr.MARKER_ARRAY)
            groups = markers.agent_groups(sim)
            every = markers.markers_every(sim.dt, 1)
            while len(step) < steps:
                for _ in range(min(block, steps - len(step))):
                    start = time.perf_counter()
                    plain_sim.step()
                    plain.append(time.perf_counter() - start)
                for _ in range(min(block, steps - len(step))):
                    t0 = time.perf_counter()
                    sim.step()
                    t1 = time.perf_counter()
                    topics.record_state(rec.write, sim.state)
                    t2 = time.perf_counter()
                    if sim.state.step % every == 0:
                        ns = topics.stamp_ns(sim.t)
                        rec.write(markers.MARKERS, ns, encode_marker_array(
                            ns, "map", markers.state_batches(sim, groups)))
                        drawn.append(time.perf_counter() - t2)
                    else:
                        drawn.append(0.0)
                    record.append(t2 - t1)
                    step.append(t1 - t0)
                    backlog = max(backlog, rec.backlog)
                rec.flush()
        if rec.error:
            raise RuntimeError(f"recording failed: {rec.error}")
        size = path.stat().st_size
    med = {k: 1e3 * float(np.median(v)) for k, v in
           (("step", plain), ("step_rec", step), ("record", record))}
    med["markers"] = 1e3 * float(np.mean(drawn))
    return {"N": n, "scene": "jammed" if jammed else "free", "step_ms": med["step"],
            "step_rec_ms": med["step_rec"], "record_ms": med["record"],
            "record_max_ms": 1e3 * max(record), "record_pct": 100 * med["record"] / med["step"],
            "markers_ms": med["markers"],
            "markers_each_ms": 1e3 * float(np.median([d for d in drawn if d > 0] or [0.0])),
            "overhead_pct": 100 * ((med["step_rec"] + med["record"] + med["markers"])
                                   / med["step"] - 1),
            "backlog_max": backlog, "kB_per_step": size / steps / 1e3}


def run(args: argparse.Namespace) -> int:
    options.counts(args.sizes, "--sizes", high=options.MAX_AGENTS, example="1000")
    options.count(args.steps, "--steps", example="200")
    options.count(args.warmup, "--warmup", low=0, example="5")
    options.count(args.block, "--block", example="20")
    options.csv_path(args.csv)
    widths = (6, 7, 9, 11, 10, 14, 11, 11, 15, 13, 12, 12)
    print("per step, ms; record = snapshot + CDR encoding + hand-off on the stepping thread")
    print(" ".join(f"{c:>{w}}" for c, w in zip(COLUMNS, widths)), flush=True)
    results = []
    for n in args.sizes:
        for jammed in ((False, True) if args.jammed else (False,)):
            r = measure(n, jammed, args.steps, args.warmup, args.block, args.compression)
            results.append(r)
            print(table_row(r, COLUMNS, widths), flush=True)
    write_csv(Path(args.csv), results, COLUMNS)
    print(f"csv: {args.csv}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``recording`` to the ``bench`` subcommands."""
    p = sub.add_parser("recording", help="per-step cost of recording beside the step time")
    p.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000], metavar="N",
                   help="agent counts measured (default 1000 10000)")
    p.add_argument("--steps", type=int, default=200,
                   help="measured steps, with and without recording each (default 200)")
    p.add_argument("--warmup", type=int, default=5, help="steps before measuring")
    p.add_argument("--block", type=int, default=20,
                   help="steps per block; the two variants alternate block by block")
    p.add_argument("--jammed", action="store_true", help="also the jammed crowd (slow)")
    p.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"),
                   help="chunk compression (default zstd, as sweep run)")
    p.add_argument("--csv", default="bench_recording.csv", help="CSV file to write")
    p.set_defaults(func=run)
