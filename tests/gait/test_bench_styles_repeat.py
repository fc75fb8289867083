"""`studio bench styles --repeat K`: each style walked K times, the k-th after a nudge while standing."""

from __future__ import annotations

import numpy as np
import pytest

from engine.bench.styles import nudge_push, repeated_jobs, totals
from engine.walk_batch import job_key
from engine.walk_runner import NUDGE_AT_S


def test_the_first_walk_is_the_bench_walk_and_each_other_one_is_nudged_once_differently():
    job = {"robot": "g1", "style": {"name": "x"}, "command": "sweep", "duration_s": 60.0}
    jobs = repeated_jobs(job, 5)
    assert jobs[0] is job and "pushes" not in jobs[0]  # the same key: results of a run without --repeat are reused
    keys = {job_key(j) for j in jobs}
    assert len(keys) == 5
    for k, j in enumerate(jobs[1:], start=1):
        (t, fx, fy, fz, duration), = j["pushes"]
        assert [t, fx, fy, fz, duration] == nudge_push(k, 5)
        assert t == NUDGE_AT_S < 1.0  # the sweep stands still until 1 s
        assert np.hypot(fx, fy) == pytest.approx(1.0, abs=1e-5) and fz == 0.0 and duration == 0.01
    assert repeated_jobs(job, 1) == [job]


def test_a_nudge_is_physically_nothing_but_the_walk_takes_another_path():
    from engine.gait.command_schedule import parse_command
    from engine.gait.style import StyleContext, load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.walk_runner import PushSpec, run_walk

    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json", StyleContext.for_robot("g1"))
    schedule = parse_command("sweep", style.velocities)
    walks = [run_walk(robot, style, schedule, 2.5, pushes, record=True)[1] for pushes in ((), (PushSpec.nudge(1, 3),))]
    com = [w["com"][-1] for w in walks]
    gap = float(np.linalg.norm(np.asarray(com[0]) - np.asarray(com[1])))
    assert 0.0 < gap < 0.005  # not the same walk, but within millimetres of it


def test_the_totals_count_the_styles_that_walk_every_time_never_and_sometimes():
    rows = [{"fell": False, "slip_mm": 3.0, "cop_in": 1.0, "flagged": False, "falls": "0/3"},
            {"fell": True, "slip_mm": 3.0, "cop_in": 1.0, "flagged": False, "falls": "3/3"},
            {"fell": False, "slip_mm": 1.0, "cop_in": 1.0, "flagged": False, "falls": "1/3"}]
    row = totals(rows, "g1", 0)
    assert row["fell"] == "walked 2/3"
    assert row["falls"] == "walks: 5/9; styles that walk every time 1, never 1, sometimes 1"
    assert "falls" not in totals([{k: v for k, v in r.items() if k != "falls"} for r in rows], "g1", 0)


def test_the_totals_count_how_the_falls_began():
    from engine.bench.styles import fall_anatomy, onset_counts

    fell = {"fell": True, "fall_sample": "left_strafe", "fall_phase_pct": 54.3, "fall_onset_s": 17.39,
            "fall_onset": "slide"}
    assert fall_anatomy(fell) == {"fell_in": "left_strafe 54%", "onset": "slide", "onset_s": 17.4}
    assert fall_anatomy({**fell, "fall_onset": None, "fall_onset_s": None})["onset"] == "unseen"
    empty = {"fell_in": "", "onset": "", "onset_s": None}
    assert fall_anatomy({"fell": False}) == empty and fall_anatomy({"fell": True}) == empty  # (a result stored before)
    assert onset_counts(["behind", "slide", "slide", "across"]) == "slide 2, across 1, behind 1"
    rows = [{"fell": True, "slip_mm": 3.0, "cop_in": 1.0, "flagged": False, "onset": "slide"},
            {"fell": True, "slip_mm": 3.0, "cop_in": 1.0, "flagged": False, "onset": "behind"},
            {"fell": False, "slip_mm": 1.0, "cop_in": 1.0, "flagged": False, "onset": ""}]
    assert totals(rows, "g1", 0)["onset"] == "falls began: behind 1, slide 1"
    # With --repeat: every fallen walk of every style ("?": a result stored before the anatomy, not counted).
    rows[0]["onset_runs"], rows[1]["onset_runs"], rows[2]["onset_runs"] = "slide,-,slide", "behind,behind,?", "-,-,-"
    assert totals(rows, "g1", 0)["onset"] == "falls began: behind 2, slide 2"  # (ties alphabetical)


def test_a_falling_walk_of_the_batch_says_where_and_how_it_began(monkeypatch):
    """tests/data/stumbly_g1.json fell 2.0 s into the sweep before G1's recovery counted the body outside its double
    support (robots/g1.toml ``recovery_support_outside_m``): with that signal off it still does, and the batch says
    where and how the fall began; with it on (G1 as shipped) it walks."""
    import dataclasses
    import json

    from engine.control.walking_parameters import WalkingParameters
    from engine.gait.rehearsal import ONSET_KINDS
    from engine.walk_batch import run_job
    from tests.conftest import REPO

    style = json.loads((REPO / "tests" / "data" / "stumbly_g1.json").read_text())
    shipped = run_job({"robot": "g1", "style": style, "command": "sweep", "duration_s": 4.0})
    assert "error" not in shipped and not shipped["fell"] and shipped["recovery_mean_share"] > 0.0
    for_robot = WalkingParameters.for_robot
    monkeypatch.setattr(WalkingParameters, "for_robot", classmethod(
        lambda cls, name: dataclasses.replace(for_robot(name), recovery_support_outside_m=float("inf"))))
    result = run_job({"robot": "g1", "style": style, "command": "sweep", "duration_s": 2.5})
    assert result["fell"] and result["fall_time_s"] < 2.5
    assert result["fall_sample"] == "forward_slow" and 0.0 <= result["fall_phase_pct"] < 100.0
    # Its body never gets 3 cm off a plan re-solved from it every tick, nor a sole in stance 1 cm off; what comes
    # first is a double support on both toes with the body behind them (from 1.30 s, 0.33 s long), which the
    # CoP on the toes pushes further back: the onset is "edges".
    assert result["fall_onset"] == "edges" and "edges" in ONSET_KINDS
    assert 1.2 <= result["fall_onset_s"] <= 1.4 < result["fall_time_s"]
    walked = run_job({"robot": "g1", "style": style, "command": "sweep", "duration_s": 1.0})
    assert not walked["fell"] and "fall_onset" not in walked
