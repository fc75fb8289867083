"""`studio bench render` runs end to end (one short round): both shadow settings measured, keys typed reach
the studio."""

from __future__ import annotations

import pytest


@pytest.mark.slow
def test_render_smoke(tmp_path):
    from studio.bench_render import bench_render

    rows = bench_render(rounds=1, window_s=2.0, settle_s=1.0, keys=2, duration_s=4.0, out_dir=str(tmp_path))
    walk = rows.pop()
    assert walk["section"] == "render walk" and walk["status_readings"] >= 1, walk  # the status line was read
    assert 0 < walk["status_rtf_min"] <= walk["status_rtf_median"], walk  # a real-time factor was shown
    assert (tmp_path / "render_test_walk_g1.png").stat().st_size > 0  # and the page was photographed
    assert [r["shadows"] for r in rows] == ["on", "off (default)"], rows
    for row in rows:
        assert row["tab_fps"] > 0, row  # the tab drew frames in both settings
        assert row["real_time_factor"] > 0, row  # the walk ran meanwhile
        latency = row["key_latency_s"]
        assert latency is not None and 0 < latency["median"] <= latency["max"], row  # each key reached the studio
