"""Long jobs in the engine process (engine/jobs.py) and the motion library's confinement (engine/motion_files.py)."""

from __future__ import annotations

import os
import re
import time

import numpy as np
import pytest

from engine.jobs import JobRunner
from engine.motion_files import OutsideLibrary, confined, list_files


def run_until_done(runner: JobRunner, job_id: str, timeout_s: float = 300.0, on_progress=None):
    events = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for ev in runner.drain():
            assert ev.job_id == job_id
            events.append(ev)
            if on_progress is not None and ev.result is None:
                on_progress(ev)
            if ev.result is not None:
                return events
        time.sleep(0.02)
    raise AssertionError(f"job {job_id} did not finish: {[e.message for e in events]}")


def test_retarget_job_reports_progress_and_writes_the_result(tmp_path, monkeypatch):
    # No rate limit on progress here: on a fast machine the whole job takes less than one 0.1 s period.
    monkeypatch.setattr("engine.jobs.PROGRESS_PERIOD_S", 0.0)
    runner = JobRunner(tmp_path)
    runner.start("retarget", {"source": "demo:trot", "robot": "go1", "method": "smr", "name": "trot",
                              "uvm_ghost": True}, job_id="r1")
    events = run_until_done(runner, "r1")
    fractions = [e.fraction for e in events]
    assert fractions == sorted(fractions), "progress never goes back"
    assert len(events) >= 3 and fractions[-1] == 1.0 and all(f < 1.0 for f in fractions[:-1])
    result = events[-1].result
    assert result["ok"], result
    assert result["path"] == "go1/trot.npz" and (tmp_path / "go1" / "trot.npz").is_file()
    assert (tmp_path / "go1" / "trot.uvm.npz").is_file()
    assert result["metrics"]["contact_iou"] > 0.9 and result["metrics"]["penetration_mm"] == 0.0
    pb = result["playback"]
    T = pb["frames"]
    assert pb["body_pos"].shape[:1] == (T,) and pb["body_pos"].shape[2] == 3 and pb["body_quat"].shape[2] == 4
    assert pb["source_keypoints"].shape == (T, 16, 3) and pb["contact"].shape == (T, 4)
    assert pb["ghost_pos"].shape == pb["body_pos"].shape
    np.testing.assert_allclose(np.linalg.norm(pb["body_quat"], axis=2), 1.0, atol=1e-5)
    assert not list(tmp_path.rglob("*.tmp")), "no temporary file left behind"

    # export of the result, into exports/
    runner.start("export", {"motion": "go1/trot.npz", "format": "unitree-csv"}, job_id="e1")
    export = run_until_done(runner, "e1")[-1].result
    assert export["ok"] and (tmp_path / export["path"]).is_file() and export["path"].startswith("exports/")
    rows = np.loadtxt(tmp_path / export["path"], delimiter=",")
    assert rows.shape == (T, 7 + 12)

    # poses of an existing motion (what the studio asks to view a file)
    runner.start("poses", {"motion": "go1/trot.npz", "source": "demo:trot", "ghost": "go1/trot.uvm.npz"}, job_id="p1")
    poses = run_until_done(runner, "p1")[-1].result
    assert poses["ok"]
    np.testing.assert_allclose(poses["playback"]["body_pos"], pb["body_pos"], atol=1e-6)


def test_cancel_leaves_no_file(tmp_path):
    runner = JobRunner(tmp_path)
    runner.start("retarget", {"source": "demo:trot", "robot": "a1", "method": "smr", "name": "c"}, job_id="c1")
    events = run_until_done(runner, "c1", on_progress=lambda ev: runner.cancel("c1"))
    result = events[-1].result
    assert not result["ok"] and result["cancelled"], result
    runner.join(30)
    assert not any(p.suffix == ".npz" for p in tmp_path.rglob("*")), list(tmp_path.rglob("*"))
    assert not list(tmp_path.rglob("*.tmp"))


@pytest.mark.parametrize("params, expected", [
    ({"source": "demo:trot", "robot": "g1", "method": "smr"}, "expected a quadruped"),
    ({"source": "demo:trot", "robot": "go1", "method": "magic"}, "method: expected one of"),
    ({"source": "../secrets.npz", "robot": "go1", "method": "smr"}, "'..' is not allowed"),
    ({"source": "/etc/passwd", "robot": "go1", "method": "smr"}, "not an absolute path"),
    ({"source": "source/missing.npz", "robot": "go1", "method": "smr"}, "missing.npz"),
])
def test_bad_parameters_fail_with_one_line_and_write_nothing(tmp_path, params, expected):
    runner = JobRunner(tmp_path)
    runner.start("retarget", params, job_id="b")
    result = run_until_done(runner, "b", 60)[-1].result
    assert not result["ok"] and not result["cancelled"]
    assert expected in result["error"] and "\n" not in result["error"]
    assert not any(p.is_file() for p in tmp_path.rglob("*"))


def test_picker_stays_inside_the_library(tmp_path):
    root = tmp_path / "motions"
    (root / "source").mkdir(parents=True)
    (root / "source" / "a.npz").write_bytes(b"x")
    outside = tmp_path / "outside.npz"
    outside.write_bytes(b"x")
    os.symlink(outside, root / "source" / "link_out.npz")
    os.symlink(tmp_path, root / "dir_out")
    assert confined(root, "source/a.npz") == (root / "source" / "a.npz").resolve()
    for bad in ("../outside.npz", "source/../../outside.npz", str(outside), "/etc/passwd", "source/link_out.npz",
                "dir_out/outside.npz", "~/x.npz", ""):
        with pytest.raises(OutsideLibrary):
            confined(root, bad)
    assert list_files(root) == ["source/a.npz"]
    with pytest.raises(OutsideLibrary):
        list_files(root, "../")


def test_engine_process_runs_a_job_while_it_keeps_publishing_frames(tmp_path, monkeypatch):
    """StartJob over the real studio↔engine pipe: progress, then the result; frames keep coming meanwhile."""
    from engine import protocol as msg
    from engine.process import EngineProcess

    monkeypatch.setenv("MOTION_STUDIO_MOTIONS", str(tmp_path))
    engine = EngineProcess("go1")
    engine.start()
    try:
        engine.send(msg.StartJob("retarget", {"source": "demo:trot", "robot": "go1", "method": "smr", "name": "p"},
                                 job_id="j"))
        progress, frames_during, result = [], 0, None
        deadline = time.monotonic() + 300
        while result is None and time.monotonic() < deadline:
            event = engine.recv(1.0)
            if isinstance(event, msg.JobProgress):
                assert event.job_id == "j"
                progress.append(event.fraction)
                result = event.result
            elif isinstance(event, msg.Frame) and progress:
                frames_during += 1
        assert result is not None and result["ok"], result
        assert (tmp_path / "go1" / "p.npz").is_file()
        assert len(progress) >= 2 and frames_during > 0, (progress, frames_during)
    finally:
        engine.stop()


@pytest.mark.slow
def test_stmr_job_reports_bo_progress_and_writes_the_dynamic_motion(tmp_path):
    runner = JobRunner(tmp_path)
    runner.start("retarget", {"source": "demo:trot", "robot": "go1", "method": "stmr", "name": "d", "budget": 2},
                 job_id="s")
    events = run_until_done(runner, "s", 1200)
    result = events[-1].result
    assert result["ok"], result
    assert any("BO evaluation" in e.message for e in events[:-1])
    # The bar spans the budget and the widened search's evaluations: it never goes back, and no BO evaluation
    # pins it at the end before the result is written
    fractions = [e.fraction for e in events]
    assert fractions == sorted(fractions) and all(f < 1.0 for f in fractions[:-1])
    assert (tmp_path / "go1" / "d.npz").is_file() and (tmp_path / "go1" / "d.smr.npz").is_file()
    assert result["metrics"]["bo_evaluations"] >= 1 and "alpha" in result["metrics"]
    pb = result["playback"]
    assert pb["body_pos"].shape[0] == pb["frames"]
    # the ghost is SMR's motion (re-timed onto the result's frames), the α segments come along
    assert pb["ghost_method"] == "smr" and pb["ghost_pos"].shape == pb["body_pos"].shape
    assert pb["segments"]["alpha"] == pytest.approx(result["metrics"]["alpha"], abs=1e-4)


def _retimed(kinematic, alpha, fps=100.0):
    """A re-timed motion as TMR writes one (α, segment knots; its qpos the kinematic motion at s_α(t))."""
    from engine.retarget.motion import RobotMotion
    from engine.retarget.quadruped.tmr.deformation import TemporalDeformation, interpolate_qpos, sample_contact

    deformation = TemporalDeformation(tuple(alpha), (kinematic.frames - 1) / kinematic.fps)
    t = np.arange(int(np.floor(deformation.duration_s * fps + 1e-9)) + 1) / fps
    qpos = interpolate_qpos(kinematic.qpos, kinematic.fps, deformation(t))
    qpos[:, 2] += 0.01  # "physics": 1 cm off the kinematic motion
    return RobotMotion(fps=fps, qpos=qpos, joint_names=kinematic.joint_names,
                       contact=sample_contact(kinematic.contact, kinematic.fps, deformation(t)), robot=kinematic.robot,
                       method="stmr", extra={"alpha": np.asarray(alpha), "segment_knots_s": deformation.control_knots_s})


def test_playback_of_a_retimed_motion_shows_the_kinematic_ghost_at_the_same_point_of_the_motion():
    from engine.jobs import body_poses, playback_data, retiming
    from engine.retarget.quadruped.tmr.kinematic_clips import trot
    from engine.retarget.synthetic import synthetic_trot
    from engine.robot.model import load_robot

    kinematic = trot(load_robot("go1"), duration_s=1.0, fps=50.0)  # 51 frames
    motion = _retimed(kinematic, [0.5, 2.0])  # the first half twice as fast, the second twice as slow
    source = synthetic_trot(frames=kinematic.frames, fps=kinematic.fps)
    assert retiming(motion).source_duration_s == pytest.approx(1.0)
    pb = playback_data(motion, source, kinematic)
    assert pb["segments"]["alpha"] == [0.5, 2.0]
    assert pb["segments"]["knots_s"] == pytest.approx([0.0, 0.25, 1.25])
    assert pb["segments"]["duration_before_s"] == pytest.approx(1.0)
    assert pb["ghost_method"] == "kinematic" and pb["ghost_pos"].shape == pb["body_pos"].shape
    _, kin_pos, _ = body_poses(kinematic)
    # control time 0.25 s (frame 25) is source time 0.5 s (kinematic frame 25); 1.25 s (frame 125) its end
    for k, f in ((0, 0), (25, 25), (125, 50)):
        np.testing.assert_allclose(pb["ghost_pos"][k], kin_pos[f], atol=1e-5)
        assert pb["source_frame"][k] == f
        np.testing.assert_allclose(pb["body_pos"][k, 0, 2] - pb["ghost_pos"][k, 0, 2], 0.01, atol=1e-6)
    # second segment: 2× slower — control 0.25 + 0.4 s is source 0.5 + 0.2 s (frame 35)
    np.testing.assert_allclose(pb["ghost_pos"][65], kin_pos[35], atol=1e-5)
    assert pb["source_frame"][65] == 35
    # a motion that was not re-timed: no segments, the ghost frame by frame
    plain = playback_data(kinematic, source, kinematic)
    assert "segments" not in plain and plain["source_frame"].tolist() == list(range(kinematic.frames))


def test_alpha_segments_drawn_on_the_timeline():
    from studio.panels.retarget_panel import alpha_bar_html, alpha_marks, segment_at

    segments = {"alpha": [0.5, 1.0, 2.0], "knots_s": [0.0, 0.25, 0.75, 1.75], "duration_before_s": 1.5}
    html = alpha_bar_html(segments, 1.75)
    assert html.count('class="alpha-segment"') == 3
    assert ">α 0.50<" in html and ">α 1.00<" in html and ">α 2.00<" in html
    widths = [float(w) for w in re.findall(r"flex:0 0 ([\d.]+)%", html)]
    assert widths == pytest.approx([100 * 0.25 / 1.75, 100 * 0.5 / 1.75, 100 * 1.0 / 1.75], abs=1e-3)
    assert "0.00 | 0.25 | 0.75 | 1.75 s" in html and "1.50 → 1.75 s" in html
    marks = alpha_marks(segments, fps=100.0, frames=176)
    assert [m.value for m in marks] == pytest.approx([0.0, 25.0, 75.0, 175.0])
    assert [m.label for m in marks] == ["0.00 s", "0.25 s", "0.75 s", "1.75 s"]
    assert segment_at(segments, 0.0) == (0, 0.5) and segment_at(segments, 0.3) == (1, 1.0)
    assert segment_at(segments, 1.75) == (2, 2.0)


def test_contact_strip_and_metrics_text():
    from studio.panels.retarget_panel import contact_strip, metrics_markdown

    src = np.zeros((10, 4), bool)
    src[:5, 0] = True
    res = src.copy()
    res[5:, 1] = True
    text = contact_strip(src, res, frame=5)
    rows = text.split("```")[1].strip("\n").splitlines()
    assert rows[0] == "FL src █████·····" and rows[1] == "FL res █████·····"
    assert rows[3] == "FR res ·····█████" and rows[-1].index("▲") == 7 + 5
    md = metrics_markdown({"contact_iou": 1.0, "replay_fell": False, "duration_s": {"before": 2.0, "after": 1.5}})
    assert "| contact IoU | 1  |" in md and "| replay fell | no  |" in md and "2 → 1.5" in md
