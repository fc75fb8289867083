"""`studio bench retarget`: the kinematic tables, then UVM / SMR / STMR side by side per clip and robot (each
tracked by the same iLQR in MuJoCo and replayed open-loop), with per-stage timing; `--clips`, `--robots` and
`--budget` make a small run, `tmr-clips` is an alias of the comparison."""

from __future__ import annotations

import json

import pytest

from studio.cli import main
from tests.conftest import run_studio
from tests.retarget.shared import shared_file

METHOD_COLUMNS = [f"{m}_{k}" for m in ("uvm", "smr", "stmr") for k in ("fell", "dtw_pct", "track_mm", "duration_s")]
STAGE_COLUMNS = ["uvm_s", "smr_s", "uvm_track_s", "smr_track_s", "tmr_s", "evals"]


def fake_row(clip: str, robot: str) -> dict:
    return {"section": "retarget-methods", "clip": clip, "robot": robot,
            "uvm_fell": False, "uvm_dtw_pct": 6.7, "uvm_track_mm": 41.3, "uvm_duration_s": 1.6,
            "smr_fell": True, "smr_dtw_pct": 5.2, "smr_track_mm": 30.6, "smr_duration_s": 1.6,
            "stmr_fell": False, "stmr_dtw_pct": 3.6, "stmr_track_mm": 20.1, "stmr_duration_s": 0.8,
            "stmr_alpha": "0.500", "stmr_fell_at_s": None, "stmr_dtw_vs_target_pct": 3.5, "stmr_vs_smr_dtw_pct": -30.8,
            "uvm_s": 0.04, "smr_s": 0.06, "uvm_track_s": 19.2, "smr_track_s": 24.4, "tmr_s": 47.0, "evals": 2,
            "smr_track_cpu_s": 6.3, "tmr_cpu_s": 12.1, "tmr_vs_inner_solve_cpu": 1.92, "paper_smr_dtw_pct": "",
            "paper_stmr_dtw_pct": "", "bo_trace": "1.0↓1.5(23.5s) 0.5✓(23.4s)"}


@pytest.fixture
def fake_stages(monkeypatch):
    """The two parts of the section replaced by recorders (the command line's plumbing and its printing)."""
    import engine.bench.retarget as bench

    calls: dict[str, tuple] = {}

    def kinematic(clips, robots, baseless=True):  # noqa: ANN001, ANN202
        calls["kinematic"] = (clips, robots)
        return [{"section": "retarget", "robot": r, "clip": c} for r in robots for c in clips]

    def methods(clips, robots, budget, address=None, **_):  # noqa: ANN001, ANN202
        calls["methods"] = (clips, robots, budget)
        return [fake_row(c, r) for r in robots for c in clips]

    monkeypatch.setattr(bench, "bench_retarget_kinematic", kinematic)
    monkeypatch.setattr(bench, "bench_retarget_methods", methods)
    monkeypatch.setattr(bench, "shared_dir", lambda: bench.Path("/"))
    return calls


def test_bench_retarget_selection_reaches_both_parts_and_prints_methods_side_by_side(fake_stages, capsys) -> None:  # noqa: ANN001
    assert main(["bench", "retarget", "--clips", "trot0,pace1", "--robots", "go1", "--budget", "2"]) == 0
    out = capsys.readouterr().out
    assert fake_stages["kinematic"] == (("trot0", "pace1"), ("go1",))
    assert fake_stages["methods"] == (("trot0", "pace1"), ("go1",), 2)
    table = out.split("[retarget-methods]\n", 1)[1].strip().splitlines()
    head = [c.strip() for c in table[0].strip("|").split("|")]
    assert head[:5] == ["clip", "robot", "UVM: fell / DTW % / mm / s", "SMR: fell / DTW % / mm / s",
                        "STMR: fell / DTW % / mm / s"]
    assert head[7].startswith("wall s: UVM / SMR / UVM track / SMR track / TMR")
    assert set(table[1]) <= set("|-") and len(table) == 4  # header, rule, one row per clip × robot
    cells = [c.strip() for c in table[2].strip("|").split("|")]
    assert cells[:5] == ["trot0", "go1", "no / 6.7 / 41.3 / 1.6", "**yes** / 5.2 / 30.6 / 1.6", "no / 3.6 / 20.1 / 0.8"]
    assert cells[5:8] == ["0.500", "-31 %", "0.04 / 0.06 / 19.2 / 24.4 / 47 (2)"]
    # the default comparison robots (go1, a1, anymal_c) and budget (6); --kinematic leaves the comparison out
    assert main(["bench", "retarget", "--clips", "trot0"]) == 0
    assert fake_stages["methods"] == (("trot0",), ("go1", "a1", "anymal_c"), 6)
    fake_stages.clear()
    capsys.readouterr()
    assert main(["bench", "retarget", "--kinematic"]) == 0
    assert "methods" not in fake_stages and "[retarget-methods]" not in capsys.readouterr().out


@pytest.mark.parametrize("extra, expected", [
    (["--robots", "go1,nosuch"], "--robots: unknown robot 'nosuch'"),
    (["--clips", "walk"], "--clips: unknown clip 'walk'"),
    (["--budget", "0"], "--budget: expected ≥ 1"),
])
def test_bench_retarget_bad_selection_is_one_line_exit_2(extra, expected, capsys) -> None:  # noqa: ANN001
    assert main(["bench", "retarget", *extra]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0]


@pytest.mark.slow  # 40-70 s here (two inner solves and a one-evaluation TMR on a 1.6 s clip)
def test_bench_retarget_tiny_run_has_uvm_smr_stmr_side_by_side() -> None:
    shared_file("stmr_rl", "datasets", "trot0", "trot0_keypoints.npz")
    out = run_studio("bench", "retarget", "--clips", "trot0", "--robots", "go1", "--budget", "1", "--json",
                     timeout=900)
    assert out.returncode == 0, out.stderr
    rows = json.loads(out.stdout)["rows"]
    assert {r["section"] for r in rows} == {"retarget", "retarget-contacts", "retarget-baseless", "retarget-methods"}
    (row,) = [r for r in rows if r["section"] == "retarget-methods"]
    assert (row["clip"], row["robot"]) == ("trot0", "go1")
    keys = list(row)
    assert keys[3:3 + len(METHOD_COLUMNS)] == METHOD_COLUMNS  # the three methods side by side, in this order
    for m in ("uvm", "smr", "stmr"):
        assert isinstance(row[f"{m}_fell"], bool)
        assert row[f"{m}_dtw_pct"] > 0 and row[f"{m}_track_mm"] > 0
    assert row["uvm_duration_s"] == row["smr_duration_s"] == pytest.approx(1.6)
    # a budget of 1 evaluates α = 1 only: STMR is SMR's motion tracked by the same (deterministic) solve
    assert row["evals"] == 1 and row["stmr_alpha"] == "1.000"
    assert row["stmr_duration_s"] == pytest.approx(row["smr_duration_s"], abs=0.011)
    assert row["stmr_dtw_pct"] == row["smr_dtw_pct"] and row["stmr_fell"] == row["smr_fell"]
    for key in STAGE_COLUMNS:
        assert row[key] > 0, key
    assert row["tmr_cpu_s"] > 0 and row["bo_trace"].startswith("1.0")
