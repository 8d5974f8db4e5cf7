"""`sweep replay` (bit-for-bit re-simulation from a recording), `sweep compare` (pathwise
distance of two runs) and the fine Brownian paths of sweep_core.paths.

Recordings are made here: like `sweep run` (run_metadata, /poses and /agents per recorded
step) and, for commands, resets and live noise changes, the way sweep_ros/node.py records
them (metadata command_*, reset_*, parameter_*, log times that keep increasing over resets).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import sweep_core as sc
from sweep_core.analysis import compare, replay
from sweep_core.analysis.run import load_run
from sweep_core.cli import main
from sweep_core.io import topics
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import Recorder
from sweep_core.model.drift import field_from_spec
from sweep_core.numerics import paths

DT, SEED = 0.01, 11
SCENE = sc.Scene.from_dict({
    "name": "box6",
    "agents": {"positions": [[0.5, 0.5], [1.0, 0.5], [1.5, 0.5], [0.5, 1.0], [1.0, 1.0],
                             [1.5, 1.0]], "radius": 0.2},
    "walls": [{"kind": "halfplane", "normal": [1, 0], "offset": 0.0},
              {"kind": "halfplane", "normal": [0, 1], "offset": 0.0},
              {"kind": "segment", "a": [3.0, 0.0], "b": [3.0, 2.0]}],
    "drift": {"kind": "uniform", "velocity": [-0.8, -0.3]},
    "noise": {"sigma": 0.1},
})
UNIFORM = {"kind": "uniform", "velocity": [1.2, 0.4]}
GOAL = {"kind": "goal", "goal": [2.0, 1.5], "speed": 1.3, "slow_radius": 0.5}
GRID = {"kind": "grid", "x": [0.0, 1.0, 2.0], "y": [0.0, 2.0],
        "vx": [[0.5, -0.25, -1.0], [0.1, 0.2, 0.3]], "vy": [[0.3, 0.0, -0.3], [0.7, 0.6, 0.5]]}


def record(path: Path, *, segments=((80, {}, {}),), every: int = 1, dt: float = DT,
           seed: int = SEED, scene: sc.Scene = SCENE, path_dt: float | None = None,
           noise_sigma: float = -1.0, chunk_size: int = 1 << 20, tamper=None,
           command_step_shift: int = 0, record_parameters: bool = True) -> list[list[sc.State]]:
    """Runs and records ``segments`` of (steps, {step: drift spec}, {step: noise_sigma}),
    separated by resets, publishing every ``every`` steps; returns the states per segment.

    tamper(step, positions) may change the positions written at a step (not the run);
    command_step_shift adds to the step written in the command metadata (not the run)."""
    sim = sc.Simulator(scene, dt=dt, seed=seed)
    meta = run_metadata(scene, sim, None, every)
    meta["parameters"] = json.dumps({"noise_sigma": noise_sigma, "dt": dt, "seed": seed})
    if path_dt is not None:
        meta["path_dt"] = repr(path_dt)
    dt_ns = topics.stamp_ns(dt)
    sigma = noise_sigma
    counts = {"command": 0, "parameter": 0}
    out: list[list[sc.State]] = []

    def apply_sigma() -> None:
        sim.set_sigma(scene.sigma if sigma == -1.0 else sigma)

    with Recorder(path, metadata=meta, chunk_size=chunk_size, flush_interval_s=None) as rec:
        for name, msgtype in topics.TYPES.items():
            rec.add_channel("/" + name, msgtype)
        last_log, epoch = 0, 0

        def publish() -> None:
            nonlocal last_log
            st = sim.state
            out[-1].append(st)
            if tamper is not None:
                st = sc.State(st.t, st.step, tamper(st.step, st.positions.copy()), st.radii,
                              st.velocities, st.reaction, st.contacts, st.min_gap)
            log = epoch + topics.stamp_ns(st.t)
            for name, data in topics.encode_state(st).items():
                rec.write("/" + name, log, data)
            last_log = log

        for s, (steps, commands, sigmas) in enumerate(segments):
            if s:
                epoch = last_log + dt_ns
                sim.reset()
                rec.add_metadata(f"reset_{s:06d}", {"log_time_ns": str(epoch),
                                                    "seed": str(sim.seed)})
            apply_sigma()
            fine = paths.FinePath(seed, dt, path_dt, scene.n_agents) if path_dt else None
            out.append([])
            publish()
            for k in range(steps):
                log = epoch + topics.stamp_ns(sim.t)
                if k in commands:
                    sim.set_drift(field_from_spec(commands[k], scene.n_agents))
                    counts["command"] += 1
                    rec.add_metadata(f"command_{counts['command']:06d}", {
                        "topic": "/cmd_vel", "step": str(k + command_step_shift),
                        "t": repr(sim.t), "log_time_ns": str(log),
                        "field": json.dumps(commands[k])})
                if k in sigmas:
                    sigma = sigmas[k]
                    apply_sigma()
                    counts["parameter"] += 1
                    if record_parameters:
                        rec.add_metadata(f"parameter_{counts['parameter']:06d}", {
                            "name": "noise_sigma", "value": json.dumps(sigma),
                            "step": str(k), "log_time_ns": str(log)})
                if fine is not None:
                    paths.step(sim, fine)
                else:
                    sim.step()
                if (k + 1) % every == 0:
                    publish()
    return out


# ---------------------------------------------------------------------------------------------
# replay
# ---------------------------------------------------------------------------------------------


def test_seeded_run_with_commands_replays_bit_for_bit(tmp_path, capsys):
    f = tmp_path / "cmd.mcap"
    states = record(f, segments=((90, {15: UNIFORM, 40: GOAL, 41: GRID, 70: GOAL}, {}),))[0]
    assert not np.array_equal(states[-1].positions, SCENE.positions)
    res = replay.replay(f)
    assert res.identical, replay.format_replay(res)
    assert (res.frames_compared, res.steps_simulated, res.commands_applied) == (91, 90, 4)
    assert res.last_step == 90 and not res.truncated and res.divergence is None
    assert main(["replay", str(f), "--quiet"]) == 0
    assert "IDENTICAL" in capsys.readouterr().out


def test_one_ulp_is_a_divergence_with_its_step_and_agent(tmp_path, capsys):
    def nudge(step, q):
        if step == 50:
            q[3, 0] = np.nextafter(q[3, 0], np.inf)
        return q

    f = tmp_path / "ulp.mcap"
    record(f, segments=((60, {10: UNIFORM}, {}),), tamper=nudge)
    res = replay.replay(f)
    d = res.divergence
    assert not res.identical and (d.step, d.agent, d.agents_differing) == (50, 3, 1)
    assert 0 < d.distance_m < 1e-12 and res.frames_compared == 50
    assert d.recorded[0] == np.nextafter(d.replayed[0], np.inf)
    # the replay goes on to the end: one ulp at one frame is no departure beyond 1e-9 m
    assert d.frames_after == 11 and d.departure_step is None and 0 < d.departure_max_m < 1e-12
    assert main(["replay", str(f), "--quiet"]) == 1
    out = capsys.readouterr().out
    assert "DIVERGED at step 50" in out and "never beyond 1e-9 m" in out
    assert main(["replay", str(f), "--quiet", "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["divergence"]["agent"] == 3


def test_a_recording_of_another_engine_version_is_named_as_such():
    """The engine shapes every float of a run: a recording made by another sweep_ros version
    is reported with both versions, like a library of SHAPING."""
    from types import SimpleNamespace

    here = sc.__version__
    notes = replay.version_notes(SimpleNamespace(versions={"sweep_ros": "0.0.1"}))
    assert any(note.startswith(f"sweep_ros {here} here, 0.0.1 in the recording")
               for note in notes), notes
    assert replay.version_notes(SimpleNamespace(versions={"sweep_ros": here})) == []


def test_a_command_recorded_at_the_wrong_step_diverges_after_it(tmp_path):
    f = tmp_path / "late.mcap"
    record(f, segments=((40, {20: UNIFORM}, {}),), command_step_shift=1)
    d = replay.replay(f).divergence
    assert d is not None and d.step == 21 and d.agent >= 0 and d.max_distance_m > 1e-4


def test_node_style_ticks_resets_and_noise_changes(tmp_path):
    """Published every 4 steps (node ticks), commands at other steps, two resets, noise_sigma
    set at start and changed live."""
    segs = ((37, {3: UNIFORM, 9: GRID}, {13: 0.3}),
            (22, {0: GOAL, 5: UNIFORM}, {}),
            (17, {}, {6: -1.0}))
    f = tmp_path / "node.mcap"
    states = record(f, segments=segs, every=4, noise_sigma=0.05)
    res = replay.replay(f)
    assert res.identical, replay.format_replay(res)
    assert res.segments == 3 and res.commands_applied == 4
    assert res.frames_compared == sum(len(s) for s in states) == 10 + 6 + 5
    assert res.steps_simulated == 36 + 20 + 16
    # the live noise change is needed: without its record the replay diverges after step 13
    g = tmp_path / "node_noparam.mcap"
    record(g, segments=segs, every=4, noise_sigma=0.05, record_parameters=False)
    d = replay.replay(g).divergence
    assert d is not None and (d.segment, d.step) == (0, 16)


def test_truncated_recording_replays_up_to_its_last_chunk(tmp_path, capsys):
    f = tmp_path / "full.mcap"
    record(f, segments=((120, {30: UNIFORM}, {}),), chunk_size=4096)
    data = f.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    res = replay.replay(cut)
    assert res.identical and res.truncated and res.read_until
    assert 30 < res.frames_compared < 121 and res.last_step == res.frames_compared - 1
    assert main(["replay", str(cut), "--quiet"]) == 0
    assert "truncated recording" in capsys.readouterr().out


def test_sweep_run_record_every_replays(tmp_path):
    scene = tmp_path / "s.yaml"
    scene.write_text(SCENE.to_yaml())
    f = tmp_path / "run.mcap"
    assert main(["run", str(scene), "--t-end", "0.5", "--seed", "3", "--record-every", "7",
                 "--out", str(f), "--quiet"]) == 0
    res = replay.replay(f)
    assert res.identical and res.frames_compared == 8 and res.steps_simulated == 49


def test_not_a_sweep_recording_is_refused(tmp_path, capsys):
    f = tmp_path / "bare.mcap"
    with Recorder(f) as rec:
        rec.add_channel("/poses", "geometry_msgs/msg/PoseArray")
        rec.write("/poses", 0, topics.encode_state(sc.Simulator(SCENE).state)["poses"])
    assert main(["replay", str(f), "--quiet"]) == 2
    assert "does not describe the run" in capsys.readouterr().err


def test_hostile_recorded_metadata_is_refused_not_expanded(tmp_path, capsys):
    """A recording whose scene holds an alias bomb in its description (600 bytes standing for
    3.5e9 numbers) hung `sweep replay`; a command 100 000 lists deep raised RecursionError.
    Both are named as problems of the metadata, and replay exits 2 with one line."""
    bomb = ["l0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1]"] + [
        f"l{k}: &a{k} [{', '.join([f'*a{k - 1}'] * 9)}]" for k in range(1, 10)]
    f = tmp_path / "hostile.mcap"
    sim = sc.Simulator(SCENE, dt=DT, seed=SEED)
    meta = run_metadata(SCENE, sim, None, 1)
    meta["scene"] = SCENE.to_yaml() + "description: {" + ", ".join(bomb) + "}\n"  # YAML
    with Recorder(f, metadata=meta) as rec:
        rec.add_channel("/poses", "geometry_msgs/msg/PoseArray")
        rec.write("/poses", 0, topics.encode_state(sim.state)["poses"])
        rec.add_metadata("command_000000", {"topic": "cmd", "step": "0", "log_time_ns": "0",
                                            "field": "[" * 100_000})
    meta_read = load_run(f)
    shown = " ".join(meta_read.problems)
    assert "aliases repeat more than 100000 nodes" in shown, shown
    assert "nested too deep" in shown, shown
    assert main(["replay", str(f), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err, err


# ---------------------------------------------------------------------------------------------
# fine Brownian paths
# ---------------------------------------------------------------------------------------------


def test_fine_path_with_one_substep_is_the_plain_run():
    a = sc.Simulator(SCENE, dt=DT, seed=SEED)
    b = sc.Simulator(SCENE, dt=DT, seed=SEED)
    a.run(0.3)
    paths.run(b, 0.3, DT)
    assert np.array_equal(a.positions, b.positions)


def test_coarse_increments_are_sums_of_fine_ones():
    fine = paths.FinePath(SEED, 0.001, 0.001, 6)
    coarse = paths.FinePath(SEED, 0.01, 0.001, 6)
    for _ in range(5):
        total = sum(fine.increment() for _ in range(10))
        assert np.allclose(coarse.increment(), total, rtol=0, atol=1e-15)
    with pytest.raises(sc.SceneError, match="path_dt"):
        paths.FinePath(SEED, 0.01, 0.003, 6)


def test_path_dt_run_replays(tmp_path):
    f = tmp_path / "coarse.mcap"
    record(f, segments=((25, {5: GOAL}, {}),), path_dt=0.001)
    res = replay.replay(f)
    assert res.identical and res.frames_compared == 26
    assert load_run(f).path_dt == 0.001


# ---------------------------------------------------------------------------------------------
# compare
# ---------------------------------------------------------------------------------------------

NOISY = sc.Scene.from_dict({**SCENE.spec, "noise": {"sigma": 0.3}})


@pytest.fixture(scope="module")
def three_runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("compare")
    fine, coarse, other = d / "fine.mcap", d / "coarse.mcap", d / "other.mcap"
    s_f = record(fine, segments=((300, {}, {}),), dt=0.001, scene=NOISY)[0]
    s_c = record(coarse, segments=((30, {}, {}),), dt=0.01, path_dt=0.001, scene=NOISY)[0]
    s_o = record(other, segments=((30, {}, {}),), dt=0.01, seed=SEED + 1, path_dt=0.001,
                 scene=NOISY)[0]
    return (fine, s_f), (coarse, s_c), (other, s_o)


def test_compare_on_the_same_brownian_path(three_runs, capsys):
    (fine, s_f), (coarse, s_c), (other, s_o) = three_runs
    c = compare.compare(fine, coarse)
    dist = np.array([np.linalg.norm(s_f[10 * k].positions - s_c[k].positions, axis=1)
                     for k in range(31)])
    assert c.common_frames == 31 and c.t_last_s == pytest.approx(0.3)
    assert c.sup_m == pytest.approx(dist.max(), rel=1e-12)
    assert np.allclose(c.per_agent_sup_m, dist.max(axis=0), rtol=1e-12)
    assert c.sup_t_s == pytest.approx(0.01 * dist.max(axis=1).argmax())
    assert c.sup_agent == dist.max(axis=0).argmax()
    assert np.allclose(c.table[:, 2], dist.mean(axis=1))
    assert c.shared_path.startswith("shared") and c.pathwise
    o = compare.compare(fine, other)
    assert o.shared_path.startswith("NOT shared") and not o.pathwise
    assert c.sup_m < 0.5 * o.sup_m, (c.sup_m, o.sup_m)
    assert compare.compare(coarse, coarse).sup_m == 0.0

    assert main(["compare", str(fine), str(coarse), "--json", "--quiet"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["sup_m"] == pytest.approx(c.sup_m) and len(out["per_agent_sup_m"]) == 6
    rows = np.genfromtxt(out["outputs"]["csv"], delimiter=",", names=True)
    assert len(rows) == 31 and Path(out["outputs"]["png"]).stat().st_size > 0


def test_compare_aligns_on_common_times_only(tmp_path):
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    s_a = record(a, segments=((4, {}, {}),), dt=0.003)[0]
    s_b = record(b, segments=((6, {}, {}),), dt=0.002)[0]
    c = compare.compare(a, b)  # t = 0, 0.006 and 0.012 s are common (stamps in whole ns)
    assert c.common_frames == 3 and c.t_last_s == pytest.approx(0.012)
    assert c.final_max_m == pytest.approx(
        np.linalg.norm(s_a[4].positions - s_b[6].positions, axis=1).max(), rel=1e-12)
    assert c.table[1, 1] == pytest.approx(
        np.linalg.norm(s_a[2].positions - s_b[3].positions, axis=1).max(), rel=1e-12)
    assert c.shared_path.startswith("NOT shared") and not c.pathwise
