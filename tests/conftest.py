"""Shared fixtures: robot models, free ports, a served studio."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
ARTIFACTS = REPO / "artifacts"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for_port(port: int, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.2)
    raise TimeoutError(f"nothing listens on port {port}")


def make_disk_full(monkeypatch, partial_write: bool = False) -> None:
    """Every file written through engine.atomic_io fails with ENOSPC (after writing half of the
    first chunk when ``partial_write``): a full disk, simulated. ``monkeypatch.undo()`` frees it."""
    import errno

    import engine.atomic_io as atomic_io

    real_fdopen = os.fdopen

    class FullFile:
        def __init__(self, f):
            self.f = f

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.f.close()

        def write(self, data):
            if partial_write:
                self.f.write(data[: len(data) // 2])  # part of it lands, then the disk is full
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        def __getattr__(self, name):
            return getattr(self.f, name)

    monkeypatch.setattr(atomic_io.os, "fdopen", lambda fd, mode="r", *a, **k: FullFile(real_fdopen(fd, mode, *a, **k)))


@pytest.fixture(scope="session")
def artifacts() -> Path:
    ARTIFACTS.mkdir(exist_ok=True)
    return ARTIFACTS


def run_studio(*args: str, timeout: float = 600, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "studio", *args], capture_output=True, text=True, timeout=timeout,
                          cwd=REPO, env={**os.environ, **(env or {})})


class ServedStudio:
    def __init__(self, robot: str = "g1"):
        self.port = free_port()
        self.proc = subprocess.Popen([sys.executable, "-m", "studio", "serve", "--robot", robot, "--port", str(self.port),
                                      "--no-rehearse-after-edits"],
                                     cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        wait_for_port(self.port)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def engine_pids(self) -> list[int]:
        out = subprocess.run(["pgrep", "-P", str(self.proc.pid)], capture_output=True, text=True)
        pids = []
        for pid in map(int, out.stdout.split()):
            try:
                cmdline = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if b"engine" in cmdline:
                pids.append(pid)
        return pids

    def stop(self) -> None:
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(5)


@pytest.fixture
def served_studio():
    studio = ServedStudio()
    yield studio
    studio.stop()


# Property tests: reproducible in CI (same examples every run), exploratory elsewhere.
from hypothesis import settings as _hyp_settings  # noqa: E402

_hyp_settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    _hyp_settings.load_profile("ci")


# The fast tier (`make test-fast`: -m "not slow and not e2e") leaves out these long tests too. They were
# the slowest of the tier (30 s to 4.5 min each on this 2-core machine under load, `--durations`); marked
# here rather than in their files, which other branches are editing (move the marker there later).
SLOW_TESTS = (
    "tests/gait/test_planner.py::test_reference_is_c1_while_the_command_changes_smoothly",
    "tests/control/test_engine_modes.py::",
    "tests/gait/test_plan_cli.py::test_sweep_plan_has_the_documented_fields_and_properties",
    "tests/test_robot_models.py::test_disk_cache_reproduces_a_fresh_build",
    "tests/test_com_mpc.py::test_propagate_lip_matches_rk4",
    "tests/gait/test_planner.py::test_flat_feet_do_not_move_and_soles_stay_above_ground",
    "tests/test_cli.py::test_bench_sim_json",
    "tests/gait/test_plan_cli.py::test_neutral_reaches_the_animators_speeds",  # shares the sweep-plan fixture
    "tests/gait/test_planner.py::test_swing_feet_land_exactly_on_their_footholds_and_stay",
    "tests/gait/test_planner.py::test_contact_events_follow_the_walk_cycle",
)


def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.nodeid.startswith(SLOW_TESTS):
            item.add_marker(pytest.mark.slow)
