"""`studio tmr` and `studio retarget-batch` as a user types them: one-line errors with exit 2 and nothing
written; a finished batch resumes by skipping what is done."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from tests.conftest import REPO, run_studio


@pytest.fixture(scope="module")
def clips(tmp_path_factory):  # noqa: ANN201
    from engine.retarget.quadruped.tmr import kinematic_clips
    from engine.robot.model import load_robot

    folder = tmp_path_factory.mktemp("tmr_clips")
    go1 = load_robot("go1")
    kinematic_clips.standing(go1, 0.2).save(folder / "stand.npz")
    kinematic_clips.standing(go1, 0.04).save(folder / "short.npz")
    (folder / "junk.npz").write_bytes(b"not a zip")
    return folder


@pytest.mark.parametrize("extra, expected", [
    (["--alpha-bound", "2.5"], "--alpha-bound: expected a log2 α bound in (0, 2], got 2.5"),
    # each case is a `studio tmr` process: three in the slow tier (the Ray one starts a Ray client)
    pytest.param(["--alpha-bound", "-1"], "--alpha-bound: expected a log2 α bound in (0, 2], got -1", marks=pytest.mark.slow),
    pytest.param(["--segments", "0"], "--segments: expected S ≥ 1, got 0", marks=pytest.mark.slow),
    pytest.param(["--widen-bound", "3"], "--widen-bound: expected a log2 α bound in (0, 2], got 3 (or 0: never widen)",
                 marks=pytest.mark.slow),
    pytest.param(["--alpha-bound", "1.8", "--widen-bound", "1.6"],
                 "--widen-bound: expected a bound above --alpha-bound 1.8 (or 0: never widen), got 1.6",
                 marks=pytest.mark.slow),
    pytest.param(["--address", "127.0.0.1:9"], "--address 127.0.0.1:9: no Ray head answers", marks=pytest.mark.slow),
    (["--robot", "g1"], "--robot: expected a quadruped"),
    (["--robot", "a1"], "stand.npz: robot: expected a motion of a1"),
])
def test_bad_options_exit_2_with_one_line_and_write_nothing(clips, tmp_path, extra, expected) -> None:  # noqa: ANN001
    out_file = tmp_path / "o.npz"
    out = run_studio("tmr", "--motion", str(clips / "stand.npz"), *extra, "--out", str(out_file), timeout=120)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0] and "Traceback" not in out.stderr
    assert not out_file.exists()


@pytest.mark.parametrize("name, extra, expected", [
    ("short.npz", ["--segments", "3"], "short.npz: qpos: expected a clip of at least two frames per segment"),
    ("junk.npz", [], "junk.npz: expected an npz archive (a zip of .npy arrays)"),
    ("missing.npz", [], "missing.npz: file not found"),
])
def test_bad_clips_exit_2_naming_the_file(clips, tmp_path, name, extra, expected) -> None:  # noqa: ANN001
    out = run_studio("tmr", "--motion", str(clips / name), *extra, "--out", str(tmp_path / "o.npz"), timeout=120)
    assert out.returncode == 2 and len(out.stderr.strip().splitlines()) == 1
    assert expected in out.stderr and not (tmp_path / "o.npz").exists()


@pytest.mark.slow  # a whole TMR run in a `studio tmr` process (in process: tests/test_tmr_pipeline.py)
def test_tmr_json_summary_and_output(clips, tmp_path) -> None:  # noqa: ANN001
    out_file = tmp_path / "stand_tmr.npz"
    out = run_studio("tmr", "--motion", str(clips / "stand.npz"), "--robot", "go1", "--budget", "1", "--out",
                     str(out_file), "--json", timeout=300)
    assert out.returncode == 0, out.stderr
    s = json.loads(out.stdout)
    for key in ("alpha", "duration_s", "bo_evaluations", "replay_fell", "dtw_keypoint_l1_pct", "tracking_error_mm",
                "wall_time_s"):
        assert key in s
    assert s["alpha"] == [1.0] and s["bo_evaluations"] == 1 and s["replay_fell"] is False
    assert set(s["duration_s"]) == {"before", "after"}
    assert out_file.is_file() and "evaluation 1/1" in out.stderr


def test_a_killed_tmr_leaves_no_partial_file(clips, tmp_path) -> None:  # noqa: ANN001
    out_file = tmp_path / "killed.npz"
    proc = subprocess.Popen([sys.executable, "-m", "studio", "tmr", "--motion", str(clips / "stand.npz"), "--budget",
                             "50", "--out", str(out_file)], cwd=REPO, stderr=subprocess.PIPE, text=True,
                            env={**os.environ})
    line = proc.stderr.readline()  # the first evaluation's progress line: the job is under way
    assert "evaluation 1/50" in line
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=120) == 130
    assert list(tmp_path.iterdir()) == []


def test_batch_skips_finished_jobs_by_content_hash(clips, tmp_path) -> None:  # noqa: ANN001
    """Resuming: jobs whose result and summary exist under their content hash are not run again (no Ray needed)."""
    from studio.cli_tmr import _settings, job_key  # noqa: PLC2701

    import argparse

    args = argparse.Namespace(segments=1, alpha_bound=1.0, budget=1, parallel=1, mode="receding", seed=0, window=0.25,
                              widen_bound=1.6, widen_budget=2)
    key = job_key(str(clips / "stand.npz"), "go1", _settings(args))
    done = tmp_path / f"stand__go1__{key}.npz"
    done.write_bytes((clips / "stand.npz").read_bytes())
    done.with_suffix(".json").write_text(json.dumps({"clip": "stand.npz", "robot": "go1", "alpha": [1.0]}))
    t0 = time.monotonic()
    out = run_studio("retarget-batch", str(clips / "stand.npz"), "--robots", "go1", "--budget", "1", "--out",
                     str(tmp_path), "--json", timeout=120)
    assert out.returncode == 0, out.stderr
    rows = json.loads(out.stdout)["jobs"]
    assert len(rows) == 1 and rows[0]["status"] == "skipped (done)"
    assert "ray" not in out.stderr.lower()
    del t0


@pytest.mark.slow  # two `studio retarget-batch` runs (TMR jobs)
def test_batch_runs_then_resumes_in_process(clips, tmp_path) -> None:  # noqa: ANN001
    args = [str(clips / "stand.npz"), "--robots", "go1", "--budget", "1", "--jobs", "1", "--out", str(tmp_path), "--json"]
    first = run_studio("retarget-batch", *args, timeout=600)
    assert first.returncode == 0, first.stderr
    assert [r["status"] for r in json.loads(first.stdout)["jobs"]] == ["done"]
    assert "1/1 jobs" in first.stderr
    second = run_studio("retarget-batch", *args, timeout=300)
    assert [r["status"] for r in json.loads(second.stdout)["jobs"]] == ["skipped (done)"]


@pytest.mark.slow
def test_batch_on_ray_runs_then_resumes(clips, tmp_path) -> None:  # noqa: ANN001
    args = [str(clips / "stand.npz"), "gen:standing", "--robots", "go1", "--budget", "1", "--jobs", "2", "--out",
            str(tmp_path), "--json"]
    first = run_studio("retarget-batch", *args, timeout=900)
    assert first.returncode == 0, first.stderr
    rows = json.loads(first.stdout)["jobs"]
    assert [r["status"] for r in rows] == ["done", "done"]
    assert len(list(tmp_path.glob("*.npz"))) == 2 and len(list(tmp_path.glob("*.json"))) == 2
    second = run_studio("retarget-batch", *args, timeout=300)
    assert [r["status"] for r in json.loads(second.stdout)["jobs"]] == ["skipped (done)"] * 2


@pytest.mark.slow  # SMR then TMR in `studio retarget-batch` processes
def test_batch_takes_source_clips_through_smr_then_tmr(tmp_path) -> None:  # noqa: ANN001
    from engine.retarget.motion import RobotMotion
    from engine.retarget.synthetic import synthetic_trot

    src = tmp_path / "kp_trot.npz"
    synthetic_trot(frames=15, fps=30.0).save(src)
    out_dir = tmp_path / "out"
    alone = run_studio("retarget-batch", str(src), "--budget", "1", "--out", str(out_dir), timeout=120)
    assert alone.returncode == 2 and "kp_trot.npz: a source motion needs --robots" in alone.stderr
    res = run_studio("retarget-batch", str(src), "--robots", "go1", "--budget", "1", "--jobs", "1", "--out",
                     str(out_dir), "--json", timeout=600)
    assert res.returncode == 0, res.stderr
    rows = json.loads(res.stdout)["jobs"]
    assert [r["status"] for r in rows] == ["done"] and rows[0]["robot"] == "go1"
    m = RobotMotion.load(out_dir / rows[0]["file"])
    assert m.method == "stmr" and m.source["kinematic_method"] == "smr" and "pd_targets" in m.extra


@pytest.mark.parametrize("extra, expected", [
    (["--clips", "trot0,nosuch"], "--clips: unknown clip 'nosuch'"),
    (["--clips", ","], "--clips: unknown clip"),
    (["--budget", "0"], "--budget: expected ≥ 1"),
])
def test_bench_tmr_clips_bad_options_exit_2_with_one_line(extra, expected) -> None:  # noqa: ANN001
    out = run_studio("bench", "tmr-clips", *extra, timeout=120)
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0]
