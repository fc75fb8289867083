"""Record 10 s of joystick walking in Test mode and export it from the panel (issue 15)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from engine.walk_recording import load_run_motion
from tests.conftest import ServedStudio
from tests.e2e.browser import open_page, stall_ms, wait_for_text

pytestmark = pytest.mark.e2e

RECORDING = re.compile(r"Recording… (?P<s>\d+\.\d) s simulated")
SAVED = re.compile(r"Saved (?P<path>runs/[\w.-]+\.npz): (?P<frames>\d+) frames")
PELVIS_X = re.compile(r"pelvis at x (?P<x>[+-]?\d+\.\d+) m")
EXPORTED = re.compile(r"Exported (?P<path>exports/[\w.-]+\.csv) \((?P<frames>\d+) frames at 30 fps\)")


def pelvis_x(page) -> float:
    """The pelvis's x (m) as the Robot tab's status line shows it."""
    m = PELVIS_X.search(page.inner_text("body"))
    assert m, page.inner_text("body")[-500:]
    return float(m["x"])


def test_record_ten_seconds_of_joystick_walking_and_export(tmp_path, monkeypatch, artifacts):
    monkeypatch.setenv("MOTION_STUDIO_MOTIONS", str(tmp_path))
    studio = ServedStudio("g1")
    try:
        with open_page(studio.url, 1000, 720) as page:
            wait_for_text(page, "Engine running")
            page.get_by_role("button", name="Test").click()
            wait_for_text(page, "test mode", timeout_ms=60_000)
            page.get_by_role("button", name="● Record").click()
            wait_for_text(page, "Recording…", timeout_ms=60_000)
            x0 = pelvis_x(page)
            # Hold ▲ forward until 10 s of simulated walking are recorded and the status line has the pelvis 0.6 m
            # ahead (a loaded machine simulates far slower than real time, and its browser's hold messages can come
            # late: a CI run beside a benchmark recorded 9.6 s of stepping in place before the first forward step;
            # wait on the engine's figures, never on the wall clock).
            page.get_by_role("button", name="▲ forward").hover()
            page.mouse.down()
            try:
                page.wait_for_function(
                    "x0 => { const t = document.body.innerText;"
                    " const m = t.match(/Recording… (\\d+\\.\\d) s simulated/);"
                    " const x = t.match(/pelvis at x ([+-]?\\d+\\.\\d+) m/);"
                    " return m && x && parseFloat(m[1]) >= 10.0 && parseFloat(x[1]) >= x0 + 0.6; }",
                    arg=x0, timeout=stall_ms(1_500_000), polling=500)
            finally:
                page.mouse.up()
            page.get_by_role("button", name="■ Stop recording").click()
            page.wait_for_function("() => /Saved runs\\/[\\w.-]+\\.npz/.test(document.body.innerText)", timeout=stall_ms(120_000))
            saved = SAVED.search(page.inner_text("body"))
            assert saved, page.inner_text("body")[-500:]
            page.get_by_role("button", name="Export recording").click()
            page.wait_for_function("() => /Exported exports\\//.test(document.body.innerText)", timeout=stall_ms(300_000))
            page.screenshot(path=str(artifacts / "studio_record_export.png"))
            exported = EXPORTED.search(page.inner_text("body"))
            assert exported, page.inner_text("body")[-500:]
        run = load_run_motion(tmp_path / saved["path"])
        assert run.frames == int(saved["frames"]) and run.duration_s >= 10.0
        assert run.qpos[-1, 0] - run.qpos[0, 0] > 0.5, "the recording walked forward"
        assert not run.metrics.get("fell", False)
        rows = np.loadtxt(tmp_path / exported["path"], delimiter=",", ndmin=2)
        assert rows.shape == (int(exported["frames"]), 36)
        assert abs(rows.shape[0] / 30.0 - run.duration_s) < 0.1
        assert np.allclose(rows[0, :3], run.qpos[0, :3], atol=1e-6)
    finally:
        studio.stop()
