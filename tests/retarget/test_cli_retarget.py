"""studio import / retarget / export: the happy path, and bad input → one line naming the file, exit 2, nothing written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from engine.retarget.synthetic import synthetic_trot
from studio.cli import main
from tests.conftest import run_studio
from tests.retarget.shared import shared_file


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def frames_file(path, frames, duration=0.05):
    path.write_text(json.dumps({"LoopMode": "Wrap", "FrameDuration": duration, "EnableCycleOffsetPosition": True,
                                "EnableCycleOffsetRotation": True, "Frames": frames}))
    return path


def good_frame(x=0.0):
    return [x, 0, 0.3, 0, 0, 0, 1] + [0.0, 0.8, -1.6] * 4


def assert_one_line_error(code, err, *needles):
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    for n in needles:
        assert n in lines[0], lines[0]


@pytest.mark.slow  # import, retarget and export: three `studio` processes doing a whole run
def test_import_retarget_export_happy_path(tmp_path):
    src = synthetic_trot("a1", frames=30)
    src.save(tmp_path / "src.npz")
    out = run_studio("retarget", "--source", str(tmp_path / "src.npz"), "--robot", "go1", "--method", "smr",
                     "--terrain", "box:0.3,0,0.2,0.6,0.03", "--out", str(tmp_path / "go1.npz"), "--json")
    assert out.returncode == 0, out.stderr
    figures = json.loads(out.stdout)
    for key in ("frames", "fps", "foot_slide_mm", "contact_iou", "penetration_mm", "keypoint_error_mm", "frames_per_s", "wall_time_s"):
        assert key in figures
    assert figures["penetration_mm"] == 0.0 and figures["contact_iou"] > 0.99
    out = run_studio("export", str(tmp_path / "go1.npz"), "--format", "amp-json", "--amp-full", "--out", str(tmp_path / "go1.json"))
    assert out.returncode == 0, out.stderr
    assert len(json.loads((tmp_path / "go1.json").read_text())["Frames"][0]) == 61


def test_import_frames_file(tmp_path, capsys):
    src = frames_file(tmp_path / "clip.txt", [good_frame(0.01 * i) for i in range(10)])
    code, out, err = run(capsys, "import", str(src), "--out", str(tmp_path / "clip.npz"))
    assert code == 0, err
    assert (tmp_path / "clip.npz").is_file() and "10 frames" in out


@pytest.mark.parametrize("case", ["truncated", "non_numeric", "short_row", "zero_length", "unknown", "nan_keypoints", "missing"])
def test_bad_sources_exit_2_and_write_nothing(tmp_path, capsys, case):
    if case == "truncated":
        src = frames_file(tmp_path / "clip.txt", [good_frame(), good_frame()])
        src.write_text(src.read_text()[:-40])
        needles = ("clip.txt", "expected valid JSON", "truncated?")
    elif case == "non_numeric":
        row = good_frame()
        row[9] = "abc"
        src = frames_file(tmp_path / "clip.txt", [good_frame(), row])
        needles = ("clip.txt", "Frames[1][9]", "expected a number, got 'abc'")
    elif case == "short_row":
        src = frames_file(tmp_path / "clip.txt", [good_frame(), good_frame()[:15]])
        needles = ("clip.txt", "Frames[1]", "expected 19 numbers")
    elif case == "zero_length":
        src = frames_file(tmp_path / "clip.txt", [])
        needles = ("clip.txt", "Frames", "at least 2 frames")
    elif case == "unknown":
        src = tmp_path / "clip.dat"
        src.write_text("hello world\n1 2 3\n")
        needles = ("clip.dat", "unknown format")
    elif case == "nan_keypoints":
        m = synthetic_trot("a1", frames=10)
        arrays = {"format": np.array("keypoint-motion/1"), "fps": np.array(30.0), "keypoints": m.keypoints.copy(),
                  "contact": m.contact}
        arrays["keypoints"][4, 7, 2] = np.nan
        src = tmp_path / "clip.npz"
        np.savez(src, **arrays)
        needles = ("clip.npz", "keypoints", "finite")
    else:
        src = tmp_path / "nothing.txt"
        needles = ("nothing.txt", "not found")
    for argv in (["import", str(src), "--out", str(tmp_path / "out.npz")],
                 ["retarget", "--source", str(src), "--robot", "go1", "--out", str(tmp_path / "out.npz")]):
        code, _, err = run(capsys, *argv)
        assert_one_line_error(code, err, *needles)
        assert not (tmp_path / "out.npz").exists()


def test_biped_target_is_refused(tmp_path, capsys):
    synthetic_trot("a1", frames=10).save(tmp_path / "src.npz")
    code, _, err = run(capsys, "retarget", "--source", str(tmp_path / "src.npz"), "--robot", "g1", "--out", str(tmp_path / "o.npz"))
    assert_one_line_error(code, err, "--robot g1", "expected a quadruped", "biped")
    code, _, err = run(capsys, "retarget", "--source", str(tmp_path / "src.npz"), "--robot", "go1", "--method", "tmr2", "--out", str(tmp_path / "o.npz"))
    assert_one_line_error(code, err, "--method", "uvm, smr")
    code, _, err = run(capsys, "retarget", "--source", str(tmp_path / "src.npz"), "--robot", "go1", "--terrain", "box:1,2", "--out", str(tmp_path / "o.npz"))
    assert_one_line_error(code, err, "--terrain", "box:x,y,w,d,h")
    assert not (tmp_path / "o.npz").exists()


def test_export_rejects_a_keypoint_motion(tmp_path, capsys):
    synthetic_trot("a1", frames=10).save(tmp_path / "src.npz")
    code, _, err = run(capsys, "export", str(tmp_path / "src.npz"), "--format", "unitree-csv", "--out", str(tmp_path / "o.csv"))
    assert_one_line_error(code, err, "src.npz", "format", "robot-motion/1")
    assert not (tmp_path / "o.csv").exists()


def test_import_stmr_clip_reports_contacts_from_the_json(tmp_path, capsys):
    src = shared_file("stmr_rl", "datasets", "pace0", "pace0_keypoints.npz")
    code, out, err = run(capsys, "import", str(src), "--out", str(tmp_path / "pace0.npz"))
    assert code == 0, err
    assert "pace0_contact.json" in out
