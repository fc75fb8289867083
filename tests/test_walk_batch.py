"""Batches of walks resume from their result files, but never from results another version of
the code made (a controller change must not be hidden behind stale walks)."""

from __future__ import annotations

import json

from engine import walk_batch


def test_a_batch_resumes_only_from_results_of_the_same_code(tmp_path, monkeypatch):
    runs: list[dict] = []

    def fake_run_job(job):
        runs.append(job)
        return {"fell": False, "n": len(runs)}

    monkeypatch.setattr(walk_batch, "run_job", fake_run_job)
    jobs = [{"robot": "g1", "i": 0}, {"robot": "g1", "i": 1}]
    first = walk_batch.run_batch(jobs, tmp_path, local=True)
    assert len(runs) == 2 and len(first) == 2
    again = walk_batch.run_batch(jobs, tmp_path, local=True)
    assert len(runs) == 2 and again == first  # resumed: nothing ran again

    stale = tmp_path / f"{walk_batch.job_key(jobs[0])}.json"
    stored = json.loads(stale.read_text())
    assert stored["code"] == walk_batch.code_version()
    stale.write_text(json.dumps({**stored, "code": "another-version"}))
    walk_batch.run_batch(jobs, tmp_path, local=True)
    assert runs[2:] == [jobs[0]]  # only the stale one ran again
