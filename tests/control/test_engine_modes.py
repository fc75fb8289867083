"""The engine's walking modes: edit (a sample's cycle), test (joystick), style updates, reset."""

from __future__ import annotations

import json

import numpy as np
import pytest

from engine import protocol as msg
from engine.core import EngineCore
from tests.conftest import REPO


def core_for(robot: str = "g1"):
    events: list = []
    return EngineCore(robot, events.append), events


def test_edit_mode_walks_the_selected_sample():
    core, events = core_for()
    core.handle(msg.SetMode("edit", {"sample": "forward_slow"}))
    assert core.mode == "edit" and core.walker is not None
    for _ in range(int(4.0 / 0.002)):
        core.tick()
    assert not core.sim.fallen
    assert core.sim.data.qpos[0] > 0.4  # 0.25 m/s for ~3 s after the start
    tel = core.telemetry().signals
    for key in ("com_xy", "support_polygon", "footholds_planned", "sample_weights", "ghost_body_pos", "feedback"):
        assert key in tel
    assert tel["sample_weights"][1] == pytest.approx(1.0)  # forward_slow only
    assert not [e for e in events if isinstance(e, msg.Notice) and e.level == "error"]


def test_test_mode_follows_the_joystick_and_style_updates_apply_live():
    core, events = core_for()
    core.handle(msg.SetMode("test"))
    core.handle(msg.SetVelocityCommand(0.0, 0.0, 0.6))
    doc = json.loads((REPO / "styles/g1/neutral.json").read_text())
    for _ in range(int(2.0 / 0.002)):
        core.tick()
    doc["samples"]["left_turn"]["attributes"]["pelvis_height_m"] = 0.65
    core.handle(msg.SetStyle(doc, revision=7))
    for _ in range(4):  # the next planner tick runs with it
        core.tick()
    assert core.frame().style_revision == 7
    for _ in range(int(2.0 / 0.002)):
        core.tick()
    assert not core.sim.fallen
    yaw = core._base_yaw()
    assert yaw > 0.3  # turned left
    bad = dict(doc, robot="talos")
    core.handle(msg.SetStyle(bad, revision=8))
    assert core.frame().style_revision == 7  # refused, the old style stays
    assert any(isinstance(e, msg.Notice) and "style refused" in e.message for e in events)


def test_modes_are_refused_where_they_make_no_sense():
    core, events = core_for("go2")
    core.handle(msg.SetMode("test"))
    assert core.mode == "stand"
    assert any(isinstance(e, msg.Notice) and "can only stand" in e.message for e in events)
    core.handle(msg.SetMode("dance"))
    assert any(isinstance(e, msg.Notice) and "expected one of stand, test, edit" in e.message for e in events)


def test_playback_speed_bounds():
    core, events = core_for()
    core.handle(msg.SetPlaybackSpeed(0.25))
    assert core.playback_speed == 0.25
    core.handle(msg.SetPlaybackSpeed(100.0))
    assert core.playback_speed == 0.25 and isinstance(events[-1], msg.Notice)


def test_an_extreme_style_edit_stays_safe():
    """A valid but extreme style (knees nearly straight at full height, feet thrown forward, toes
    splayed out) at full speed: torques stay finite every tick, nothing raises, and a fall is
    reported exactly when it happens (the QP's own fallbacks are tested in test_inverse_dynamics)."""
    core, events = core_for()
    core.handle(msg.SetMode("test"))
    core.handle(msg.SetVelocityCommand(0.5, 0.0, 0.0))
    doc = json.loads((REPO / "styles/g1/neutral.json").read_text())
    for sample in doc["samples"].values():
        sample["attributes"].update(pelvis_height_m=0.78, stance_x_bias_m=0.2, stance_splay_rad=0.6)
    core.handle(msg.SetStyle(doc, revision=3))
    for _ in range(4):  # the next planner tick runs with it
        core.tick()
    assert core.frame().style_revision == 3  # accepted: it is a valid style
    fell = False
    for _ in range(int(6.0 / 0.002)):
        core.tick()
        assert np.all(np.isfinite(core.sim.data.ctrl))
        assert np.all(np.isfinite(core.sim.data.qpos))
        fell |= core.sim.fallen
    notices = [e.message for e in events if isinstance(e, msg.Notice)]
    assert fell == any("fell" in m for m in notices)
