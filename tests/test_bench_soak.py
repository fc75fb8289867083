"""`studio bench soak` runs end to end (a few seconds, one client, one browser tab): figures present, no exception."""

from __future__ import annotations

import math

import pytest


@pytest.mark.slow
def test_soak_smoke():
    from studio.bench_soak import bench_soak

    rows = bench_soak(minutes=0.25, clients=1, tabs=1)
    studio = next(r for r in rows if r["section"] == "soak")
    clients = [r for r in rows if r["section"] == "soak clients"]
    assert studio["exceptions"] == 0 and studio["engine_restarts"] == 0, rows
    assert len(clients) == 1 and clients[0]["ws_messages_per_s"] > 0  # the client was streamed to
    assert clients[0]["robot_frames_per_s"] > 0  # and decoded robot poses from the stream
    assert any(r["section"] == "soak cpu" and r["what"] == "studio total (not bench)" for r in rows)
    assert math.isfinite(studio["sim_clock_drift_pct"]) and studio["engine_frames_per_s"] > 0
    assert studio["edits"] >= 2
    assert studio["tabs"] == 1 and float(studio["tab_fps"]) > 0  # the tab rendered the studio


def test_headless_clients_run_in_their_own_process():
    """The soak's clients live in a child process (the studio process's RSS is the studio's): they connect,
    decode what the server streams and report their rates and errors over the line protocol, then stop."""
    import time

    import numpy as np
    import viser

    from studio.bench_soak import _ClientProcess
    from tests.conftest import free_port

    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    node = server.scene.add_frame("/robot/pelvis")
    pool = _ClientProcess(f"ws://127.0.0.1:{server.get_port()}/", 2)
    try:
        assert pool.proc.stdout is not None and pool.proc.stdout.readline().strip() == "ready"
        deadline = time.monotonic() + 60
        while len(server.get_clients()) < 2 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert len(server.get_clients()) == 2
        pool.mark()
        for i in range(40):  # 40 moves of a robot body, 25 ms apart
            node.position = (0.01 * i, 0.0, 0.0)
            time.sleep(0.025)
        time.sleep(0.5)
        reports = pool.report()
        assert len(reports) == 2 and all(not r["error"] for r in reports), reports
        assert all(r["rates"][0] > 0 and r["rates"][2] > 0 for r in reports), reports  # messages, robot frames
        assert pool.pid != __import__("os").getpid() and np.isfinite(reports[0]["rates"][1])
    finally:
        pool.stop()
        server.stop()
    assert pool.proc.returncode == 0


def test_sim_clock_counts_a_reset_apart_from_the_time_simulated():
    """A fall resets the sim clock to 0: the drift is what was simulated over the wall time, the reset is
    counted apart (a first-and-last-frame difference read it as −90 % drift), and a stall is measured."""
    from studio.bench_soak import sim_clock

    real_time = [(0.1 * k, 30.0 + 0.1 * k) for k in range(101)]  # 10 s at real time
    assert sim_clock(real_time)["resets"] == 0
    assert sim_clock(real_time)["drift"] == pytest.approx(0.0, abs=1e-9)
    fell = [(0.1 * k, 30.0 + 0.1 * k) for k in range(60)] + [(0.1 * k, 0.1 * (k - 60)) for k in range(60, 101)]
    clock = sim_clock(fell)
    assert clock["resets"] == 1
    assert clock["simulated_s"] == pytest.approx(9.9)  # the step back to 0 is not counted as time
    assert clock["drift"] == pytest.approx(-0.01, abs=1e-9)
    stalled = real_time[:50] + [(5.0 + 0.1 * k, real_time[49][1]) for k in range(1, 21)] + [
        (7.0 + 0.1 * k, real_time[49][1] + 0.1 * k) for k in range(1, 31)]
    clock = sim_clock(stalled)
    assert clock["longest_stall_s"] == pytest.approx(2.1)  # frames from 4.9 s to 7.0 s all show the same sim time
    assert clock["resets"] == 0 and clock["drift"] == pytest.approx((4.9 + 3.0) / 10.0 - 1.0)
    assert math.isnan(sim_clock(real_time[:1])["drift"])
