"""Studio panels driven headless through viser handles (setting values runs their callbacks)."""

from __future__ import annotations

import json
import shutil
import time

import numpy as np
import pytest
import viser

from engine import protocol as msg
from engine.gait.style import load_style
from studio.panels.drive_panel import HOLD_TIMEOUT_MAX_S, HOLD_TIMEOUT_S, DrivePanel, JoystickState
from studio.panels.sample_editor import SampleEditor
from studio.panels.style_browser import StyleBrowser
from studio.style_session import StyleSession
from tests.conftest import REPO, free_port


@pytest.fixture(scope="module")
def server():
    srv = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    yield srv
    srv.stop()


@pytest.fixture
def session(tmp_path):
    folder = tmp_path / "g1"
    folder.mkdir()
    for p in (REPO / "styles/g1").glob("*.json"):
        shutil.copy(p, folder / p.name)
    s = StyleSession("g1", folder=folder)
    assert s.open("neutral").ok
    return s


class Notes(list):
    def __call__(self, level, text):
        self.append((level, text))


def test_style_session_undo_redo_autosave_and_recovery(session):
    style = session.style
    sample = style.samples["in_place"]
    from dataclasses import replace

    wider = replace(sample, attributes=replace(sample.attributes, stance_width_m=0.3))
    assert session.apply(style.with_sample("in_place", wider), "wider").ok
    assert session.dirty and session.recovery_path("neutral").is_file()
    # A crash now: a new session offers the autosaved edits.
    again = StyleSession("g1", folder=session.folder)
    assert again.recovery_available("neutral")
    assert again.recover("neutral").ok and again.style.samples["in_place"].attributes.stance_width_m == 0.3
    assert session.undo().ok and session.style.samples["in_place"].attributes.stance_width_m == 0.24
    assert session.redo().ok and session.style.samples["in_place"].attributes.stance_width_m == 0.3
    assert session.save().ok and not session.dirty and not session.recovery_path("neutral").exists()
    assert load_style(session.folder / "neutral.json").samples["in_place"].attributes.stance_width_m == 0.3
    # Invalid edits are refused and change nothing.
    too_wide = replace(sample, attributes=replace(sample.attributes, stance_width_m=2.0))
    result = session.apply(style.with_sample("in_place", too_wide), "too wide")
    assert not result.ok and "stance_width_m" in result.message
    assert session.style.samples["in_place"].attributes.stance_width_m == 0.3


def test_session_paths_stay_inside_the_styles_folder(session):
    for name in ("../../etc/passwd", "a/b", "", ".hidden", "x" * 100):
        result = session.save_as(name)
        assert not result.ok
    assert session.new_from("neutral", "my-walk").ok
    assert (session.folder / "my-walk.json").is_file() and session.style.name == "my-walk"


def test_style_browser(server, session):
    notes = Notes()
    with server.gui.add_folder("browser"):
        browser = StyleBrowser(server, session, notes)
    browser.name.value = "bouncy"
    assert browser.new("bouncy")
    assert "bouncy" in browser.dropdown.options and browser.dropdown.value == "bouncy"
    assert "bouncy" in browser.title.content and "unsaved" not in browser.title.content
    assert browser.open("neutral")
    assert "neutral" in browser.title.content


def test_sample_editor_edits_intervals_and_attributes_and_refuses_bad_ones(server, session):
    notes = Notes()
    picked = []
    with server.gui.add_folder("sample"):
        editor = SampleEditor(server, session, notes, on_sample=picked.append)
    editor.dropdown.value = "forward_slow"
    assert picked == ["forward_slow"] and editor.sample_name == "forward_slow"
    before = session.style.samples["forward_slow"]
    t_ltd, t_rlo, t_rtd, cycle = before.intervals.events_s
    # Longer cycle through the timeline: the knots of the swing curves rescale with it.
    editor.timeline.value = (t_ltd + 0.04, t_rlo + 0.04, t_rtd + 0.08, cycle + 0.08)
    after = session.style.samples["forward_slow"]
    assert after.intervals.cycle_s == pytest.approx(cycle + 0.08)
    assert after.curves["left_foot.z"].duration_s == pytest.approx(t_ltd + 0.04)
    # An interval dragged past its neighbour (too little double support) is refused; the slider snaps back.
    editor.timeline.value = (t_ltd + 0.04, t_ltd + 0.045, t_rtd + 0.08, cycle + 0.08)
    assert session.style.samples["forward_slow"].intervals == after.intervals
    assert tuple(editor.timeline.value) == tuple(round(e, 4) for e in after.intervals.events_s)
    assert "double support" in editor.message.content and notes[-1][0] == "warning"
    # Attributes.
    editor.attributes["pelvis_height_m"].value = 0.65
    assert session.style.samples["forward_slow"].attributes.pelvis_height_m == pytest.approx(0.65)
    # Duplicate a sample onto another.
    editor.copy_target.value = "reverse_slow"
    assert editor.copy_to("reverse_slow")
    assert session.style.samples["reverse_slow"].intervals == session.style.samples["forward_slow"].intervals
    assert session.undo().ok and session.style.samples["reverse_slow"].intervals != session.style.samples["forward_slow"].intervals


class FakeLink:
    def __init__(self):
        self.sent = []

    def send(self, command):
        self.sent.append(command)
        return True


class FakeStudio:
    def __init__(self):
        self.link = FakeLink()
        self.mode = "stand"
        self.modes = []
        self.shadows = False

        class O:
            def set_visible(self, v):
                pass

        self.overlays = O()

    def set_mode(self, mode):
        self.mode = mode
        self.modes.append(mode)

    def set_ghost_visible(self, v):
        pass

    def velocity_limits(self):
        return np.array([0.5, 0.15, 1.0])

    def robot_position(self):
        return np.zeros(3)

    def robot_yaw_rad(self):
        return 0.0


def test_drive_panel_joystick_springs_back_and_stops(server):
    studio = FakeStudio()
    with server.gui.add_folder("drive"):
        drive = DrivePanel(server, studio)
    try:
        drive.set_mode("test")
        assert studio.mode == "test"
        drive.hold(0, 1.0)
        drive.hold(2, -1.0)
        np.testing.assert_allclose(drive.command(), [0.5, 0.0, -1.0])
        drive.release(0, 1.0)  # released after a short press: a tap latches forward
        drive.release(2, -1.0)
        np.testing.assert_allclose(drive.command(), [0.5, 0.0, -1.0])
        drive.hold(1, 1.0)
        drive.stop_now()
        np.testing.assert_allclose(drive.command(), 0.0)
        assert isinstance(studio.link.sent[-1], msg.SetVelocityCommand) and studio.link.sent[-1].vx_mps == 0.0
        drive.speed.value = 0.25
        assert isinstance(studio.link.sent[-1], msg.SetPlaybackSpeed) and studio.link.sent[-1].speed == 0.25
    finally:
        drive._stop.set()


class FakeClock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_joystick_hold_lasts_until_release_even_with_slow_repeats():
    """Under software WebGL the browser's hold repeats can be a second apart: the hold must not drop out."""
    clock = FakeClock()
    joy = JoystickState(clock)
    joy.hold(0, 1.0)
    for _ in range(10):  # repeats 1.2 s apart (a 1 FPS browser)
        clock.t += 1.2
        np.testing.assert_allclose(joy.unit_command(), [1.0, 0.0, 0.0])
        joy.hold(0, 1.0)
    clock.t += 0.3
    joy.release(0, 1.0)  # a long hold ends at release and latches nothing
    np.testing.assert_allclose(joy.unit_command(), 0.0)


def test_joystick_hold_survives_a_slow_browsers_repeats_seconds_apart():
    """A 3x slower machine rendering software WebGL: repeats 3-4 s apart. The hold stays on between them,
    and its release (after a last gap longer than the fast-browser timeout) ends it without latching."""
    clock = FakeClock()
    joy = JoystickState(clock)
    joy.hold(2, 1.0)
    for gap in (1.5, 3.0, 3.5, 4.0, 2.5):
        for _ in range(int(gap / 0.5)):
            clock.t += 0.5
            np.testing.assert_allclose(joy.unit_command(), [0.0, 0.0, 1.0])
        clock.t += gap - 0.5 * int(gap / 0.5)
        joy.hold(2, 1.0)
    assert joy.hold_timeout_s >= 3 * 2.5
    clock.t += 3.0
    joy.release(2, 1.0)  # a hold, not a tap: nothing latches
    np.testing.assert_allclose(joy.unit_command(), 0.0)
    assert not joy.latched_any
    joy.hold(2, 1.0)  # a lost release still ends, within the longest timeout
    clock.t += HOLD_TIMEOUT_MAX_S + 0.1
    np.testing.assert_allclose(joy.unit_command(), 0.0)


def test_joystick_timeout_comes_back_down_when_the_browser_speeds_up():
    clock = FakeClock()
    joy = JoystickState(clock)
    joy.hold(0, 1.0)
    clock.t += 3.0
    joy.hold(0, 1.0)
    assert joy.hold_timeout_s == pytest.approx(9.0)
    for _ in range(200):  # 10 s of repeats at 20 Hz
        clock.t += 0.05
        joy.hold(0, 1.0)
    joy.release(0, 1.0)
    assert joy.hold_timeout_s == pytest.approx(HOLD_TIMEOUT_S)


def test_joystick_lost_release_times_out():
    clock = FakeClock()
    joy = JoystickState(clock)
    joy.hold(2, 1.0)
    clock.t += HOLD_TIMEOUT_S + 0.1
    np.testing.assert_allclose(joy.unit_command(), 0.0)
    joy.release(2, 1.0)  # the late release of a long press is not a tap: nothing latches
    np.testing.assert_allclose(joy.unit_command(), 0.0)
    assert not joy.latched_any


def test_joystick_tap_latches_and_toggles():
    clock = FakeClock()
    joy = JoystickState(clock)
    joy.hold(0, 1.0)
    clock.t += 0.1
    joy.release(0, 1.0)
    clock.t += 30.0  # a latch does not time out
    np.testing.assert_allclose(joy.unit_command(), [1.0, 0.0, 0.0])
    assert joy.latched_any
    joy.hold(0, -1.0)  # holding back overrides the latched forward while held
    np.testing.assert_allclose(joy.unit_command(), [-1.0, 0.0, 0.0])
    clock.t += 2.0
    joy.hold(0, -1.0)
    clock.t += 0.5
    joy.release(0, -1.0)  # a long hold takes manual control: the latch is cleared
    np.testing.assert_allclose(joy.unit_command(), 0.0)
    joy.release(2, 1.0)  # a click without a hold message (a very quick tap) latches too
    np.testing.assert_allclose(joy.unit_command(), [0.0, 0.0, 1.0])
    joy.release(2, 1.0)  # tapping the same button again releases it
    np.testing.assert_allclose(joy.unit_command(), 0.0)


def test_joystick_quick_click_seen_late_by_a_slow_browser_is_a_tap():
    """Software WebGL: a click's press and release reach the server a frame (~0.7 s) apart, with no
    hold repeat between — still a tap (it latches); a hold with repeats that long is not."""
    clock = FakeClock()
    joy = JoystickState(clock)
    joy.hold(0, 1.0)
    clock.t += 0.8
    joy.release(0, 1.0)
    np.testing.assert_allclose(joy.unit_command(), [1.0, 0.0, 0.0])
    joy.stop()
    joy.hold(0, 1.0)
    clock.t += 0.4
    joy.hold(0, 1.0)  # one repeat: the button was held
    clock.t += 0.4
    joy.release(0, 1.0)
    np.testing.assert_allclose(joy.unit_command(), 0.0)
    assert not joy.latched_any


def test_recovery_is_offered_only_for_edits_this_session_does_not_hold(session):
    from dataclasses import replace

    assert not session.recovery_available("neutral")  # a normal session: nothing to recover
    sample = session.style.samples["in_place"]
    wider = replace(sample, attributes=replace(sample.attributes, stance_width_m=0.3))
    assert session.apply(session.style.with_sample("in_place", wider), "wider").ok
    assert not session.recovery_available("neutral")  # its own autosave: the edits are right here
    assert session.open("casual").ok  # the edits of neutral stay in its recovery file …
    assert session.recovery_available("neutral")  # … and are offered
    copy = session.recovery_path("casual")
    copy.parent.mkdir(exist_ok=True)
    shutil.copy(session.folder / "casual.json", copy)  # an autosave identical to the file
    assert not session.recovery_available("casual")


def test_saved_styles_keep_ordinary_file_modes(session):
    import os

    shipped = (session.folder / "neutral.json").stat().st_mode & 0o777
    assert session.save_as("mine").ok
    umask = os.umask(0o022)
    os.umask(umask)
    assert (session.folder / "mine.json").stat().st_mode & 0o777 == 0o666 & ~umask
    os.chmod(session.folder / "neutral.json", 0o640)
    assert session.open("neutral").ok and session.save().ok
    assert (session.folder / "neutral.json").stat().st_mode & 0o777 == 0o640  # the replaced file's mode stays
    assert shipped & 0o444


def test_events_slider_spans_the_cycle_and_the_phase_bar_lines_up(server, session):
    from studio.panels.sample_editor import phase_bar_html, timeline_max_s

    assert timeline_max_s(0.8, 3.0) == pytest.approx(1.2) and timeline_max_s(2.5, 3.0) == 3.0
    with server.gui.add_folder("timeline"):
        editor = SampleEditor(server, session, Notes())
    cycle = session.style.samples["in_place"].intervals.cycle_s
    assert editor.timeline.max == pytest.approx(timeline_max_s(cycle, session.ctx.max_cycle_s))
    assert editor.timeline.max < session.ctx.max_cycle_s  # not 0–3 s with the handles in its left third
    bar = phase_bar_html(session.style.samples["in_place"].intervals, float(editor.timeline.max))
    assert "transparent" in bar  # the bar spans the slider: the part after the cycle is left empty
    editor.dropdown.value = "forward_fast"
    fast = session.style.samples["forward_fast"].intervals.cycle_s
    assert editor.timeline.max == pytest.approx(timeline_max_s(fast, session.ctx.max_cycle_s))


def test_plots_follow_the_engine_clock():
    from studio.panels.plots_panel import WINDOW_S, PlotsPanel

    srv = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    try:
        plots = PlotsPanel(srv)
        signals = {"sample_weights": np.eye(9)[2], "pelvis_z": np.array([0.7, 0.69]),
                   "pelvis_yaw": np.array([0.0, 0.01]), "feedback": np.array([0.0, 0.0, 0.01, 0.0, 1.0])}
        for k in range(400):  # 20 s of telemetry at 20 Hz, engine clock from 40 s
            plots.add(40.0 + 0.05 * k, {**signals, "recovery_share": np.array([0.25 if k >= 390 else 0.0])})
        plots.render()
        share = plots.feedback.data[4]  # the balance recovery's neutral share, last series of the feedback plot
        assert share[-1] == pytest.approx(0.25) and share[0] == 0.0
        t = plots.weights.data[0]
        assert t[-1] == pytest.approx(59.95) and t[0] >= 59.95 - WINDOW_S - 1e-9 and len(t) <= 120
        assert plots.weights.scales["x"]["range"] == pytest.approx((59.95 - WINDOW_S, 59.95))
        assert plots.tracking.scales["x"]["range"] == plots.weights.scales["x"]["range"]
    finally:
        srv.stop()


def test_status_line_names_a_balance_recovery():
    from studio.app import recovery_text

    assert recovery_text({}) == "" and recovery_text({"recovery_share": np.zeros(1, dtype=np.float32)}) == ""
    assert recovery_text({"recovery_share": np.array([0.35], dtype=np.float32)}) == \
        " · balance recovery: walking 35 % neutral"
    assert recovery_text({"recovery_share": np.array([0.35, 0.0], dtype=np.float32)}) == \
        " · balance recovery: walking 35 % neutral"
    # the walk's start from the neutral gait (engine/control/recovery_blend.py) is not called a recovery
    assert recovery_text({"recovery_share": np.array([1.0, 1.0], dtype=np.float32)}) == \
        " · starting from the neutral gait: walking 100 % neutral"
    assert recovery_text({"recovery_share": np.array([0.0, 1.0], dtype=np.float32)}) == ""
