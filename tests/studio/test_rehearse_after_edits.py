"""The Style tab's speeds and the Rehearsal panel's *Rehearse after each edit* (issue 13: a style that falls says so
before Test is pressed). Real rehearsal processes over a short sweep; a viser server without an engine."""

from __future__ import annotations

import shutil
from dataclasses import replace
import time

import pytest

from engine.gait.style import style_digest
from studio.panels import rehearsal_panel, typing_pause
from studio.panels.rehearsal_panel import RehearsalPanel
from studio.panels.style_speeds import StyleSpeeds
from studio.style_session import StyleSession
from tests.conftest import REPO
from tests.studio.test_app import wait
from tests.studio.test_panels import Notes, server, session  # noqa: F401  (the fixtures: a viser server, neutral open)

SPLAYED = REPO / "tests" / "data" / "splayed_g1.json"
SHORT_SWEEP_S = 3.0  # stand 1 s and the start of the forward leg: enough to walk, quick to rehearse


def kept(panel: RehearsalPanel, digest: str, walks: int = 1) -> dict | None:
    """The verdict the panel keeps for the style content ``digest`` rehearsed with ``walks`` walks."""
    return panel.verdicts.get(f"{digest}×{walks}")


def test_a_speed_edit_is_an_undoable_validated_edit_of_the_style(server, session):
    notices = Notes()
    speeds = StyleSpeeds(server, session, notices)
    assert speeds.inputs["x_max_mps"].value == pytest.approx(session.style.velocities.x_max_mps)
    assert speeds.set_speed("x_max_mps", 0.42)
    assert session.style.velocities.x_max_mps == pytest.approx(0.42) and session.dirty
    # Slow must stay below fast: refused, the style and the field keep 0.42's neighbour values.
    slow = session.style.velocities.x_slow_mps
    assert not speeds.set_speed("x_slow_mps", 0.6)
    assert session.style.velocities.x_slow_mps == pytest.approx(slow)
    assert speeds.inputs["x_slow_mps"].value == pytest.approx(slow)
    assert "x_slow_mps" in speeds.message.content and notices and notices[-1][0] == "warning"
    # A step beyond the legs' reach (the validator couples each sample's step to its velocity): refused too.
    assert not speeds.set_speed("x_max_mps", 5.0)
    assert session.style.velocities.x_max_mps == pytest.approx(0.42)
    assert session.undo().ok
    assert speeds.inputs["x_max_mps"].value == pytest.approx(0.5)  # the field follows undo


def test_typed_speeds_apply_once_when_the_keys_pause(server, session, monkeypatch):
    # The shared typing pause (studio/panels/typing_pause.py), long enough that three assignments never span it.
    monkeypatch.setattr(typing_pause, "TYPING_PAUSE_S", 1.5)
    speeds = StyleSpeeds(server, session, Notes())
    field = speeds.inputs["x_max_mps"]
    for typed in (0.0, 0.4, 0.45):  # keystrokes "0", ".4", "5"
        field.value = typed
    assert session.undo_labels() == []  # nothing applied while typing ("0" would have been refused)
    wait(lambda: session.undo_labels() != [], 10)
    assert session.undo_labels() == ["speed x_max_mps"]  # one edit, the last value
    assert session.style.velocities.x_max_mps == pytest.approx(0.45)
    assert speeds.message.content == ""
    session.undo()  # the panel writes the field back: not a keystroke, so no edit follows
    time.sleep(2.0)
    assert field.value == pytest.approx(0.5) and session.undo_labels() == []


def test_edits_are_rehearsed_by_themselves_once_the_style_rests_and_undo_reuses_the_verdict(server, session, monkeypatch):
    monkeypatch.setattr(rehearsal_panel, "AUTO_DELAY_S", 0.5)
    started: list[str] = []
    original_start = RehearsalPanel.start

    def counting_start(self, style=None):
        started.append(style_digest(style if style is not None else self.session.style))
        original_start(self, style)

    monkeypatch.setattr(RehearsalPanel, "start", counting_start)
    panel = RehearsalPanel(server, session, SHORT_SWEEP_S, auto=True)
    speeds = StyleSpeeds(server, session, Notes())
    try:
        neutral = style_digest(session.style)
        assert not started  # opening the studio does not rehearse: only a change does
        # A burst of edits (a knot dragged, a sample's slider) is rehearsed once, at its last value.
        for value in (0.45, 0.44, 0.43):
            assert speeds.set_speed("x_max_mps", value)
            assert session.undo().ok and session.redo().ok
        assert "once the style rests" in panel.status.content
        edited = style_digest(session.style)
        wait(lambda: kept(panel, edited) is not None, 180)
        assert started == [edited]
        result = kept(panel, edited)
        assert result["fell"] is False and result["duration_s"] == pytest.approx(SHORT_SWEEP_S)
        assert "Rehearsal:" in panel.status.content and "walks" in panel.status.content
        # Undo to neutral: a version never rehearsed, so it walks; redo: the verdict is remembered, no walk.
        for _ in range(3):
            assert session.undo().ok
        assert style_digest(session.style) == neutral
        wait(lambda: kept(panel, neutral) is not None, 180)
        assert started == [edited, neutral]
        for _ in range(3):
            assert session.redo().ok
        assert style_digest(session.style) == edited and "rehearsed before" in panel.status.content
        time.sleep(1.0)
        assert started == [edited, neutral] and not panel.running
        # A new edit while a rehearsal runs cancels it (its verdict would describe an older version).
        assert speeds.set_speed("x_max_mps", 0.47)
        wait(lambda: panel.running, 180)
        running = style_digest(session.style)
        process = panel._process
        assert session.apply(session.style, "an edit that changes nothing").ok
        time.sleep(0.8)
        assert panel._process is process and panel.running  # the same version: its walk goes on
        assert speeds.set_speed("x_max_mps", 0.48)
        wait(lambda: not panel.running or panel._running_digest != f"{running}×1", 30)
        latest = style_digest(session.style)
        wait(lambda: kept(panel, latest) is not None, 180)
        assert kept(panel, running) is None
        assert "cancelled" not in panel.status.content
        # Off: edits are not rehearsed.
        panel.auto.value = False
        assert speeds.set_speed("x_max_mps", 0.49)
        time.sleep(1.5)
        assert not panel.running and kept(panel, style_digest(session.style)) is None
    finally:
        panel.stop()


def test_a_style_that_falls_says_where_before_test_is_pressed(server, tmp_path, monkeypatch):
    """A random G1 style of the validated space that falls 0.9 s into the sweep, stepping in place
    (tests/data/splayed_g1.json: draw 14 of `studio bench styles --robot g1 --seed 5 --space validated`, saved by the
    studio's writer; in place its feet splay 0.37 rad and stand 8 cm back, with a 0.68 s toe-off): opened, the panel
    rehearses it by itself and names the sample and the phase; with in_place's splay at 0 it walks."""
    monkeypatch.setattr(rehearsal_panel, "AUTO_DELAY_S", 0.2)
    folder = tmp_path / "g1"
    folder.mkdir()
    shutil.copy(REPO / "styles" / "g1" / "neutral.json", folder / "neutral.json")
    shutil.copy(SPLAYED, folder / "splayed.json")
    session = StyleSession("g1", folder=folder)
    assert session.open("neutral").ok
    shown: list[str] = []
    panel = RehearsalPanel(server, session, 4.0, auto=True, on_show_sample=shown.append)
    try:
        assert not panel.show_fall.visible and panel.show_fall_sample() is None and shown == []
        assert session.open("splayed").ok
        wait(lambda: kept(panel, style_digest(session.style)) is not None, 180)
        fell = kept(panel, style_digest(session.style))
        assert fell["fell"] and fell["sample"] == "in_place" and fell["phase_pct"] is not None
        wait(lambda: panel.show_fall.visible, 10)
        assert "falls at" in panel.status.content and "% of its cycle" in panel.status.content
        assert "**in_place**" in panel.status.content and "(standing)" in panel.status.content
        # The button selects the sample the walk fell in (the app selects it in the Sample and Curves tabs).
        assert panel.show_fall.label == f"Show {fell['sample']}" and panel.show_fall_sample() == fell["sample"]
        assert shown == [fell["sample"]]
        style = session.style
        in_place = style.samples["in_place"]
        unsplayed = replace(in_place, attributes=replace(in_place.attributes, stance_splay_rad=0.0))
        assert session.apply(style.with_sample("in_place", unsplayed), "in_place stance_splay_rad").ok
        assert not panel.show_fall.visible  # a new version: the old fall is not shown any more
        wait(lambda: kept(panel, style_digest(session.style)) is not None, 180)
        assert not kept(panel, style_digest(session.style))["fell"]
        wait(lambda: "walks the 4 s sweep" in panel.status.content, 10)
        assert not panel.show_fall.visible
        # Three walks (the first the benchmark's, two nudged while standing): rehearsed again, kept apart.
        panel.walks.value = "3"
        wait(lambda: kept(panel, style_digest(session.style), 3) is not None, 240)
        three = kept(panel, style_digest(session.style), 3)
        assert three["walks"] == 3 and 0 <= three["falls"] <= 3 and three["fell"] == (three["falls"] > 0)
        assert "of 3 walks" in panel.status.content or "worst of 3 walks" in panel.status.content
    finally:
        panel.stop()
