"""The Sample tab's *Rehearsal*: walk the open style through the sweep in physics, off screen.

The edit-time check above it reads the reference; a rehearsal (engine/gait/rehearsal.py) simulates the walk the
way ``studio bench styles`` does and says whether, when and where it falls. It runs in its own process at low
priority (``nice`` 10, so the live simulation keeps its CPU), reports its progress here, can be cancelled, and
marks its verdict stale once the style is edited after it started. The panel computes nothing: it writes the
style to a temporary file, starts the process and shows the lines it prints.

*Rehearse after each edit* (on in ``studio serve``): once the style has rested :data:`AUTO_DELAY_S` after an
edit, an undo or an open, the panel rehearses it by itself, so a style that falls says so before Test is pressed
(issue 13: the reference check cannot see falls that begin in the closed loop). A newer edit cancels a rehearsal
of an older version. Verdicts are kept per style content (:func:`engine.gait.style.style_digest`) and number of
walks: undoing back to a version already rehearsed shows its verdict at once, without walking it again.

*Walks* (1, 3 or 5; 3 in ``studio serve``): the first walk is the benchmark's, each other one is nudged once while
the robot stands (physically nothing). Many styles sit where that turns a fall into a walk or back, so the verdict
says in how many walks the style fell; it is shown after the first walk and refined as the others end.

When a verdict is a fall, *Show <sample>* selects the sample the walk was following when it fell, in the Sample
and Curves tabs (and the walk of Edit mode), so the edit-time check and the curves shown are that sample's.
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
from typing import TYPE_CHECKING, Callable

import viser

from engine.gait.rehearsal import SWEEP_DURATION_S
from engine.gait.style import Style, style_digest, style_to_json_dict
from engine.gait.velocity_sampler import SAMPLE_NAMES
from engine.process import REPO_ROOT

if TYPE_CHECKING:
    from studio.style_session import StyleSession

REHEARSAL_NICE = 10
START_LABEL, CANCEL_LABEL = "Rehearse the sweep", "Cancel rehearsal"
AUTO_DELAY_S = 2.0  # the style rests this long after an edit before it is rehearsed by itself
CACHE_SIZE = 64  # verdicts kept (per style content and number of walks)
WALK_CHOICES = ("1", "3", "5")


def rehearsal_markdown(result: dict, stale: bool, wall_s: float | None = None, remembered: bool = False,
                       walking: str = "") -> str:
    """The rehearsal's verdict as the panel shows it (``walking``: what is still under way)."""
    mark = "✓" if result.get("clean") else ("⚠️" if not result.get("fell") else "✗")
    text = f"{mark} Rehearsal: {result.get('message', '')}"
    if walking:
        text += f" <small>({walking})</small>"
    if wall_s is not None:
        text += f" <small>({wall_s:.0f} s to rehearse)</small>"
    if remembered:
        text += " <small>(this version was rehearsed before)</small>"
    if stale:
        text += "\n\n<small>(rehearsed before your last edit: rehearse again to check it)</small>"
    return text


class RehearsalPanel:
    def __init__(self, server: viser.ViserServer, session: "StyleSession", duration_s: float = SWEEP_DURATION_S,
                 auto: bool = False, walks: int = 1, on_show_sample: Callable[[str], None] = lambda name: None):
        self.session = session
        self.on_show_sample = on_show_sample  # select a sample in the Sample and Curves tabs
        self.duration_s = duration_s
        self.auto = server.gui.add_checkbox(
            "Rehearse after each edit", initial_value=auto,
            hint=f"rehearse the style by itself {AUTO_DELAY_S:.0f} s after each edit, undo or open (a newer edit "
                 "cancels it); undoing to a version rehearsed before shows its verdict at once")
        self.walks = server.gui.add_dropdown(
            "Walks", options=WALK_CHOICES, initial_value=str(walks) if str(walks) in WALK_CHOICES else "1",
            hint="walks per rehearsal: the first is the benchmark's, each other one nudged once while standing "
                 "(physically nothing); a style at the margin falls in some of them")
        self.button = server.gui.add_button(
            START_LABEL, icon=viser.Icon.PLAYER_PLAY,
            hint=f"walk this style through the {duration_s:.0f} s sweep (stand, forward, back, sideways, turns) in "
                 "physics, in the background, as `studio bench styles` does: does it fall, where, and why")
        self.status = server.gui.add_markdown("")
        self.show_fall = server.gui.add_button(
            "Show the sample it fell in", icon=viser.Icon.ARROW_RIGHT, visible=False,
            hint="select the sample the walk was following when it fell, in the Sample and Curves tabs")
        self._fall_sample: str | None = None
        self._lock = threading.Lock()
        self._process: subprocess.Popen | None = None
        self._running_digest: str | None = None  # the content being rehearsed
        self._cancelled: tuple[bool, bool] = (False, False)  # (cancelled, by the animator)
        self.verdicts: dict[str, dict] = {}  # style digest → the rehearsal's result (insertion order: oldest first)
        self._due: tuple[float, Style] | None = None  # (monotonic time, style) of the next rehearsal by itself
        self._wake = threading.Condition()
        self._stopped = False
        self.button.on_click(lambda _: self.toggle())
        self.show_fall.on_click(self._on_show_fall)
        self.auto.on_update(lambda _: self._on_auto())
        self.walks.on_update(lambda _: self._on_auto())
        session.subscribe(self._on_style_change)
        threading.Thread(target=self._auto_loop, name="rehearsal-auto", daemon=True).start()

    @property
    def running(self) -> bool:
        with self._lock:
            return self._process is not None and self._process.poll() is None

    def toggle(self) -> None:
        if self.running:
            self.cancel()
        else:
            self.start()

    def start(self, style: Style | None = None) -> None:
        style = style if style is not None else self.session.style
        if style is None:
            self.status.content = "<small>no style open</small>"
            return
        self.cancel(manual=False)  # (one rehearsal at a time)
        walks = self.walk_count
        folder = Path(tempfile.mkdtemp(prefix="motion-studio-rehearsal-"))
        path = folder / "style.json"
        path.write_text(json.dumps(style_to_json_dict(style)))
        command = [sys.executable, "-m", "engine.gait.rehearsal", "--robot", self.session.robot, "--style", str(path),
                   "--duration", str(self.duration_s), "--walks", str(walks), "--nice", str(REHEARSAL_NICE)]
        process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   cwd=str(REPO_ROOT))
        with self._lock:
            self._process, self._cancelled, self._running_digest = process, (False, False), self._key(style, walks)
        self.button.label, self.button.icon = CANCEL_LABEL, viser.Icon.PLAYER_STOP
        self._show_verdict(None)
        self.status.content = "<small>rehearsing the sweep in physics…</small>"
        threading.Thread(target=self._follow, args=(process, style, walks, folder, time.monotonic()),
                         name="rehearsal", daemon=True).start()

    @property
    def walk_count(self) -> int:
        return int(self.walks.value)

    @staticmethod
    def _key(style: Style, walks: int) -> str:
        return f"{style_digest(style)}×{walks}"

    def verdict(self, style: Style, walks: int | None = None) -> dict | None:
        """The kept verdict of ``style`` rehearsed with ``walks`` walks (the panel's choice by default), or None."""
        with self._lock:
            return self.verdicts.get(self._key(style, walks if walks is not None else self.walk_count))

    def cancel(self, manual: bool = True) -> None:
        """Kill the running rehearsal; ``manual``: the animator asked (the panel says so), otherwise a newer
        edit superseded it."""
        with self._lock:
            process, self._cancelled = self._process, (True, manual)
        if process is not None and process.poll() is None:
            process.kill()

    def stop(self) -> None:
        """End a running rehearsal (the studio stops or the robot changes)."""
        self.session.unsubscribe(self._on_style_change)
        with self._wake:
            self._stopped, self._due = True, None
            self._wake.notify_all()
        self.cancel()

    # ------------------------------------------------------------------ by itself, after each edit
    def _on_style_change(self, style: Style, reason: str) -> None:
        if not self.auto.value:
            return
        digest = self._key(style, self.walk_count)
        with self._lock:
            running = self._process is not None and self._process.poll() is None
            if running and self._running_digest == digest:
                return  # (this very version is being rehearsed: an edit that changed nothing the robot walks)
            known = self.verdicts.get(digest)
        if running:
            self.cancel(manual=False)  # an older version's walk: its verdict would be stale when it ends
        with self._wake:
            self._due = None if known is not None else (time.monotonic() + AUTO_DELAY_S, style)
            self._wake.notify_all()
        if known is not None:
            self._show_verdict(known, stale=False, remembered=True)
        else:
            self._show_verdict(None)
            self.status.content = (f"<small>changed: rehearsing the sweep by itself once the style rests "
                                   f"{AUTO_DELAY_S:.0f} s…</small>")

    def _on_auto(self) -> None:
        if self.auto.value and self.session.style is not None:
            self._on_style_change(self.session.style, "rehearse after each edit")
        elif not self.auto.value:
            with self._wake:
                self._due = None

    def _auto_loop(self) -> None:
        while True:
            with self._wake:
                while not self._stopped and (self._due is None or self._due[0] > time.monotonic()):
                    self._wake.wait(None if self._due is None else max(self._due[0] - time.monotonic(), 0.0))
                due = self._due
                if self._stopped or due is None:
                    return
                style = due[1]
                self._due = None
            if self.auto.value and self.session.style is style:  # (a newer edit reschedules)
                self.start(style)

    def _follow(self, process: subprocess.Popen, style: Style, walks: int, folder: Path, started_s: float) -> None:
        result = None
        so_far: dict | None = None  # the verdict after the walks done so far
        total_s = walks * self.duration_s
        assert process.stdout is not None and process.stderr is not None
        try:
            for line in process.stdout:
                try:
                    event = json.loads(line)
                except json.JSONDecodeError:
                    continue
                if self._process is not process:
                    continue  # (superseded: what it prints is no longer news)
                if "progress_s" in event and "walk" not in event:
                    if so_far is None:
                        self.status.content = (f"<small>rehearsing the sweep in physics: {event['progress_s']:.0f} of "
                                               f"{total_s:.0f} s simulated</small>")
                    else:
                        self._show_verdict(
                            so_far, stale=False, walking=f"walk {int(event['progress_s'] // self.duration_s) + 1} of "
                                                         f"{walks} under way")
                elif "walk" in event:
                    so_far = event["walk"]
                    self._show_verdict(so_far, stale=False, walking=f"{so_far.get('walks', 1)} of {walks} walks so far")
                elif "result" in event:
                    result = event["result"]
            error = process.stderr.read().strip().splitlines()
            process.wait()
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        with self._lock:
            mine = self._process is process
            cancelled, by_animator = self._cancelled if mine else (True, False)  # (not mine: a newer one took over)
            if mine:
                self._process, self._running_digest = None, None
        if result is not None and process.returncode == 0:
            self._remember(style, walks, result)
        if not mine or self._stopped:  # (superseded, or the panel is gone: nothing to show)
            return
        self.button.label, self.button.icon = START_LABEL, viser.Icon.PLAYER_PLAY
        if cancelled:
            if by_animator:
                self._show_verdict(None)
                self.status.content = "<small>rehearsal cancelled</small>"
        elif result is not None:
            self._show_verdict(result, stale=self.session.style is not style, wall_s=time.monotonic() - started_s)
        else:
            reason = error[-1] if error else f"exit status {process.returncode}"
            self._show_verdict(None)
            self.status.content = f"<small>the rehearsal failed: {reason}</small>"

    def _show_verdict(self, result: dict | None, **how) -> None:
        """Show a verdict (None: none), and the button to its fall's sample when it fell in one."""
        sample = result.get("sample") if result is not None and result.get("fell") else None
        self._fall_sample = sample if sample in SAMPLE_NAMES else None
        if self._fall_sample is not None:
            self.show_fall.label = f"Show {self._fall_sample}"
        self.show_fall.visible = self._fall_sample is not None
        if result is not None:
            self.status.content = rehearsal_markdown(result, **how)

    def _on_show_fall(self, _event: object) -> None:
        self.show_fall_sample()

    def show_fall_sample(self) -> str | None:
        """Select the sample the shown verdict fell in (the button); returns it, or None when there is none."""
        sample = self._fall_sample
        if sample is not None:
            self.on_show_sample(sample)
        return sample

    def _remember(self, style: Style, walks: int, result: dict) -> None:
        digest = self._key(style, walks)
        with self._lock:
            self.verdicts.pop(digest, None)
            self.verdicts[digest] = result
            while len(self.verdicts) > CACHE_SIZE:
                self.verdicts.pop(next(iter(self.verdicts)))
