"""Record the walk (Test mode) and export it for robot learning.

● Record asks the engine to record (``SetRecording``): every 4th 500 Hz tick, the simulated state and the
reference the controller tracks. ■ Stop has the engine write ``runs/<name>.npz`` in the motion library
(atomically) and report it; Export then runs the engine's ``export`` job on that file (Unitree CSV,
BeyondMimic npz or AMP JSON, resampled to the chosen rate). The panel only sends commands and shows
what comes back: the recording and the numerics live in the engine (engine/walk_recording.py,
engine/export/).
"""

from __future__ import annotations

import itertools
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import viser

from engine import protocol as msg
from engine.jobs import export_outputs
from engine.motion_files import motions_root
from studio.job_outputs import cleanup_lost_outputs, lost_job_text

if TYPE_CHECKING:
    from studio.app import Studio

EXPORT_FORMATS = ("unitree-csv", "beyondmimic-npz", "amp-json")
EXPORT_RATES = {"30 fps": 30.0, "50 fps": 50.0, "as recorded (125 fps)": None}
TAKES = ("simulated", "reference")
JOB_PREFIX = "rec-"  # job ids of this panel (the app routes their JobProgress here)


class RecordPanel:
    def __init__(self, server: viser.ViserServer, studio: "Studio", root: Path | None = None):
        self.server = server
        self.studio = studio
        self.root = Path(root) if root is not None else motions_root()  # the engine's motion library
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self.recording = False
        self.started_at_s: float | None = None
        self.run_path: str | None = None  # the last saved recording, relative to the motion library
        self.export_path: str | None = None
        self._export_job: str | None = None
        self._export_outputs: tuple[float, tuple[str, ...]] = (0.0, ())  # (start time, files the export writes)
        self._saving = False  # ■ Stop was pressed: the engine is writing the recording
        with server.gui.add_folder("Record (test mode)"):
            self.record = server.gui.add_button("● Record", color="red",
                                                hint="record the walk (simulated and reference) until ■ Stop")
            self.status = server.gui.add_markdown("Not recording. Switch to Test mode and walk with the joystick.")
            self.format = server.gui.add_dropdown("Export format", EXPORT_FORMATS, initial_value="unitree-csv")
            self.rate = server.gui.add_dropdown("Export rate", tuple(EXPORT_RATES), initial_value="30 fps")
            self.take = server.gui.add_dropdown("Take", TAKES, initial_value="simulated",
                                                hint="the simulated walk or the reference it tracked")
            self.export = server.gui.add_button("Export recording", disabled=True)
            self.export_status = server.gui.add_markdown("Nothing exported yet.")
        self.record.on_click(lambda _: self.toggle())
        self.export.on_click(lambda _: self.start_export())

    # ------------------------------------------------------------------ record
    def toggle(self) -> None:
        with self._lock:
            if not self.recording:
                if self.studio.mode not in ("test", "edit"):
                    self.status.content = "Recording needs a walking robot: switch to **Test** mode first."
                    return
                self.recording = True
                frame = self.studio.view.last_frame
                self.started_at_s = frame.sim_time_s if frame is not None else None
                self.record.label = "■ Stop recording"
                self.status.content = "● Recording… (■ Stop recording saves it)"
                self.studio.link.send(msg.SetRecording(True, request_id=f"{JOB_PREFIX}{next(self._ids)}"))
            else:
                self.recording = False
                self._saving = True
                self.record.label = "● Record"
                self.status.content = "Saving the recording…"
                self.studio.link.send(msg.SetRecording(False, request_id=f"{JOB_PREFIX}{next(self._ids)}"))

    # ------------------------------------------------------------------ export
    def start_export(self) -> None:
        if not self.run_path:
            return
        job_id = f"{JOB_PREFIX}export-{next(self._ids)}"
        self._export_job = job_id
        self.export.disabled = True
        self.export_status.content = f"Exporting `{self.run_path}` as {self.format.value}…"
        params = {"motion": self.run_path, "format": self.format.value, "fps": EXPORT_RATES[self.rate.value],
                  "take": self.take.value}
        self._export_outputs = (time.time(), export_outputs(self.root, params))  # known before the job starts
        self.studio.link.send(msg.StartJob("export", params, job_id=job_id))

    def on_engine_lost(self, pid: int | None) -> list[str]:
        """The engine died (the link's thread): a recording in progress lived in it, and so did an export job."""
        lost = []
        if self.recording or self._saving:
            self.recording = self._saving = False
            self.record.label = "● Record"
            self.status.content = (f"Recording lost: the engine (pid {pid}) stopped; the recording was in its memory "
                                   "and is not saved (a saved run is written whole or not at all). Press ● Record to "
                                   "record again.")
            lost.append("the recording")
        if self._export_job is not None:
            self._export_job = None
            self.export.disabled = False
            started, outputs = self._export_outputs
            self._export_outputs = (0.0, ())
            written = cleanup_lost_outputs(self.root, outputs, started)  # a cut write's temporary is removed
            self.export_status.content = f"Export lost: {lost_job_text(pid, written, 'press Export recording')}"
            lost.append("the export job")
        return lost

    # ------------------------------------------------------------------ engine events (the link's thread)
    def on_job(self, event: msg.JobProgress) -> None:
        if event.result is None:
            return
        result = event.result
        if event.job == "record":
            self.recording = False
            self._saving = False
            self.record.label = "● Record"
            if result.get("ok"):
                self.run_path = result["path"]
                self.status.content = (f"Saved `{result['path']}`: {result['frames']} frames, "
                                       f"{result['duration_s']:.1f} s at {result['fps']:g} fps")
                self.export.disabled = False
            else:
                self.status.content = f"Not saved: {result.get('error', 'failed')}"
        elif event.job_id == self._export_job:
            self._export_job = None
            self._export_outputs = (0.0, ())
            self.export.disabled = False
            if result.get("ok"):
                self.export_path = result["path"]
                self.export_status.content = (f"Exported `{result['path']}` ({result['frames']} frames at "
                                              f"{result['fps']:g} fps)")
            else:
                self.export_status.content = f"Export failed: {result.get('error', 'failed')}"

    def elapsed_s(self) -> float | None:
        frame = self.studio.view.last_frame
        if not self.recording or frame is None or self.started_at_s is None:
            return None
        return frame.sim_time_s - self.started_at_s

    def tick_status(self) -> None:
        """Called by the studio's status loop: the elapsed simulated time while recording."""
        elapsed = self.elapsed_s()
        if elapsed is not None:
            self.status.content = f"● Recording… {elapsed:.1f} s simulated (■ Stop recording saves it)"
