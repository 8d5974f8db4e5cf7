"""Load measurements of sweep_node (not a test; numbers for issue 12 and the README).

    python test/node_load.py jam [--root DIR] [--seconds 30]
    python test/node_load.py cmd-rate [--root DIR] [--rate 1000] [--seconds 10]

``jam``: 2000 agents on a hexagonal lattice (spacing 0.5 m, radius 0.24 m, goal drift to the
centre, sigma 0.1 m/sqrt(s)) at the default pacing (20 Hz x 5 steps); prints the step time (ms),
achieved tick rate vs requested (Hz), timer overruns and the latency of ``pause`` (s).
``cmd-rate``: the bundled 200-agent scene, cmd_vel published at --rate Hz for --seconds s;
prints the node's command counters from its diagnostics.

The node is started from the sources under --root (default: this repository) with
``python -m sweep_ros.main``; DDS stays on this machine (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST)
on ROS_DOMAIN_ID (default 87).
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist, Vector3
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_srvs.srv import SetBool

sys.path.insert(0, str(Path(__file__).resolve().parent))
from scenes import hex_jam  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


def start_node(root: Path, work: Path, overrides: dict) -> subprocess.Popen:
    params = work / "params.yaml"
    params.write_text(yaml.safe_dump({"/**": {"ros__parameters": overrides}}))
    env = dict(os.environ, PYTHONPATH=str(root))
    return subprocess.Popen([sys.executable, "-m", "sweep_ros.main", "--ros-args",
                             "--params-file", str(params)], env=env, cwd=work,
                            stdout=open(work / "node.log", "w"), stderr=subprocess.STDOUT)


class Probe:
    def __init__(self) -> None:
        self.node = Node("sweep_load_probe")
        self.ex = SingleThreadedExecutor()
        self.ex.add_node(self.node)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        self.diag: list[tuple[float, dict]] = []
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self._on_diag, qos)
        self.cmd_vel = self.node.create_publisher(Twist, "/crowd/cmd_vel", qos)

    def _on_diag(self, msg: DiagnosticArray) -> None:
        self.diag.append((time.monotonic(),
                          {kv.key: kv.value for kv in msg.status[0].values}))

    def spin_for(self, s: float) -> None:
        end = time.monotonic() + s
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.01)

    def wait(self, pred, timeout: float) -> None:
        end = time.monotonic() + timeout
        while not pred():
            if time.monotonic() > end:
                raise SystemExit("timed out")
            self.ex.spin_once(timeout_sec=0.02)

    def pause(self, on: bool) -> float:
        client = self.node.create_client(SetBool, "/pause")
        self.wait(client.service_is_ready, 30)
        t0 = time.monotonic()
        fut = client.call_async(SetBool.Request(data=on))
        self.wait(fut.done, 120)
        dt = time.monotonic() - t0
        self.node.destroy_client(client)
        return dt


def jam(args: argparse.Namespace, probe: Probe, work: Path) -> None:
    scene = work / "jam.yaml"
    scene.write_text(yaml.safe_dump(hex_jam(40, 50)))
    proc = start_node(args.root, work, {"scene": str(scene), "rate_hz": 20.0,
                                        "steps_per_tick": 5})
    try:
        probe.wait(lambda: len(probe.diag) >= 2, 120)
        probe.spin_for(args.seconds)
        n_before = len(probe.diag)
        lat = []
        for _ in range(3):
            lat.append(probe.pause(True))
            probe.spin_for(1.0)
            probe.pause(False)
            probe.spin_for(3.0)
        recent = [d for _, d in probe.diag[2:]]
        if args.verbose:
            for d in recent:
                print({k: d[k] for k in ("sim_time_s", "steps", "paused", "step_time_ms",
                                         "tick_rate_hz", "tick_time_ms", "timer_overruns")})
        (w0, a), (w1, b) = probe.diag[2], probe.diag[n_before - 1]
        step = [float(d["step_time_ms"]) for d in recent if float(d["step_time_ms"]) > 0]
        steps = int(b["steps"]) - int(a["steps"])
        overruns = int(b["timer_overruns"]) - int(a["timer_overruns"])
        print(f"jam N=2000: step time {sum(step) / len(step):.0f} ms (mean of windows), "
              f"achieved tick rate {steps / 5 / (w1 - w0):.2f} Hz of 20 requested, "
              f"timer overruns {overruns} in {w1 - w0:.0f} s, pause latency "
              + ", ".join(f"{x:.2f}" for x in lat) + " s")
    finally:
        proc.terminate()
        proc.wait(60)


def cmd_rate(args: argparse.Namespace, probe: Probe, work: Path) -> None:
    proc = start_node(args.root, work, {"rate_hz": args.tick_hz} if args.tick_hz else {})
    try:
        probe.wait(lambda: probe.cmd_vel.get_subscription_count() > 0 and probe.diag, 60)
        period = 1.0 / args.rate
        n = int(args.rate * args.seconds)
        t0 = time.monotonic()
        for k in range(n):
            probe.cmd_vel.publish(Twist(linear=Vector3(x=0.5 + 0.5 * (k % 2), y=0.0)))
            while time.monotonic() < t0 + (k + 1) * period:
                probe.ex.spin_once(timeout_sec=0)
        elapsed = time.monotonic() - t0
        probe.spin_for(3.0)
        d = probe.diag[-1][1]
        keys = sorted(k for k in d if k.startswith("command"))
        print(f"cmd_vel: {n} published in {elapsed:.1f} s; node: "
              + ", ".join(f"{k} {d[k]}" for k in keys))
    finally:
        proc.terminate()
        proc.wait(60)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("what", choices=["jam", "cmd-rate"])
    ap.add_argument("--root", type=Path, default=REPO)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--tick-hz", type=float, default=0.0, help="cmd-rate: the node's rate_hz")
    ap.add_argument("--verbose", action="store_true", help="print every diagnostics window")
    args = ap.parse_args()
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", "87")
    rclpy.init()
    probe = Probe()
    with tempfile.TemporaryDirectory() as tmp:
        (jam if args.what == "jam" else cmd_rate)(args, probe, Path(tmp))
    rclpy.shutdown()


if __name__ == "__main__":
    main()
