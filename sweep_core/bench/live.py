"""``sweep bench live``: the step rate of a recorded run served live (``sweep run --live``,
as fast as it goes: ``--live-rate 0``) with one Foxglove WebSocket client subscribed to every
channel, against the same run served to no client. The client is a separate process (the
websockets package) that reads and drops the messages, as a viewer on another core would. The
two variants alternate, ``--repeats`` times each, from the same seed (the same states); steps/s
is steps / wall time of the stepping (``record_run``), best of the repeats; ratio = with /
without."""
from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from sweep_core.bench import options
from sweep_core.bench.speed import crowd
from sweep_core.bench.tables import table_row, write_csv
from sweep_core.io.live import LiveView
from sweep_core.io.recording.runs import record_run
from sweep_core.numerics.simulator import Simulator

COLUMNS = ("N", "steps", "alone_steps_per_s", "client_steps_per_s", "ratio")

#: the client: connects, subscribes to every channel advertised, reads until the server closes
CLIENT = """
import json, sys
from websockets.sync.client import connect
with connect(sys.argv[1], subprotocols=["foxglove.sdk.v1"], open_timeout=60) as ws:
    print("connected", flush=True)
    n = 0
    try:
        for msg in ws:
            if isinstance(msg, str):
                info = json.loads(msg)
                if info["op"] == "advertise":
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                        {"id": c["id"], "channelId": c["id"]} for c in info["channels"]]}))
    except Exception:
        pass
"""


def _once(n: int, steps: int, client: bool, folder: Path) -> float:
    """Steps per second of one served run (with a client or not)."""
    sim = Simulator(crowd(n, False), dt=0.01, seed=0)
    proc = None
    with LiveView(0, rate=0.0, say=lambda line: None) as live:
        if client:
            proc = subprocess.Popen([sys.executable, "-c", CLIENT,
                                     f"ws://127.0.0.1:{live.port}"], stdout=subprocess.PIPE,
                                    text=True)
            assert proc.stdout is not None
            proc.stdout.readline()  # "connected"
        run = record_run(sim, steps * sim.dt, folder / "live.mcap", {}, live=live)
    if proc is not None:
        proc.wait(timeout=60)
    if run.failure is not None:
        raise run.failure
    return run.steps / run.wall_s


def run(args: argparse.Namespace) -> int:
    options.counts(args.sizes, "--sizes", high=options.MAX_AGENTS, example="1000")
    options.count(args.steps, "--steps", example="200")
    options.count(args.repeats, "--repeats", example="3")
    options.csv_path(args.csv)
    print("steps/s of sweep run --live --live-rate 0, without and with one client "
          "subscribed to every channel (best of the repeats)")
    widths = (6, 6, 18, 19, 7)
    print(" ".join(f"{c:>{w}}" for c, w in zip(COLUMNS, widths)), flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            _once(n, 5, False, Path(tmp))  # warm-up: kernels, caches
            alone, with_client = [], []
            for _ in range(args.repeats):
                alone.append(_once(n, args.steps, False, Path(tmp)))
                with_client.append(_once(n, args.steps, True, Path(tmp)))
            r = {"N": n, "steps": args.steps, "alone_steps_per_s": max(alone),
                 "client_steps_per_s": max(with_client),
                 "ratio": max(with_client) / max(alone)}
            rows.append(r)
            print(table_row(r, COLUMNS, widths), flush=True)
    write_csv(Path(args.csv), rows, COLUMNS)
    print(f"csv: {args.csv}")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``live`` to the ``bench`` subcommands."""
    p = sub.add_parser("live", help="step rate of a live-served run with one client vs none")
    p.add_argument("--sizes", type=int, nargs="+", default=[1000], metavar="N",
                   help="agent counts of the runs (default 1000)")
    p.add_argument("--steps", type=int, default=200, help="steps per run (default 200)")
    p.add_argument("--repeats", type=int, default=3, help="runs of each variant (default 3)")
    p.add_argument("--csv", default="bench_live.csv", help="CSV file to write")
    p.set_defaults(func=run)
