"""The studio app with a real engine process: robot switching, bad files, engine restarts."""

from __future__ import annotations

import json
import os
import shutil
import signal
import time

import pytest

from studio.app import Studio
from tests.conftest import REPO, free_port


def wait(predicate, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.1)
    raise AssertionError("timed out")


@pytest.fixture
def studio(tmp_path):
    styles = tmp_path / "styles"
    for robot in ("g1", "talos", "dino"):
        (styles / robot).mkdir(parents=True)
        for p in (REPO / "styles" / robot).glob("*.json"):
            shutil.copy(p, styles / robot / p.name)
    app = Studio("g1", port=free_port(), styles_folder=styles).start()
    assert app.loaded.wait(60)
    yield app
    app.stop()


def test_the_dino_opens_with_its_neck_and_tail_curves(studio):
    studio.robot_panel.robot.value = "dino"
    wait(lambda: studio.session is not None and studio.session.robot == "dino" and studio.curve_editor is not None)
    assert studio.session.style.robot == "dino"
    assert studio.session.open("strut").ok
    channels = set(studio.session.style.sample("forward_slow").curves)
    assert {"joints.neck_pitch_joint", "joints.head_pitch_joint", "joints.tail_yaw_1_joint"} <= channels


def test_switching_robots_switches_styles_and_panels(studio):
    assert studio.session.robot == "g1" and studio.curve_editor is not None
    studio.robot_panel.robot.value = "talos"
    wait(lambda: studio.session is not None and studio.session.robot == "talos" and studio.sample_editor is not None
         and studio.sample_editor.session is studio.session)  # the panels are built after the session
    assert studio.session.style.robot == "talos"
    lo, hi = studio.session.ctx.pelvis_height_range_m
    slider = studio.sample_editor.attributes["pelvis_height_m"]
    assert (slider.min, slider.max) == (lo, hi) == (0.82, 1.04)
    studio.robot_panel.robot.value = "go2"
    wait(lambda: studio.robot_name == "go2" and studio.session is None)
    studio.set_mode("test")
    assert any("can only stand" in text for _, text in studio.notices)


def test_a_broken_style_file_is_refused_with_one_line_and_nothing_is_lost(studio, tmp_path):
    folder = studio.session.folder
    doc = json.loads((folder / "neutral.json").read_text())
    doc["samples"]["in_place"]["intervals"]["right_swing_s"] = [0.1, 0.2]
    (folder / "broken.json").write_text(json.dumps(doc))
    before = studio.session.style
    assert not studio.style_browser.open("broken")
    level, text = studio.notices[-1]
    assert level == "error" and "broken.json: samples.in_place.intervals: expected event order" in text
    assert "\n" not in text and studio.session.style is before


@pytest.mark.slow  # kills the engine process and waits for the new one (engine level: tests/test_engine.py)
def test_edits_survive_an_engine_crash(studio):
    from dataclasses import replace

    session = studio.session
    sample = session.style.samples["in_place"]
    edited = replace(sample, attributes=replace(sample.attributes, stance_width_m=0.28))
    assert session.apply(session.style.with_sample("in_place", edited), "wider").ok
    revision = studio.style_revision
    studio.set_mode("edit")
    old_pid = studio.link.pid
    os.kill(old_pid, signal.SIGKILL)
    wait(lambda: studio.link.pid not in (None, old_pid), 10)
    wait(lambda: studio.style_revision > revision)  # the edited style went to the new engine
    assert session.style.samples["in_place"].attributes.stance_width_m == 0.28 and session.dirty
    wait(lambda: studio.view.last_frame is not None and studio.view.last_frame.mode == "edit", 30)


def test_shadows_are_off_by_default_and_the_checkbox_turns_them_on(studio, monkeypatch):
    """Shadow maps cost a browser without a GPU several times its frame rate (``studio bench render``): the
    studio starts without them; the Robot tab's checkbox sends the lights' setting to every browser."""
    from viser import _messages

    sent: list = []
    original = studio.server._websock_server.queue_message
    monkeypatch.setattr(studio.server._websock_server, "queue_message",
                        lambda m: (sent.append(m), original(m))[1])
    assert studio.shadows is False and studio.drive.shadows.value is False
    studio.drive.shadows.value = True
    wait(lambda: any(isinstance(m, _messages.EnableLightsMessage) and m.cast_shadow for m in sent), 10)
    assert studio.shadows is True
    studio.drive.shadows.value = False
    wait(lambda: isinstance(lights := [m for m in sent if isinstance(m, _messages.EnableLightsMessage)][-1],
                            _messages.EnableLightsMessage) and not lights.cast_shadow, 10)
    assert studio.shadows is False
