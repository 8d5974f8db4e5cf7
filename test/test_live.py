"""``sweep run --live``: a run served over Foxglove's WebSocket protocol (foxglove-sdk), read
by a plain WebSocket client (the websockets package) speaking the ``foxglove.sdk.v1``
subprotocol, its messages decoded by Foxglove's mcap_ros2 parser from the advertised schema
text. Timeouts are generous bounds for "receives", never measurements."""
from __future__ import annotations

import json
import socket
import struct
import threading

import pytest
from mcap_ros2._dynamic import generate_dynamic
from websockets.sync.client import connect

import sweep_core as sc
from sweep_core.cli import main
from sweep_core.io.live import LiveView
from sweep_core.io.metadata import run_metadata
from sweep_core.io.recording import read_metadata, runs
from sweep_core.model.scene import load_scene

WAIT_S = 60.0  # a generous bound on "receives", for a loaded machine


def _serve(tmp_path, t_end, rate=1.0):
    """A recorded run of the default scene served live, on its own thread."""
    scene = load_scene(None)
    sim = sc.Simulator(scene, dt=0.05, seed=0)
    lines: list[str] = []
    live = LiveView(0, rate, say=lines.append)
    out = tmp_path / "live.mcap"
    result: list = []
    thread = threading.Thread(target=lambda: result.append(runs.record_run(
        sim, t_end, out, run_metadata(scene, sim, t_end, 1), live=live)))
    thread.start()
    return scene, live, out, thread, result, lines


def _receive(port, topics):
    """Connects, subscribes to ``topics`` once all are advertised, returns the first message
    of each, decoded. A subscription the server refuses (it can advertise a channel an
    instant before it knows it for this client: a status message says so) is sent again."""
    got, channels, subs = {}, {}, {}
    with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1"],
                 open_timeout=WAIT_S) as ws:
        assert ws.subprotocol == "foxglove.sdk.v1"

        def subscribe():
            todo = [c for c in channels.values() if c["topic"] not in got]
            start = len(subs) + 1
            subs.update({start + k: c for k, c in enumerate(todo)})
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": start + k, "channelId": c["id"]} for k, c in enumerate(todo)]}))

        while len(got) < len(topics):
            msg = ws.recv(timeout=WAIT_S)
            if isinstance(msg, str):
                info = json.loads(msg)
                if info["op"] == "advertise":
                    channels.update({c["id"]: c for c in info["channels"]
                                     if c["topic"] in topics})
                    if len(channels) == len(topics):
                        subscribe()
                elif info["op"] == "status" and len(channels) == len(topics):
                    subscribe()
                continue
            op, sub, _ = struct.unpack_from("<BIQ", msg)
            assert op == 1  # message data
            c = subs[sub]
            assert (c["encoding"], c["schemaEncoding"]) == ("cdr", "ros2msg")
            decode = generate_dynamic(c["schemaName"], c["schema"])[c["schemaName"]]
            got.setdefault(c["topic"], decode(msg[13:]))
    return got


def test_client_receives_agents_and_walls_and_leaving_leaves_the_run_going(tmp_path):
    scene, live, out, thread, result, lines = _serve(tmp_path, t_end=3.0)
    try:
        got = _receive(live.port, {"/agents", "/walls", "/markers"})
    finally:
        thread.join(timeout=10 * WAIT_S)
        live.stop()
    assert got["/agents"].width == scene.n_agents
    walls = [m for m in got["/walls"].markers if m.ns == "walls"]
    assert len(walls) == len(scene.geometry.segment_a) > 0
    assert sum(m.ns == "agents" for m in got["/markers"].markers) == scene.n_agents
    # the client left mid-run: said in one line, the run completed and its recording closed
    assert result[0].status == "completed"
    assert any("left" in line for line in lines)
    assert read_metadata(out)["sweep_status"]["status"] == "completed"


def test_port_in_use_is_one_line_exit_2(tmp_path, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        code = main(["run", "--t-end", "0.1", "--out", str(tmp_path / "x.mcap"), "--quiet",
                     "--live", str(port)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and f"--live {port}" in err[0] and "fix:" in err[0]
    assert not (tmp_path / "x.mcap").exists()


@pytest.mark.parametrize("args", [["--live", "70000"], ["--live-rate", "-1"],
                                  ["--marker-rate", "0"]])
def test_bad_live_options_are_refused(tmp_path, capsys, args):
    code = main(["run", "--t-end", "0.1", "--out", str(tmp_path / "x.mcap"), "--quiet", *args])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and args[0] in err[0]
    assert not (tmp_path / "x.mcap").exists()


def test_a_recording_is_served_as_it_was_recorded(tmp_path):
    """sweep replay --live: the recording's own messages (agents, walls, markers) reach a
    client, decoded from the recording's schemas, paced on the recording's clock."""
    rec = tmp_path / "rec.mcap"
    assert main(["run", "--t-end", "3", "--dt", "0.05", "--out", str(rec), "--quiet"]) == 0
    from sweep_core.io.live import serve_recording

    lines: list[str] = []
    live = LiveView(0, 1.0, say=lines.append)
    served: list[int] = []
    thread = threading.Thread(target=lambda: served.append(serve_recording(rec, live)))
    thread.start()
    try:
        got = _receive(live.port, {"/agents", "/walls", "/markers"})
    finally:
        thread.join(timeout=10 * WAIT_S)
        live.stop()
    scene = load_scene(None)
    assert got["/agents"].width == scene.n_agents
    assert len([m for m in got["/walls"].markers if m.ns == "walls"]) == \
        len(scene.geometry.segment_a)
    # every message of the recording was served (3 s at dt 0.05: 61 states)
    from sweep_core.io.recording.scan import scan_recording
    assert served == [scan_recording(rec).message_count] and served[0] >= 2 * 61


def test_replay_live_port_in_use_is_one_line_exit_2(tmp_path, capsys):
    rec = tmp_path / "rec.mcap"
    assert main(["run", "--t-end", "0.1", "--out", str(rec), "--quiet"]) == 0
    capsys.readouterr()
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        code = main(["replay", str(rec), "--quiet", "--live", str(port)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and f"--live {port}" in err[0] and "fix:" in err[0]
