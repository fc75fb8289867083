"""The Record button's engine side: the engine records the walk (simulated + the reference it tracked),
writes runs/<name>.npz atomically, and the export job writes it in a learning format (issue 15)."""

from __future__ import annotations

import time

import numpy as np

from engine import protocol as msg
from engine.core import EngineCore
from engine.export.unitree_csv import UNITREE_G1_29
from engine.walk_recording import load_run_motion


def _results(core: EngineCore, events: list, job: str, timeout_s: float = 120.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        events.extend(core.jobs.drain())
        done = [e for e in events if isinstance(e, msg.JobProgress) and e.job == job and e.result is not None]
        if done:
            return done[-1].result
        time.sleep(0.02)
    raise AssertionError(f"no {job} result: {events[-5:]}")


def test_record_a_walk_then_export_it(tmp_path, monkeypatch):
    monkeypatch.setenv("MOTION_STUDIO_MOTIONS", str(tmp_path))
    events: list = []
    core = EngineCore("g1", events.append)
    core.jobs.root = tmp_path
    core.handle(msg.SetMode("test"))
    core.handle(msg.SetVelocityCommand(0.3, 0.0, 0.0))
    core.handle(msg.SetRecording(True, name="walk1", request_id="r1"))
    for _ in range(400):  # 0.8 s
        core.tick()
    core.handle(msg.SetRecording(False, request_id="r1"))
    result = _results(core, events, "record")
    assert result["ok"], result
    assert result["path"] == "runs/walk1.npz" and result["fps"] == 125.0
    sim = load_run_motion(tmp_path / "runs/walk1.npz")
    ref = load_run_motion(tmp_path / "runs/walk1.npz", "reference")
    assert sim.frames == result["frames"] >= 95 and sim.joint_names == list(UNITREE_G1_29)
    assert sim.qpos[-1, 0] > sim.qpos[0, 0]  # it walked forward
    assert ref.qpos.shape == sim.qpos.shape and not np.allclose(ref.qpos, sim.qpos)
    assert not list((tmp_path / "runs").glob(".*"))  # no temporaries left
    core.handle(msg.StartJob("export", {"motion": "runs/walk1.npz", "format": "unitree-csv", "fps": 30}, job_id="e1"))
    exported = _results(core, events, "export")
    assert exported["ok"] and exported["path"] == "exports/g1_walk1_30fps.csv", exported
    rows = np.loadtxt(tmp_path / exported["path"], delimiter=",", ndmin=2)
    assert rows.shape == (exported["frames"], 36) and exported["fps"] == 30.0


def test_stopping_without_walking_reports_nothing_recorded(tmp_path, monkeypatch):
    monkeypatch.setenv("MOTION_STUDIO_MOTIONS", str(tmp_path))
    events: list = []
    core = EngineCore("g1", events.append)
    core.handle(msg.SetRecording(True, request_id="r2"))  # standing: no walker, no frames
    for _ in range(20):
        core.tick()
    core.handle(msg.SetRecording(False, request_id="r2"))
    result = _results(core, events, "record")
    assert not result["ok"] and "nothing was recorded" in result["error"]
    assert not (tmp_path / "runs").exists()
    core.handle(msg.SetRecording(True, name="../escape"))
    notices = [e for e in events if isinstance(e, msg.Notice) and e.level == "error"]
    assert notices and "expected letters" in notices[-1].message and core.recorder is None
