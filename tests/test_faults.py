"""Faults (issue 14): a killed engine, a killed save, a terminated server, a full disk.

The studio says what happened, keeps or offers the edits, and no saved file is ever half-written.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from engine.gait.style import StyleContext, load_style
from studio.style_session import StyleSession
from tests.conftest import REPO, make_disk_full

NEUTRAL = REPO / "styles" / "g1" / "neutral.json"


@pytest.fixture(scope="module")
def g1_ctx() -> StyleContext:
    return StyleContext.for_robot("g1")


def _session(ctx, folder: Path) -> StyleSession:
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(NEUTRAL, folder / "neutral.json")
    session = StyleSession("g1", ctx, folder=folder)
    assert session.open("neutral").ok
    return session


def _edit(session: StyleSession, width: float) -> bool:
    from dataclasses import replace

    sample = session.style.samples["in_place"]
    edited = replace(sample, attributes=replace(sample.attributes, stance_width_m=width))
    return session.apply(session.style.with_sample("in_place", edited), f"width {width}").ok


def _whole_styles(folder: Path, ctx) -> list[str]:
    """Every visible style file loads completely (temporaries are hidden dot-files)."""
    names = []
    for p in sorted(folder.glob("*.json")):
        load_style(p, ctx, expected_robot="g1")
        names.append(p.name)
    return names


# ----------------------------------------------------------------------------- kill -9 during a save

_SAVER = textwrap.dedent("""
    import sys, json
    from engine.atomic_io import atomic_write_text
    target, text = sys.argv[1], open(sys.argv[2]).read()
    doc = json.loads(text)
    i = 0
    print("ready", flush=True)
    while True:  # rewrite the style as fast as possible, each time a little different (and padded: slow writes)
        i += 1
        doc["description"] = f"save {i} " + "x" * 200_000
        atomic_write_text(target, json.dumps(doc))
""")


def test_kill_9_during_saves_never_leaves_a_half_written_style(tmp_path, g1_ctx):
    target = tmp_path / "neutral.json"
    shutil.copy(NEUTRAL, target)
    script = tmp_path / "saver.py"
    script.write_text(_SAVER)
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    for delay_s in (0.05, 0.13, 0.31, 0.5, 0.77):
        proc = subprocess.Popen([sys.executable, str(script), str(target), str(NEUTRAL)], stdout=subprocess.PIPE,
                                text=True, env=env)
        assert proc.stdout.readline().strip() == "ready"
        time.sleep(delay_s)  # a random moment inside the write loop (the kill time, not a wait for a result)
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
        style = load_style(target, g1_ctx, expected_robot="g1")  # complete: the old or a new version
        assert style.description.startswith(("save ", "The nominal"))
    assert _whole_styles(tmp_path, g1_ctx) == ["neutral.json"]


# ----------------------------------------------------------------------------- SIGTERM during autosaves

_EDITOR = textwrap.dedent("""
    import sys
    from dataclasses import replace
    from pathlib import Path
    from studio.style_session import StyleSession
    session = StyleSession("g1", folder=Path(sys.argv[1]))
    assert session.open("neutral").ok
    print("ready", flush=True)
    i = 0
    while True:  # every accepted edit is autosaved
        i += 1
        s = session.style.samples["in_place"]
        # never 0.24 m, neutral's own width: an autosave equal to the saved file offers nothing to recover
        e = replace(s, attributes=replace(s.attributes, stance_width_m=0.221 + 0.004 * (i % 10)))
        session.apply(session.style.with_sample("in_place", e), "edit")
""")


def test_sigterm_during_autosaves_leaves_a_recoverable_file(tmp_path, g1_ctx):
    folder = tmp_path / "g1"
    folder.mkdir()
    shutil.copy(NEUTRAL, folder / "neutral.json")
    script = tmp_path / "editor.py"
    script.write_text(_EDITOR)
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, str(script), str(folder)], stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert proc.stdout.readline().strip() == "ready"
        rec = folder / ".autosave" / "neutral.json"
        deadline = time.monotonic() + 120
        while not rec.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert rec.exists()
        time.sleep(0.3)  # let a few more autosaves run, then terminate mid-stream
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(10)
    assert (folder / "neutral.json").read_bytes() == NEUTRAL.read_bytes()  # the saved style is untouched
    session = StyleSession("g1", g1_ctx, folder=folder)
    assert session.recovery_available("neutral")  # the studio offers the autosaved edits
    result = session.recover("neutral")
    assert result.ok and session.dirty, result.message
    assert 0.22 <= session.style.samples["in_place"].attributes.stance_width_m <= 0.26


@pytest.mark.slow
def test_serve_stops_cleanly_on_sigterm(tmp_path):
    """SIGTERM to `studio serve`: it shuts its engine down and exits 0 (no orphan, no traceback)."""
    from tests.conftest import ServedStudio

    studio = ServedStudio()
    try:
        deadline = time.monotonic() + 120
        while not studio.engine_pids() and time.monotonic() < deadline:
            time.sleep(0.1)
        engines = studio.engine_pids()
        assert engines
        studio.proc.send_signal(signal.SIGTERM)
        code = studio.proc.wait(30)
        output = studio.proc.stdout.read()
    finally:
        if studio.proc.poll() is None:
            studio.stop()
    tail = output[output.rfind("Motion Studio:"):]
    assert code == 0 and "KeyboardInterrupt" not in tail and "Exception ignored" not in tail, tail[-2000:]
    deadline = time.monotonic() + 10
    while any(Path(f"/proc/{p}").exists() for p in engines) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(Path(f"/proc/{p}").exists() and b"engine" in Path(f"/proc/{p}/cmdline").read_bytes()
                   for p in engines)


# ----------------------------------------------------------------------------- a full disk


def _check_full_disk_behaviour(session: StyleSession, folder: Path, ctx, warnings: list[str]) -> None:
    saved = (folder / "neutral.json").read_bytes()
    assert _edit(session, 0.27)  # the edit is accepted and stays in memory
    assert session.dirty and session.style.samples["in_place"].attributes.stance_width_m == 0.27
    assert warnings and "autosave failed" in warnings[0] and "No space left on device" in warnings[0]
    result = session.save()
    assert not result.ok and "could not save neutral.json: No space left on device" in result.message
    assert "\n" not in result.message and session.dirty
    assert (folder / "neutral.json").read_bytes() == saved  # the old file is whole
    assert not [p for p in folder.rglob("*") if p.name.endswith(".tmp")], "a temporary file was left behind"
    assert _whole_styles(folder, ctx) == ["neutral.json"]


def test_full_disk_simulated(tmp_path, g1_ctx, monkeypatch):
    folder = tmp_path / "g1"
    session = _session(g1_ctx, folder)
    warnings: list[str] = []
    session.warn = warnings.append
    make_disk_full(monkeypatch, partial_write=True)
    _check_full_disk_behaviour(session, folder, g1_ctx, warnings)
    monkeypatch.undo()
    assert session.save().ok and not session.dirty  # space again: the edits were never lost
    assert load_style(folder / "neutral.json", g1_ctx).samples["in_place"].attributes.stance_width_m == 0.27


@pytest.fixture
def tiny_tmpfs(tmp_path):
    mount = tmp_path / "tmpfs"
    mount.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mount)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip() or 'not root'}); the simulated test covers it")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], capture_output=True)


def test_full_disk_on_a_real_tmpfs(tiny_tmpfs, g1_ctx):
    folder = tiny_tmpfs / "g1"
    session = _session(g1_ctx, folder)  # ~15 kB of 64 kB
    filler = tiny_tmpfs / "filler"
    with open(filler, "wb", buffering=0) as f:  # fill the disk
        try:
            while True:
                f.write(b"\0" * 4096)
        except OSError as exc:
            assert exc.errno == errno.ENOSPC
    warnings: list[str] = []
    session.warn = warnings.append
    _check_full_disk_behaviour(session, folder, g1_ctx, warnings)
    filler.unlink()
    assert session.save().ok and not session.dirty
    assert json.loads((folder / "neutral.json").read_text())["samples"]["in_place"]["attributes"][
        "stance_width_m"] == 0.27


# ----------------------------------------------------------------------------- kill -9 of the engine mid-walk


@pytest.mark.slow
def test_kill_9_of_the_engine_during_a_test_mode_walk(tmp_path):
    """The studio says the engine stopped, starts a new one and replays robot, edited style, mode and command."""
    from studio.app import Studio
    from tests.conftest import free_port

    def wait(predicate, timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return
            time.sleep(0.05)
        pytest.fail(f"timed out waiting for {what}")

    styles = tmp_path / "styles"
    (styles / "g1").mkdir(parents=True)
    shutil.copy(NEUTRAL, styles / "g1" / "neutral.json")
    studio = Studio("g1", port=free_port(), styles_folder=styles).start()
    try:
        assert studio.loaded.wait(120)
        assert _edit(studio.session, 0.26)
        studio.set_mode("test")
        wait(lambda: studio.view.last_frame is not None and studio.view.last_frame.mode == "test"
             and studio.view.last_frame.sim_time_s > 1.0, 120, "the robot walking in test mode")
        old_pid = studio.link.pid
        os.kill(old_pid, signal.SIGKILL)
        wait(lambda: studio.link.pid not in (None, old_pid), 60, "a new engine")
        wait(lambda: any("stopped" in text and str(old_pid) in text for _, text in studio.notices), 30,
             "the studio to say the engine stopped")
        wait(lambda: any("Engine restarted" in text for _, text in studio.notices), 30, "the restart notice")
        # the new engine's clock starts again from 0; it runs the replayed mode with the edited style
        wait(lambda: studio.view.last_frame.mode == "test" and studio.view.last_frame.sim_time_s < 5.0, 120,
             "frames of the new engine in test mode")
        assert studio.session.style.samples["in_place"].attributes.stance_width_m == 0.26 and studio.session.dirty
        sticky = studio.link._sticky  # noqa: SLF001 - what the link replays
        assert "set_velocity_command" in sticky and sticky["set_mode"].mode == "test"  # (the drive panel's latest)
        assert sticky["set_style"].style["samples"]["in_place"]["attributes"]["stance_width_m"] == 0.26
        wait(lambda: studio.style_revision > 0 and studio.view.last_frame.style_revision == studio.style_revision,
             60, "the new engine to run the edited style")
    finally:
        studio.stop()


# ----------------------------------------------------------------------------- kill -9 of the engine mid-retarget


@pytest.mark.slow
def test_kill_9_of_the_engine_during_a_retargeting_job(tmp_path, monkeypatch):
    """A retargeting job started in the Retarget workspace dies with its engine: the studio says the engine
    stopped, restarts it, reports the job as lost (Run is enabled again), nothing of the job's output exists —
    no file, no temporary — and the same Run then works on the new engine."""
    from engine.retarget.motion import RobotMotion
    from studio.app import Studio
    from tests.conftest import free_port

    def wait(predicate, timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return
            time.sleep(0.05)
        pytest.fail(f"timed out waiting for {what} (status: {studio.retarget.status.content!r}, "
                    f"notices: {studio.notices[-3:]})")

    motions = tmp_path / "motions"
    (motions / "go2").mkdir(parents=True)
    monkeypatch.setenv("MOTION_STUDIO_MOTIONS", str(motions))  # the studio's panel and its engine's jobs
    studio = Studio("go2", port=free_port(), styles_folder=tmp_path / "styles").start()
    panel = studio.retarget
    try:
        assert studio.loaded.wait(180)
        panel.source.value = "demo:trot"
        panel.method.value = "stmr"  # SMR, then TMR's Bayesian optimisation in MuJoCo: minutes, killed long before
        panel.budget.value = 6
        panel.start_retarget()
        job = panel.job_id
        assert job is not None and panel.run.disabled
        wait(lambda: "TMR: BO evaluation" in panel.status.content, 300, "the job to reach TMR")
        old_pid = studio.link.pid
        os.kill(old_pid, signal.SIGKILL)
        wait(lambda: "Retarget lost" in panel.status.content, 60, "the job reported as lost")
        status = panel.status.content
        assert f"pid {old_pid}" in status and "nothing was written" in status and "Press Run" in status, status
        assert panel.job_id is None and not panel.run.disabled and panel.cancel.disabled
        assert any("stopped" in text and str(old_pid) in text for _, text in studio.notices)
        assert any("Lost with the engine" in text and "retarget job" in text for _, text in studio.notices)
        wait(lambda: studio.link.pid not in (None, old_pid), 60, "a new engine")
        wait(lambda: any("Engine restarted" in text for _, text in studio.notices), 60, "the restart notice")
        assert sorted(p.name for p in (motions / "go2").iterdir()) == []  # no output, no temporary
        assert not any("is a quadruped" in text for _, text in studio.notices)  # the same robot: no hint again
        # the user starts it again (SMR this time: seconds) and the new engine writes the result whole
        panel.method.value = "smr"
        panel.with_ghost.value = False
        panel.start_retarget()
        wait(lambda: "Result:" in panel.status.content or "failed" in panel.status.content, 300, "the new job")
        assert panel.status.content == "Result: `go2/trot_smr.npz` written", panel.status.content
        assert RobotMotion.load(motions / "go2" / "trot_smr.npz").robot == "go2"
        assert [p.name for p in (motions / "go2").iterdir()] == ["trot_smr.npz"]
    finally:
        studio.stop()


def test_a_lost_retarget_job_removes_what_a_cut_write_left(tmp_path):
    """What a kill -9 that lands inside the atomic write leaves (a hidden temporary beside the output; the output
    itself whole or absent) is removed when the studio reports the job as lost; other files stay."""
    import itertools
    from types import SimpleNamespace

    import viser

    from studio.panels.retarget_panel import RetargetPanel
    from tests.conftest import free_port

    sent: list = []
    notes: list = []
    studio = SimpleNamespace(link=SimpleNamespace(send=sent.append), _notify=lambda level, text: notes.append(text))
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    (tmp_path / "go2").mkdir()
    try:
        panel = RetargetPanel(server, studio, root=tmp_path)  # type: ignore[arg-type]
        panel._ids = itertools.count(7)  # noqa: SLF001
        panel.source.value = "demo:trot"
        panel.robot.value = "go2"
        panel.method.value = "smr"
        panel.start_retarget()
        assert sent and sent[0].job == "retarget" and sent[0].params["name"] == "trot_smr"
        cut = tmp_path / "go2" / ".trot_smr.npz.k3j2_x.tmp"  # mkstemp's name for go2/trot_smr.npz
        cut.write_bytes(b"PK\x03\x04 half")
        other = tmp_path / "go2" / "keep.npz"
        other.write_bytes(b"x")
        lost = panel.on_engine_lost(4242)
        assert lost == ["the retarget job"]
        assert not cut.exists() and other.exists()
        assert panel.status.content.startswith("Retarget lost: the engine (pid 4242) stopped during the job; "
                                               "nothing was written.")
        assert panel.job_id is None and not panel.run.disabled
        assert panel.on_engine_lost(4243) == []  # nothing pending any more
        panel.stop()
    finally:
        server.stop()


def test_a_recording_and_an_export_lost_with_the_engine_are_reported(tmp_path):
    """The Record panel's recording lives in the engine's memory, its export runs there: when the engine dies
    the panel says both are lost and lets the user start again (no "Saving…" / "Exporting…" forever)."""
    from types import SimpleNamespace

    import viser

    from studio.panels.record_panel import RecordPanel
    from tests.conftest import free_port

    sent: list = []
    studio = SimpleNamespace(link=SimpleNamespace(send=sent.append), mode="test", view=SimpleNamespace(last_frame=None))
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        panel = RecordPanel(server, studio)  # type: ignore[arg-type]
        assert panel.on_engine_lost(1) == []
        panel.toggle()  # ● Record
        assert panel.recording and sent[-1].kind == "set_recording"
        panel.toggle()  # ■ Stop: the engine is saving it
        assert panel.status.content == "Saving the recording…"
        panel.run_path = "runs/walk.npz"
        panel.start_export()
        assert panel.export.disabled
        assert panel.on_engine_lost(4242) == ["the recording", "the export job"]
        assert panel.status.content.startswith("Recording lost: the engine (pid 4242) stopped")
        assert panel.export_status.content.startswith("Export lost: the engine (pid 4242) stopped")
        assert not panel.recording and panel.record.label == "● Record" and not panel.export.disabled
        assert panel.on_engine_lost(4243) == []
    finally:
        server.stop()


# ----------------------------------------------------------------------------- exports lost with the engine


def _motion_library(root: Path) -> Path:
    """A motion library with a go2 robot motion (``go2/standing.npz``) and a walk run of it (``runs/walk.npz``:
    the same motion, its reference = the simulated take), as the Retarget workspace and the Record panel export."""
    import numpy as np

    from tests.fuzz_corpus import make_corpus as mc

    arrays = mc.valid_robot_npz()
    for folder, name, extra in (("go2", "standing.npz", {}), ("runs", "walk.npz", {"reference_qpos": arrays["qpos"]})):
        (root / folder).mkdir(parents=True, exist_ok=True)
        np.savez(root / folder / name, **arrays, **extra)
    return root


@pytest.mark.parametrize("params", [
    {"motion": "go2/standing.npz", "format": "amp-json"},
    {"motion": "go2/standing.npz", "format": "amp-json", "amp_full": True},
    {"motion": "go2/standing.npz", "format": "unitree-csv"},
    {"motion": "go2/standing.npz", "format": "npz"},
    {"motion": "runs/walk.npz", "format": "unitree-csv", "fps": 30.0, "take": "simulated"},
    {"motion": "runs/walk.npz", "format": "beyondmimic-npz", "fps": 50.0, "take": "reference"},
    {"motion": "runs/walk.npz", "format": "amp-json", "fps": None, "take": "reference"},
], ids=lambda p: "-".join(f"{v}" for v in p.values()))
def test_export_outputs_are_what_the_export_job_writes(tmp_path, params):
    """The panels know an export's output before it starts (engine/jobs.py export_outputs, read from the motion's
    ``robot`` entry): the very file the engine's export job then writes."""
    from engine.jobs import JobRunner, export_outputs

    root = _motion_library(tmp_path)
    outputs = export_outputs(root, params)
    runner = JobRunner(root=root)
    runner.start("export", params, "export-1")
    runner.join(120)
    (result,) = [e.result for e in runner.drain() if e.result is not None]
    assert result["ok"], result
    assert outputs == (result["path"],) and (root / result["path"]).is_file()
    assert sorted(p.name for p in (root / "exports").iterdir()) == [Path(result["path"]).name]


def test_export_outputs_of_bad_parameters_are_empty(tmp_path):
    from engine.jobs import export_outputs

    root = _motion_library(tmp_path)
    (root / "go2" / "junk.npz").write_bytes(b"PK\x03\x04 junk")
    for params in ({"motion": "go2/standing.npz", "format": "gif"}, {"motion": "../x.npz", "format": "npz"},
                   {"motion": "go2/missing.npz", "format": "npz"}, {"motion": "go2/junk.npz", "format": "npz"},
                   {"motion": "go2/standing.npz", "format": "npz", "fps": -1}):
        assert export_outputs(root, params) == (), params


def _planted_temporary(root: Path, output: str) -> Path:
    """What a kill -9 inside the atomic write of ``output`` leaves: mkstemp's hidden temporary beside it."""
    target = root / output
    target.parent.mkdir(parents=True, exist_ok=True)
    cut = target.parent / f".{target.name}.q8w_3z.tmp"
    cut.write_bytes(b"{\"LoopMode\": \"Wr")
    return cut


def test_a_lost_export_job_removes_what_a_cut_write_left(tmp_path):
    """The Retarget workspace's Export and the Record panel's export pass their output up front: when the engine
    dies during the export, the temporary a cut write left is removed, the panel says the export was lost and
    nothing was written, Export is usable again; other files in exports/ stay."""
    import itertools
    from types import SimpleNamespace

    import viser

    from studio.panels.record_panel import RecordPanel
    from studio.panels.retarget_panel import RetargetPanel
    from tests.conftest import free_port

    root = _motion_library(tmp_path)
    sent: list = []
    studio = SimpleNamespace(link=SimpleNamespace(send=sent.append), _notify=lambda level, text: None, mode="test",
                             view=SimpleNamespace(last_frame=None))
    server = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        retarget = RetargetPanel(server, studio, root=root)  # type: ignore[arg-type]
        retarget._ids = itertools.count(3)  # noqa: SLF001
        retarget.result_path = "go2/standing.npz"  # what viewing a result sets
        retarget.export_format.value = "amp-json"
        retarget.start_export()
        assert sent[-1].job == "export" and sent[-1].params["motion"] == "go2/standing.npz"
        cut = _planted_temporary(root, "exports/go2_standing.json")
        other = root / "exports" / "go2_other.json"
        other.write_text("{}")
        assert retarget.on_engine_lost(4242) == ["the export job"]
        assert not cut.exists() and other.exists() and not (root / "exports" / "go2_standing.json").exists()
        assert retarget.export_status.content == ("Export lost: the engine (pid 4242) stopped during the job; "
                                                  "nothing was written. Press Export to start it again.")
        assert retarget.on_engine_lost(4243) == []
        retarget.stop()

        record = RecordPanel(server, studio, root=root)  # type: ignore[arg-type]
        record.run_path = "runs/walk.npz"  # what ■ Stop's saved recording sets
        record.format.value = "unitree-csv"
        record.rate.value = "30 fps"
        record.start_export()
        assert sent[-1].job == "export" and sent[-1].params == {"motion": "runs/walk.npz", "format": "unitree-csv",
                                                                 "fps": 30.0, "take": "simulated"}
        cut = _planted_temporary(root, "exports/go2_walk_30fps.csv")
        assert record.on_engine_lost(4244) == ["the export job"]
        assert not cut.exists() and other.exists() and not record.export.disabled
        assert record.export_status.content == ("Export lost: the engine (pid 4244) stopped during the job; nothing "
                                                "was written. Press Export recording to start it again.")
        # an export whose rename happened before the engine died is complete, and said so
        record.start_export()
        (root / "exports" / "go2_walk_30fps.csv").write_text("0\n")
        assert record.on_engine_lost(4245) == ["the export job"]
        assert "its output `exports/go2_walk_30fps.csv` is complete" in record.export_status.content
    finally:
        server.stop()


def test_the_write_hold_hook_is_off_unless_a_test_sets_it(tmp_path, monkeypatch):
    """engine/atomic_io.py's fault-injection hook: without its variable a write never waits; with it, only files
    matching its pattern do (here for 0 s), and the write completes."""
    from engine import atomic_io

    slept: list[float] = []
    monkeypatch.setattr(atomic_io.time, "sleep", slept.append)
    monkeypatch.delenv(atomic_io.HOLD_WRITES_ENV, raising=False)
    atomic_io.atomic_write_text(tmp_path / "go2_a.json", "a")
    assert slept == []
    monkeypatch.setenv(atomic_io.HOLD_WRITES_ENV, "go2_*.json")
    monkeypatch.setenv(atomic_io.HOLD_SECONDS_ENV, "0")
    atomic_io.atomic_write_text(tmp_path / "other.json", "b")
    atomic_io.atomic_write_text(tmp_path / "go2_b.json", "c")
    assert slept == [0.0] and (tmp_path / "go2_b.json").read_text() == "c"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["go2_a.json", "go2_b.json", "other.json"]


@pytest.mark.slow
def test_kill_9_of_the_engine_inside_an_export_write(tmp_path, monkeypatch):
    """A real kill -9 that lands inside the atomic write of an export (the engine's write held by the test-only
    hook of engine/atomic_io.py after its temporary is written, before the rename): for the Retarget workspace's
    Export and the Record panel's export, the panel says the export was lost and nothing was written, neither the
    output nor a temporary exists, and Export then writes the file whole on the restarted engine."""
    from engine import atomic_io
    from studio.app import Studio
    from tests.conftest import free_port

    def wait(predicate, timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate():
                return
            time.sleep(0.05)
        pytest.fail(f"timed out waiting for {what} (retarget: {studio.retarget.export_status.content!r}, record: "
                    f"{studio.record.export_status.content!r}, notices: {studio.notices[-3:]})")

    root = _motion_library(tmp_path / "motions")
    exports = root / "exports"
    monkeypatch.setenv("MOTION_STUDIO_MOTIONS", str(root))  # the studio's panels and its engine's jobs
    monkeypatch.setenv(atomic_io.HOLD_WRITES_ENV, "go2_*")  # the engine started now holds its export writes
    studio = Studio("go2", port=free_port(), styles_folder=tmp_path / "styles").start()
    retarget, record = studio.retarget, studio.record
    try:
        assert studio.loaded.wait(180)

        def kill_inside_the_write(status, output: str) -> int:
            wait(lambda: exports.is_dir() and any(exports.glob(f".{output}.*.tmp")), 120, f"the write of {output}")
            assert not (exports / output).exists()
            old_pid = studio.link.pid
            os.kill(old_pid, signal.SIGKILL)
            wait(lambda: "Export lost" in status(), 60, "the export reported as lost")
            assert status() == (f"Export lost: the engine (pid {old_pid}) stopped during the job; nothing was written. "
                                f"Press {'Export' if status == retarget_status else 'Export recording'} to start it "
                                "again."), status()
            assert list(exports.iterdir()) == []  # no output, no temporary
            wait(lambda: studio.link.pid not in (None, old_pid), 60, "a new engine")
            return old_pid

        def retarget_status() -> str:
            return retarget.export_status.content

        def record_status() -> str:
            return record.export_status.content

        retarget.view_result("go2/standing.npz")
        wait(lambda: not retarget.export_button.disabled, 180, "the result on view")
        retarget.export_format.value = "amp-json"
        retarget.start_export()
        first = kill_inside_the_write(retarget_status, "go2_standing.json")
        assert any("Lost with the engine" in text and "export job" in text and str(first) in text
                   for _, text in studio.notices)

        record.run_path = "runs/walk.npz"  # a saved recording (■ Stop)
        record.export.disabled = False
        record.format.value = "unitree-csv"
        record.rate.value = "30 fps"
        record.start_export()
        monkeypatch.delenv(atomic_io.HOLD_WRITES_ENV)  # the next engine (after this kill) writes normally
        kill_inside_the_write(record_status, "go2_walk_30fps.csv")

        record.start_export()
        wait(lambda: record.export_status.content.startswith(("Exported", "Export failed")), 120, "the new export")
        assert record.export_status.content.startswith("Exported `exports/go2_walk_30fps.csv` (")
        retarget.start_export()
        wait(lambda: retarget.export_status.content.startswith(("Exported", "Export failed")), 120, "the export")
        assert retarget.export_status.content == "Exported: `motions/exports/go2_standing.json`"
        assert sorted(p.name for p in exports.iterdir()) == ["go2_standing.json", "go2_walk_30fps.csv"]
        assert json.loads((exports / "go2_standing.json").read_text())["Frames"]
    finally:
        studio.stop()
