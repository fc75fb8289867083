"""The simulation first (engine/scheduling.py): the engine's session takes a lower autogroup niceness where the
kernel and the privileges allow it, and only a session leader sets it."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from engine.scheduling import SESSION_NICENESS, autogroup_niceness, prefer_simulation
from tests.conftest import REPO

AUTOGROUP = Path("/proc/self/autogroup")
PROBE = ("from engine.scheduling import autogroup_niceness, prefer_simulation; "
         "ok = prefer_simulation(); print(ok); print(autogroup_niceness())")


def _may_lower_niceness() -> bool:
    """CAP_SYS_NICE (bit 23) among this process's effective capabilities (root in a container may lack it)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("CapEff:"):
            return bool(int(line.split()[1], 16) >> 23 & 1)
    return False


def _probe(new_session: bool) -> tuple[bool, int | None]:
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=REPO, capture_output=True, text=True, timeout=60,
                         start_new_session=new_session, check=True).stdout.split()
    return out[0] == "True", None if out[1] == "None" else int(out[1])


@pytest.mark.skipif(not AUTOGROUP.exists(), reason="no scheduler autogroups here")
def test_the_engine_session_takes_the_lower_niceness_where_permitted():
    """In a new session (as EngineProcess starts the engine): the autogroup reads the niceness when it was set, and
    a new session's 0 when it was not permitted."""
    set_, nice = _probe(new_session=True)
    assert nice == (SESSION_NICENESS if set_ else 0)
    assert set_ == _may_lower_niceness()


@pytest.mark.skipif(not AUTOGROUP.exists(), reason="no scheduler autogroups here")
def test_a_process_that_does_not_lead_its_session_leaves_it_alone():
    """Also where this session is the kernel's default group, whose autogroup file reads empty (a CI container)."""
    before = autogroup_niceness()
    set_, nice = _probe(new_session=False)  # in this test's session
    assert not set_ and nice == before


def test_without_autogroups_nothing_is_set(tmp_path, monkeypatch):
    import engine.scheduling as scheduling

    monkeypatch.setattr(scheduling.os, "getsid", lambda pid: scheduling.os.getpid())  # as the engine: a leader
    assert not prefer_simulation(autogroup=tmp_path / "absent" / "autogroup")


@pytest.mark.parametrize("text, expected", [("/autogroup-2111 nice 0\n", 0), ("/autogroup-7 nice -5\n", -5),
                                            ("", None), ("\n", None), ("garbage\n", None)])
def test_the_autogroup_file_reads_its_niceness_or_none(tmp_path, text, expected):
    path = tmp_path / "autogroup"
    path.write_text(text)
    assert autogroup_niceness(path) == expected
    assert autogroup_niceness(tmp_path / "absent") is None
