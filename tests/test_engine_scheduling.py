"""The simulation first (engine/scheduling.py): the engine's session takes a lower autogroup niceness where the
kernel and the privileges allow it, and a job thread in the engine a higher niceness of its own."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from engine.jobs import JobRunner
from engine.scheduling import JOB_THREAD_NICENESS, SESSION_NICENESS, prefer_simulation
from tests.conftest import REPO

AUTOGROUP = Path("/proc/self/autogroup")


@pytest.mark.skipif(not AUTOGROUP.exists(), reason="no scheduler autogroups here")
def test_the_engine_session_takes_the_lower_niceness_where_permitted():
    """In a new session (as EngineProcess starts the engine): the autogroup reads the niceness when it was set, and
    is unchanged (0, a new session's) when it was not permitted."""
    code = ("from pathlib import Path; from engine.scheduling import prefer_simulation; "
            "ok = prefer_simulation(); print(ok); print(Path('/proc/self/autogroup').read_text().split()[-1])")
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60,
                         start_new_session=True, check=True).stdout.split()
    set_, nice = out[0] == "True", int(out[1])
    assert nice == (SESSION_NICENESS if set_ else 0)
    if os.geteuid() == 0:
        assert set_, "root may lower a niceness"


def test_without_autogroups_nothing_is_set(tmp_path):
    assert not prefer_simulation(autogroup=tmp_path / "absent" / "autogroup")


@pytest.mark.skipif(not hasattr(os, "setpriority"), reason="no per-thread niceness here")
def test_a_job_thread_runs_at_a_higher_niceness_than_the_engine_loop(tmp_path, monkeypatch):
    import engine.jobs as jobs

    seen: dict[str, int] = {}

    def probe(params, report, cancel):  # noqa: ANN001, ANN202
        seen["job"] = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
        return {}

    monkeypatch.setattr(jobs, "JOBS", (*jobs.JOBS, "probe"))
    loop = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    runner = JobRunner(tmp_path)
    runner._job_probe = probe  # (a job is a method _job_<name>)
    runner.start("probe", {})
    runner.join(30)
    assert [e.message for e in runner.drain()][-1] == "done"
    assert seen["job"] == min(loop + JOB_THREAD_NICENESS, 19)
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == loop
