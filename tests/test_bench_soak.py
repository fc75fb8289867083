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
