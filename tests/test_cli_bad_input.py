"""`studio check` on malformed files: one line naming the file, field and expectation, exit 2 (issue 14)."""

from __future__ import annotations

import pytest

from tests.conftest import make_disk_full, run_studio


@pytest.mark.parametrize("name, content, expected", [
    ("deep.json", b"[" * 100_000 + b"]" * 100_000, "deep.json: line 1 column 100000: expected at most 64 nested"),
    ("trunc.json", b'{"schema": "motion-studio/sty', "trunc.json: line 1 column 12: expected valid JSON "
                                                     "(unterminated string starting here; the file ends early"),
    ("dup.json", b'{"schema": 1, "schema": 2}', "dup.json: schema: duplicate key 'schema'; expected each key once"),
    ("latin1.json", b'{"name": "caf\xe9"}', "latin1.json: byte 13: expected UTF-8 text, got byte 0xe9"),
    ("empty.json", b"", "empty.json: expected JSON, the file is empty"),
])
def test_check_reports_one_line(tmp_path, name, content, expected):
    (tmp_path / name).write_bytes(content)
    r = run_studio("check", str(tmp_path / name), timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert expected in lines[0], lines[0]


def test_check_missing_file_has_no_empty_field():
    r = run_studio("check", "nope.json", timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip() == "studio: error: nope.json: file not found"


def test_out_in_a_missing_folder_is_refused_before_the_run():
    r = run_studio("plan", "--out", "/nonexistent-folder/x.npz", timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip() == "studio: error: --out: expected a writable file in an existing folder, got " \
                               "'/nonexistent-folder/x.npz'"


def test_a_full_disk_while_writing_the_recording_is_one_line_and_nothing_is_left(tmp_path, monkeypatch, capsys):
    import numpy as np

    import engine.gait.offline_plan as offline_plan
    from studio import cli

    monkeypatch.setattr(offline_plan, "run_plan", lambda *a: {"t": np.zeros(3), "command": np.zeros((3, 3)),
                                                              "command_requested": np.zeros((3, 3))})

    make_disk_full(monkeypatch)
    out = tmp_path / "plan.npz"
    assert cli.main(["plan", "--out", str(out), "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"studio: error: --out: could not write {out}: No space left on device"
    assert list(tmp_path.iterdir()) == []  # no recording, no temporary file


def test_check_rehearse_refuses_a_bad_duration_before_any_walk():
    r = run_studio("check", "styles/g1/neutral.json", "--rehearse", "--duration", "-3", timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip() == "studio: error: --duration: expected 0 < seconds <= 600, got -3.0"


@pytest.mark.slow
def test_check_rehearse_walks_the_style_and_prints_the_verdict():
    r = run_studio("check", "styles/g1/neutral.json", "--rehearse", "--duration", "2", timeout=600)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert len(lines) == 2 and lines[0] == "styles/g1/neutral.json: ok"
    assert lines[1].startswith("styles/g1/neutral.json: rehearsal: walks the 2 s sweep without falling")
