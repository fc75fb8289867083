"""`studio retarget --method stmr` as a user types it: SMR then TMR, the JSON adds the TMR figures to SMR's, the
file is the dynamic motion (qpos, qvel, ctrl torques, PD targets); bad TMR input is one line, exit 2, nothing
written, and it is caught before any retargeting work."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.conftest import run_studio


@pytest.fixture(scope="module")
def source(tmp_path_factory):  # noqa: ANN201
    from engine.retarget.synthetic import synthetic_trot

    folder = tmp_path_factory.mktemp("stmr_src")
    synthetic_trot(frames=24, fps=30.0).save(folder / "trot.npz")  # 0.8 s
    return folder / "trot.npz"


@pytest.mark.slow  # a whole STMR retarget in a `studio retarget` process
def test_stmr_json_has_smr_and_tmr_figures_and_writes_the_dynamic_motion(source, tmp_path) -> None:  # noqa: ANN001
    from engine.retarget.motion import RobotMotion

    out_file = tmp_path / "trot_go1_stmr.npz"
    out = run_studio("retarget", "--source", str(source), "--robot", "go1", "--method", "stmr", "--budget", "1",
                     "--out", str(out_file), "--json", timeout=600)
    assert out.returncode == 0, out.stderr
    s = json.loads(out.stdout)
    # SMR's figures …
    for key in ("foot_slide_mm", "contact_iou", "penetration_mm", "keypoint_error_mm", "frames"):
        assert key in s
    # … and TMR's
    assert s["method"] == "stmr" and s["alpha"] == [1.0] and s["bo_evaluations"] == 1
    assert set(s["duration_s"]) == {"before", "after"}
    assert s["duration_s"]["after"] == pytest.approx(s["duration_s"]["before"], abs=0.011)
    assert isinstance(s["replay_fell"], bool)
    assert s["tracking_error_mm"] > 0 and s["dtw_keypoint_l1_pct"] is not None
    assert "evaluation 1/1" in out.stderr
    m = RobotMotion.load(out_file)
    assert m.method == "stmr" and m.robot == "go1" and m.fps == pytest.approx(100.0)
    assert m.qvel.shape == (m.frames, 18) and m.ctrl.shape == (m.frames, 12)
    kp, kd, pd = m.extra["pd_kp"], m.extra["pd_kd"], m.extra["pd_targets"]
    np.testing.assert_allclose(kp * (pd - m.qpos[:, 7:]) - kd * m.qvel[:, 6:], m.ctrl, atol=1e-8)
    assert m.extra["alpha"].tolist() == [1.0] and len(m.extra["segment_knots_s"]) == 2
    assert m.metrics["alpha"] == [1.0] and m.metrics["replay_fell"] == s["replay_fell"]


@pytest.mark.parametrize("extra, expected", [
    (["--alpha-bound", "2.5"], "--alpha-bound: expected a log2 α bound in (0, 2], got 2.5"),
    # each case is a `studio retarget` process: three in the slow tier (the Ray one starts a Ray client)
    pytest.param(["--segments", "0"], "--segments: expected S ≥ 1, got 0", marks=pytest.mark.slow),
    (["--segments", "13"], "trot.npz: keypoints: expected a clip of at least two frames per segment"),
    pytest.param(["--address", "127.0.0.1:9"], "--address 127.0.0.1:9: no Ray head answers", marks=pytest.mark.slow),
    pytest.param(["--budget", "0"], "--budget: expected 1..1000 evaluations, got 0", marks=pytest.mark.slow),
])
def test_bad_stmr_options_exit_2_with_one_line(source, tmp_path, extra, expected) -> None:  # noqa: ANN001
    out_file = tmp_path / "o.npz"
    out = run_studio("retarget", "--source", str(source), "--robot", "go1", "--method", "stmr", *extra,
                     "--out", str(out_file), timeout=120)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and "Traceback" not in out.stderr
    assert not out_file.exists()


def test_unknown_method_names_stmr_among_the_choices(source, tmp_path) -> None:  # noqa: ANN001
    out = run_studio("retarget", "--source", str(source), "--robot", "go1", "--method", "tmr",
                     "--out", str(tmp_path / "o.npz"), timeout=120)
    assert out.returncode == 2 and "expected one of uvm, smr, stmr" in out.stderr
