"""tools/tmr_clips_table.py: two `studio bench tmr-clips --json` runs side by side (STMR before → after)."""

from __future__ import annotations

import json

from tests.retarget.test_bench_retarget import fake_row
from tools.tmr_clips_table import main


def test_before_and_after_rows_side_by_side(tmp_path, capsys) -> None:  # noqa: ANN001
    before = [fake_row("hopturn", "go1"), {"section": "retarget", "robot": "go1", "clip": "hopturn"}]
    after = [{**fake_row("hopturn", "go1"), "stmr_fell": True, "stmr_fell_at_s": 1.74, "stmr_alpha": "0.587",
              "evals": 6}, fake_row("sidesteps", "go1")]
    (tmp_path / "b.json").write_text(json.dumps({"rows": before}))
    (tmp_path / "a.json").write_text("noise\n" + json.dumps({"rows": after}))
    assert main([str(tmp_path / "b.json"), str(tmp_path / "a.json")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 4  # head, rule, hopturn (both runs), sidesteps (after only)
    hop, side = lines[2], lines[3]
    assert hop.startswith("| hopturn | go1 | **yes** / 5.2 | 0.500 |")
    assert "| 0.587 |" in hop and "**yes** (at 1.74 s)" in hop and "| 6: 47 / 12.1 |" in hop
    assert side.startswith("| sidesteps | go1 | **yes** / 5.2 | – |")
    assert all(line.count("|") == lines[0].count("|") for line in lines)


def test_a_missing_file_is_one_line_exit_2(tmp_path, capsys) -> None:  # noqa: ANN001
    assert main([str(tmp_path / "nope.json"), str(tmp_path / "nope.json")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
