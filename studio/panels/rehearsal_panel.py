"""The Sample tab's *Rehearse the sweep* button: walk the open style through the sweep in physics, off screen.

The edit-time check above it reads the reference; a rehearsal (engine/gait/rehearsal.py) simulates the walk the
way ``studio bench styles`` does and says whether, when and where it falls. It runs in its own process at low
priority (``nice`` 10, so the live simulation keeps its CPU), reports its progress here, can be cancelled, and
marks its verdict stale once the style is edited after it started. The panel computes nothing: it writes the
style to a temporary file, starts the process and shows the lines it prints.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

import viser

from engine.gait.rehearsal import SWEEP_DURATION_S
from engine.gait.style import style_to_json_dict
from engine.process import REPO_ROOT

if TYPE_CHECKING:
    from studio.style_session import StyleSession

REHEARSAL_NICE = 10
START_LABEL, CANCEL_LABEL = "Rehearse the sweep", "Cancel rehearsal"


def rehearsal_markdown(result: dict, stale: bool, wall_s: float | None = None) -> str:
    """The rehearsal's verdict as the panel shows it."""
    mark = "✓" if result.get("clean") else ("⚠️" if not result.get("fell") else "✗")
    text = f"{mark} Rehearsal: {result.get('message', '')}"
    if wall_s is not None:
        text += f" <small>({wall_s:.0f} s to rehearse)</small>"
    if stale:
        text += "\n\n<small>(rehearsed before your last edit: rehearse again to check it)</small>"
    return text


class RehearsalPanel:
    def __init__(self, server: viser.ViserServer, session: "StyleSession", duration_s: float = SWEEP_DURATION_S):
        self.session = session
        self.duration_s = duration_s
        self.button = server.gui.add_button(
            START_LABEL, icon=viser.Icon.PLAYER_PLAY,
            hint=f"walk this style through the {duration_s:.0f} s sweep (stand, forward, back, sideways, turns) in "
                 "physics, in the background, as `studio bench styles` does: does it fall, where, and why")
        self.status = server.gui.add_markdown("")
        self._lock = threading.Lock()
        self._process: subprocess.Popen | None = None
        self._cancelled = False
        self.button.on_click(lambda _: self.toggle())

    @property
    def running(self) -> bool:
        with self._lock:
            return self._process is not None and self._process.poll() is None

    def toggle(self) -> None:
        if self.running:
            self.cancel()
        else:
            self.start()

    def start(self) -> None:
        style = self.session.style
        if style is None:
            self.status.content = "<small>no style open</small>"
            return
        folder = Path(tempfile.mkdtemp(prefix="motion-studio-rehearsal-"))
        path = folder / "style.json"
        path.write_text(json.dumps(style_to_json_dict(style)))
        command = [sys.executable, "-m", "engine.gait.rehearsal", "--robot", self.session.robot, "--style", str(path),
                   "--duration", str(self.duration_s), "--nice", str(REHEARSAL_NICE)]
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   cwd=str(REPO_ROOT))
        with self._lock:
            self._process, self._cancelled = process, False
        self.button.label, self.button.icon = CANCEL_LABEL, viser.Icon.PLAYER_STOP
        self.status.content = "<small>rehearsing the sweep in physics…</small>"
        threading.Thread(target=self._follow, args=(process, style, folder, time.monotonic()), name="rehearsal",
                         daemon=True).start()

    def cancel(self) -> None:
        with self._lock:
            process, self._cancelled = self._process, True
        if process is not None and process.poll() is None:
            process.kill()

    def stop(self) -> None:
        """End a running rehearsal (the studio stops or the robot changes)."""
        self.cancel()

    def _follow(self, process: subprocess.Popen, style: object, folder: Path, started_s: float) -> None:
        result = None
        assert process.stdout is not None and process.stderr is not None
        try:
            for line in process.stdout:
                try:
                    event = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if "progress_s" in event:
                    self.status.content = (f"<small>rehearsing the sweep in physics: {event['progress_s']:.0f} of "
                                           f"{self.duration_s:.0f} s simulated</small>")
                elif "result" in event:
                    result = event["result"]
            error = process.stderr.read().strip().splitlines()
            process.wait()
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        with self._lock:
            cancelled = self._cancelled
            if self._process is process:
                self._process = None
        self.button.label, self.button.icon = START_LABEL, viser.Icon.PLAYER_PLAY
        if cancelled:
            self.status.content = "<small>rehearsal cancelled</small>"
        elif result is not None:
            self.status.content = rehearsal_markdown(result, stale=self.session.style is not style,
                                                     wall_s=time.monotonic() - started_s)
        else:
            reason = error[-1] if error else f"exit status {process.returncode}"
            self.status.content = f"<small>the rehearsal failed: {reason}</small>"
