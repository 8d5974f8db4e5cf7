"""Runs give the same bits on every CPU: robot scenes (each bundled planner, the scan, the
crowd's avoid reaction, the kinematics), the CrowdNav environment and a recording's robot
messages, hashed in a process with the CPU's FMA, AVX2 and AVX-512 code paths of the C
library, numpy and OpenBLAS switched off, equal those of a process with them on. On a CPU
without those features both processes take the same paths and the test compares like with
like."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from test_platform import cpu_variants_off_env

RUNS = """
import hashlib, numpy as np, gymnasium
import sweep_core.envs
from sweep_core.bench.social_runs import with_controller
from sweep_core.io.cdr.robot import yaw_quaternion, quaternion_yaw
from sweep_core.model.scene import load_scene
from sweep_core.numerics.simulator import Simulator

h = hashlib.sha256()
cases = [("crowdnav", c, 0.1, 40) for c in ("pursuit", "orca", "social_force", "window")]
cases.append(("robot_crowd", None, 0.01, 120))
for name, controller, dt, n in cases:
    scene = load_scene(name)
    if controller is not None:
        scene = with_controller(scene, controller)
    sim = Simulator(scene, dt=dt, seed=11)
    for _ in range(n):
        sim.step()
        h.update(sim.positions.tobytes())
        for st in sim.robots.states.values():
            h.update(np.array(st.pose + st.twist + st.command, dtype=np.float64).tobytes())
            h.update(np.asarray(st.contact_impulse, dtype=np.float64).tobytes())
            if st.scan is not None:
                h.update(np.asarray(st.scan.ranges).tobytes())
            h.update(np.array(yaw_quaternion(st.pose[2])).tobytes())
            h.update(np.float64(quaternion_yaw(yaw_quaternion(st.pose[2]))).tobytes())
env = gymnasium.make("sweep/CrowdNav-v0").unwrapped
rng = np.random.default_rng(2)
obs, _ = env.reset(seed=4)
for _ in range(150):
    obs, reward, end, cut, _ = env.step(rng.uniform(env.action_space.low, env.action_space.high))
    for key in sorted(obs):
        h.update(obs[key].tobytes())
    h.update(np.float64(reward).tobytes())
    if end or cut:
        obs, _ = env.reset()
print(h.hexdigest())
"""


@pytest.mark.skipif(sys.platform != "linux", reason="glibc tunables")
def test_robot_runs_and_environment_have_the_same_bits_without_cpu_variants() -> None:
    root = str(Path(__file__).resolve().parents[1])
    mine = subprocess.run([sys.executable, "-c", RUNS], capture_output=True, text=True,
                          cwd=root, check=True).stdout
    plain = subprocess.run([sys.executable, "-c", RUNS], capture_output=True, text=True,
                           cwd=root, check=True, env=cpu_variants_off_env()).stdout
    assert len(mine.strip()) == 64 and mine == plain
