"""The function-curve editor, driven headless through the same handlers its viser callbacks call."""

from __future__ import annotations

import math
import shutil
import time
from types import SimpleNamespace

import numpy as np
import pytest
import viser

from engine.gait.curves import TangentMode
from engine.gait.style import StyleContext, validate_style
from engine.gait import curve_editing as rules
from studio.panels.curve_editor import appearance as look
from studio.panels import typing_pause
from studio.panels.curve_editor import interaction
from studio.panels.curve_editor.interaction import SerialWorker
from studio.panels.curve_editor import CurveEditor, KnotRef
from studio.style_session import StyleSession
from tests.conftest import REPO, free_port

SWING = "left_foot.z"
SHOULDER = "joints.left_shoulder_pitch_joint"
ELBOW = "joints.left_elbow_joint"


@pytest.fixture(scope="module")
def g1_ctx() -> StyleContext:
    return StyleContext.for_robot("g1")


def _session(robot: str, ctx: StyleContext, tmp_path) -> StyleSession:
    shutil.copy(REPO / "styles" / robot / "neutral.json", tmp_path / "neutral.json")
    session = StyleSession(robot=robot, ctx=ctx, folder=tmp_path)
    assert session.open("neutral").ok
    return session


@pytest.fixture
def server():
    srv = viser.ViserServer(host="127.0.0.1", port=free_port(), verbose=False)
    yield srv
    srv.stop()


@pytest.fixture
def session(g1_ctx, tmp_path) -> StyleSession:
    return _session("g1", g1_ctx, tmp_path)


@pytest.fixture
def editor(server, session, monkeypatch):
    monkeypatch.setattr(interaction, "PREVIEW_PERIOD_S", 0.0)  # every drag update also applies a preview
    monkeypatch.setattr(typing_pause, "TYPING_PAUSE_S", 0.0)  # typed values apply at once
    ed = CurveEditor(server, session)
    yield ed
    ed.close()


def event(phase: str, start, end, client=None):
    return SimpleNamespace(phase=phase, start_position=np.asarray(start), end_position=np.asarray(end), client=client)


def drag_knot(ed: CurveEditor, ref: KnotRef, t_s: float, value: float, steps: int = 3) -> None:
    """Mouse drag of a knot to (t, value): start on the knot, a few updates, release."""
    start = ed.knot_world_position(ref)
    goal = ed.world_position(ref.channel, t_s, value)
    ed.handle_knot_drag(ref, event("start", start, start))
    for s in range(1, steps + 1):
        ed.handle_knot_drag(ref, event("update", start, start + (goal - start) * s / steps))
    ed.handle_knot_drag(ref, event("end", start, goal))


def drag_handle(ed: CurveEditor, side: str, t_s: float, value: float) -> None:
    start = ed.handle_world_position(side)
    goal = ed.world_position(ed.primary.channel, t_s, value)
    ed.handle_tangent_drag(side, event("start", start, start))
    ed.handle_tangent_drag(side, event("update", start, (start + goal) / 2))
    ed.handle_tangent_drag(side, event("end", start, goal))


def curve(session: StyleSession, channel: str, sample: str = "forward_fast"):
    return session.style.sample(sample).curve(channel)


# ----------------------------------------------------------------------------- graph view


def test_graph_shows_the_swing_curve_framed_with_knots_and_pinned_boundaries(editor, session):
    assert editor.sample == "forward_fast" and editor.active_channel == SWING and editor.interval == "left"
    t_lo, t_hi, v_lo, v_hi = editor.view
    d = session.style.sample("forward_fast").intervals.swing_duration_s("left")
    assert t_lo < 0.0 and t_hi > d and t_hi - t_lo < 1.2 * d  # the interval's extent, small margins
    assert v_lo < 0.0 < 0.07 < v_hi < 0.09  # value range of left_foot.z (0 .. 0.07) with padding
    assert editor._curves.visible and len(editor._curves.points) > 50
    keys = sorted(editor._knots.nodes)
    assert len(keys) == 3 and sum(k.endswith("_pin") for k in keys) == 2  # liftoff/touchdown drawn pinned
    x, z = editor.graph_point(SWING, 0.14, 0.07)
    node = editor._knots.nodes["left_foot_z_1_key"]
    assert np.allclose(node.position, (x, 0.0, z))
    ticks = [n.text for k, n in editor._labels.nodes.items() if k.startswith("t") and editor._labels.cache.get((k, "visible"))]
    assert "0.10" in ticks and "0.20" in ticks


def test_channel_list_checkboxes_show_colours_and_frame_all_covers_every_visible_curve(editor, session):
    assert editor.channel_checkboxes[SWING].label == "🟦 z · 3 keys"  # z is blue, as in Maya
    box = editor.channel_checkboxes[SHOULDER]
    assert box.label == "⬜ left_shoulder_pitch_joint · 4 keys"  # hidden joints have no colour yet
    box.value = True  # a cycle channel: the view switches to the cycle
    assert editor.interval == "cycle" and editor.visible_channels == (SHOULDER,)
    editor.channel_checkboxes[ELBOW].value = True
    editor.channel_checkboxes["joints.right_shoulder_pitch_joint"].value = True
    editor.channel_checkboxes["pelvis.z"].value = True
    shown = editor.visible_channels
    assert len(shown) == 4 and len({editor.color_of(ch)[0] for ch in shown}) == 4  # all distinct
    assert box.label.split()[0] in "🟥🟩🟦🟧🟪🟫⬛" and editor.color_of(SHOULDER)[1] == box.label.split()[0]
    editor.channel_checkboxes["joints.right_shoulder_pitch_joint"].value = False
    editor.channel_checkboxes["pelvis.z"].value = False
    assert set(editor.visible_channels) == {SHOULDER, ELBOW}
    assert "rgb" in editor.legend_md.content and ELBOW in editor.legend_md.content
    t_lo, t_hi, v_lo, v_hi = editor.view
    cycle = session.style.sample("forward_fast").intervals.cycle_s
    assert math.isclose(t_lo, -0.5 * cycle) and math.isclose(t_hi, 1.5 * cycle)  # one neighbour half each side
    lo = min(curve(session, SHOULDER).value_range()[0], curve(session, ELBOW).value_range()[0])
    hi = max(curve(session, SHOULDER).value_range()[1], curve(session, ELBOW).value_range()[1])
    assert v_lo < lo and v_hi > hi and (v_hi - v_lo) < 1.5 * (hi - lo)
    editor.normalize_checkbox.value = True  # mixed ranges: each curve scaled to the view
    assert editor.view[2] == pytest.approx(-1.24) and editor.view[3] == pytest.approx(1.24)  # ±1 plus 12 % padding
    for ch in (SHOULDER, ELBOW):
        lo, hi = curve(session, ch).value_range()
        assert editor._to_view(ch, lo) == pytest.approx(-1.0) and editor._to_view(ch, hi) == pytest.approx(1.0)
    editor.channel_checkboxes[SWING].value = True  # back to the left swing hides the cycle channels
    assert editor.interval == "left" and editor.visible_channels == (SWING,)


def test_cyclic_view_draws_neighbour_periods_faint_and_knots_only_in_the_main_period(editor, session):
    editor.set_active_channel(SHOULDER)
    colors = editor._curves.colors.reshape(-1, 3)
    main = tuple(look._linear_u8(editor.color_of(SHOULDER)[0]))
    faint = tuple(look._linear_u8(look._blend(editor.color_of(SHOULDER)[0], look.INTERVAL_BG, 0.65)))
    found = {tuple(c) for c in colors}
    assert main in found and faint in found
    pts = editor._curves.points.reshape(-1, 3)
    x0, _ = editor.graph_point(SHOULDER, 0.0, 0.0)
    x1, _ = editor.graph_point(SHOULDER, 0.7, 0.0)
    faint_x = pts[np.all(colors == faint, axis=1)][:, 0]
    assert (faint_x < x0 + 1e-6).any() and (faint_x > x1 - 1e-6).any()  # before and after the cycle
    assert len([k for k in editor._knots.nodes if k.startswith("joints_left_shoulder")]) == 4  # main period only


def test_playhead_line_and_conversion_from_cycle_time(editor, session):
    editor.set_playhead(0.1)
    x, _ = editor.graph_point(SWING, 0.1, 0.0)
    assert editor._playhead_line.visible and editor._playhead_line.position[0] == pytest.approx(x)
    assert editor._playhead_label.text == "0.100 s"
    editor.set_playhead(None)
    assert not editor._playhead_line.visible
    assert editor.playhead_from_cycle_time(0.1) == pytest.approx(0.1)
    assert editor.playhead_from_cycle_time(0.5) is None  # left foot in stance
    editor.set_active_channel("right_foot.z")
    assert editor.playhead_from_cycle_time(0.45) == pytest.approx(0.1)  # right swing starts at 0.35 s


# ----------------------------------------------------------------------------- dragging


def test_dragging_a_knot_edits_the_style_live_and_leaves_one_undo_entry(editor, session):
    before = curve(session, SWING)
    ref = KnotRef(SWING, 1)
    node = editor._knots.nodes["left_foot_z_1_key"]
    start = editor.knot_world_position(ref)
    goal = editor.world_position(SWING, 0.16, 0.09)
    editor.handle_knot_drag(ref, event("start", start, start))
    editor.handle_knot_drag(ref, event("update", start, (start + goal) / 2))
    assert editor._ghost.visible  # faint copy of the curve as it was
    mid = curve(session, SWING).knots[1]
    assert mid.t_s == pytest.approx(0.15, abs=1e-6) and mid.value == pytest.approx(0.08, abs=1e-6)  # live preview
    editor.handle_knot_drag(ref, event("update", start, goal))
    editor.handle_knot_drag(ref, event("end", start, goal))
    k = curve(session, SWING).knots[1]
    assert k.t_s == pytest.approx(0.16, abs=1e-6) and k.value == pytest.approx(0.09, abs=1e-6)
    assert editor._knots.nodes["left_foot_z_1_key"] is node  # moved in place, not recreated
    assert np.allclose(node.position, (*editor.graph_point(SWING, k.t_s, k.value)[:1], 0.0,
                                       editor.graph_point(SWING, k.t_s, k.value)[1]))
    assert not editor._ghost.visible
    assert session.undo_labels() == ["move 1 knot(s) on left_foot.z"]
    validate_style(session.style, session.ctx)
    editor.undo_button.value = True
    assert curve(session, SWING) == before and session.can_redo
    editor.redo_button.value = True
    assert curve(session, SWING).knots[1].value == pytest.approx(0.09, abs=1e-6)


def test_swing_boundary_knots_are_pinned(editor, session):
    before = curve(session, SWING)
    drag_knot(editor, KnotRef(SWING, 0), 0.05, 0.04)
    assert curve(session, SWING) == before and not session.can_undo
    assert "swing boundary" in editor.status
    # pitch channels: boundary value may move, clamped to the channel's range (heel −π/2..0)
    editor.set_active_channel("left_foot.heel_pitch")
    editor.set_playhead(0.1)
    assert editor.add_knot_at_playhead().ok
    editor.frame_all()
    drag_knot(editor, KnotRef("left_foot.heel_pitch", 0), 0.05, 0.5)  # up: clamped to 0
    k0 = curve(session, "left_foot.heel_pitch").knots[0]
    assert k0.t_s == 0.0 and k0.value == 0.0
    drag_knot(editor, KnotRef("left_foot.heel_pitch", 0), 0.05, -0.3)
    k0 = curve(session, "left_foot.heel_pitch").knots[0]
    assert k0.t_s == 0.0 and k0.value == pytest.approx(-0.3, abs=1e-6)
    validate_style(session.style, session.ctx)


def test_drags_are_clamped_to_the_interval_neighbours_and_limits_with_a_message(editor, session):
    d = 0.28
    drag_knot(editor, KnotRef(SWING, 1), 0.5, 0.05)  # beyond touchdown
    k = curve(session, SWING).knots[1]
    assert k.t_s < d and k.t_s == pytest.approx(d - 1e-3)
    assert "clamped" in editor.status and "swing" in editor.status
    drag_knot(editor, KnotRef(SWING, 1), 0.1, -0.05)  # below the ground
    assert curve(session, SWING).knots[1].value == 0.0 and "clamped" in editor.status
    editor.set_active_channel(SHOULDER)
    drag_knot(editor, KnotRef(SHOULDER, 3), 0.9, 0.03)  # past the end of the cycle
    k3 = curve(session, SHOULDER).knots[3]
    assert 0.455 < k3.t_s < 0.7 and "cycle" in editor.status
    editor.set_active_channel(ELBOW)
    drag_knot(editor, KnotRef(ELBOW, 3), 0.63, 5.0)  # above the elbow's joint limit
    lo, hi = session.ctx.joint_limits["left_elbow_joint"]
    assert curve(session, ELBOW).knots[3].value == pytest.approx(hi)
    validate_style(session.style, session.ctx)


def test_a_refused_edit_snaps_back_with_the_validators_message(editor, session, server):
    base = session.style
    editor.select([KnotRef(SWING, 1)])
    # a steep tangent drags the curve below the ground before the peak: the session refuses
    drag_handle(editor, "in", 0.13, -0.2)
    assert session.style is base and not session.can_undo
    assert "swing height" in editor.status and "snapped back" in editor.status
    assert editor.notices and "swing height" in editor.notices[-1]
    assert curve(session, SWING).knots[1].mode is TangentMode.AUTO_CLAMPED
    # the drawn knot is back where the style has it
    x, z = editor.graph_point(SWING, 0.14, 0.07)
    assert np.allclose(editor._knots.nodes["left_foot_z_1_key"].position, (x, 0.0, z))


def test_tangent_handles_set_slopes_aligned_or_free(editor, session):
    editor.set_active_channel(ELBOW)
    editor.handle_knot_click(KnotRef(ELBOW, 1))  # t=0.28 v=0.65, auto-clamped (flat: local min)
    out = editor.handle_world_position("out")
    assert out is not None and editor._handles["out"].visible
    cps = curve(session, ELBOW).bezier_control_points()
    assert np.allclose(out, editor.world_position(ELBOW, *cps[1, 1]))  # the Bézier control point P1
    drag_handle(editor, "out", 0.28 + 0.175 / 3, 0.65 + 0.5 * 0.175 / 3)  # slope +0.5
    k = curve(session, ELBOW).knots[1]
    assert k.mode is TangentMode.ALIGNED and k.in_slope == pytest.approx(0.5, abs=1e-6) == k.out_slope
    editor.tangent_dropdown.value = "free (broken)"
    assert curve(session, ELBOW).knots[1].mode is TangentMode.FREE
    drag_handle(editor, "in", 0.28 - 0.175 / 3, 0.65 + 1.0 * 0.175 / 3)  # slope −1 on the in side only
    k = curve(session, ELBOW).knots[1]
    assert k.in_slope == pytest.approx(-1.0, abs=1e-6) and k.out_slope == pytest.approx(0.5, abs=1e-6)
    assert len(session.undo_labels()) == 3
    validate_style(session.style, session.ctx)


def test_tangent_modes_from_the_dropdown_and_auto_clamped_never_overshoots(editor, session):
    editor.set_active_channel(SHOULDER)
    editor.select([KnotRef(SHOULDER, 0)])
    editor.tangent_dropdown.value = "flat"
    k = curve(session, SHOULDER).knots[0]
    assert k.mode is TangentMode.FLAT and k.in_slope == 0.0 == k.out_slope
    editor.tangent_dropdown.value = "linear"
    c = curve(session, SHOULDER)
    ks = c.knots
    assert ks[0].out_slope == pytest.approx((ks[1].value - ks[0].value) / (ks[1].t_s - ks[0].t_s))
    editor.tangent_dropdown.value = "aligned"
    assert curve(session, SHOULDER).knots[0].mode is TangentMode.ALIGNED
    editor.select_all()
    assert editor.tangent_dropdown.value == "(mixed)"
    editor.tangent_dropdown.value = "auto-clamped"
    c = curve(session, SHOULDER)
    assert all(k.mode is TangentMode.AUTO_CLAMPED for k in c.knots)
    vals = [k.value for k in c.knots]
    lo, hi = c.value_range()
    assert lo >= min(vals) - 1e-12 and hi <= max(vals) + 1e-12  # no overshoot between keys
    # pinned swing boundaries stay flat
    editor.set_active_channel(SWING)
    editor.select([KnotRef(SWING, 0)])
    assert not editor.set_tangent_mode(TangentMode.LINEAR).ok
    assert curve(session, SWING).knots[0].mode is TangentMode.FLAT


def test_typed_time_and_value(editor, session):
    editor.handle_knot_click(KnotRef(SWING, 1))
    assert editor.time_input.value == pytest.approx(0.14) and not editor.time_input.disabled
    editor.value_input.value = 0.05
    editor.time_input.value = 0.12
    k = curve(session, SWING).knots[1]
    assert (k.t_s, k.value) == pytest.approx((0.12, 0.05))
    editor.time_input.value = 0.9  # outside the swing: clamped
    assert curve(session, SWING).knots[1].t_s < 0.28 and "clamped" in editor.status
    editor.handle_knot_click(KnotRef(SWING, 0))
    assert editor.time_input.disabled and editor.value_input.disabled


# ----------------------------------------------------------------------------- knots


def test_add_knot_at_playhead_and_on_empty_channels(editor, session):
    assert not editor.add_knot_at_playhead().ok and "playhead" in editor.status
    editor.set_playhead(0.07)
    expected = curve(session, SWING).evaluate(0.07)
    editor.add_button.value = True  # the GUI button
    c = curve(session, SWING)
    assert c.n_knots == 4 and c.knots[1].t_s == pytest.approx(0.07) and c.knots[1].value == pytest.approx(expected)
    assert editor.selection == (KnotRef(SWING, 1),)
    assert not editor.add_knot_at_playhead().ok  # a knot exists there already
    editor.set_active_channel("left_foot.x")  # no curve yet: a new one with pinned boundaries
    assert editor.add_knot_at_playhead().ok
    assert [k.t_s for k in curve(session, "left_foot.x").knots] == pytest.approx([0.0, 0.07, 0.28])
    editor.set_active_channel("pelvis.z")
    editor.set_playhead(0.8)  # cycle time wraps (0.8 mod 0.7)
    assert editor.add_knot_at_playhead().ok
    assert curve(session, "pelvis.z").knots[0].t_s == pytest.approx(0.1)
    validate_style(session.style, session.ctx)


def test_delete_keeps_pinned_boundaries(editor, session):
    editor.select([KnotRef(SWING, 0), KnotRef(SWING, 1)])
    editor.delete_button.value = True
    c = curve(session, SWING)
    assert c.n_knots == 2 and "pinned" in editor.status
    editor.select([KnotRef(SWING, 1)])
    assert not editor.delete_selected().ok and curve(session, SWING).n_knots == 2
    editor.set_active_channel(SHOULDER)
    editor.select_all()
    assert editor.delete_selected().ok
    assert curve(session, SHOULDER) is None  # an empty cycle channel holds its default again


def test_box_select_and_group_move(editor, session):
    editor.set_active_channel(SHOULDER)
    editor.show_channel(ELBOW)
    position, look_at, up = editor.camera_pose(fov=0.9, aspect=1.6)
    z = (look_at - position) / np.linalg.norm(look_at - position)
    y = -up / np.linalg.norm(up)
    wxyz = viser.transforms.SO3.from_matrix(np.stack([np.cross(y, z), y, z], axis=1)).wxyz
    camera = SimpleNamespace(position=position, wxyz=wxyz, fov=0.9, aspect=1.6)
    uv0 = look.project_to_screen(editor.knot_world_position(KnotRef(SHOULDER, 0)), position, wxyz, 0.9, 1.6)
    uv1 = look.project_to_screen(editor.knot_world_position(KnotRef(SHOULDER, 1)), position, wxyz, 0.9, 1.6)
    # a rectangle around the first two knots (t = 0.105, 0.28) of both channels
    picked = editor.select_in_screen_rect(camera, (uv0[0] - 0.01, 0.0), (uv1[0] + 0.01, 1.0))
    assert set(picked) == {KnotRef(SHOULDER, 0), KnotRef(SHOULDER, 1), KnotRef(ELBOW, 0), KnotRef(ELBOW, 1)}
    before = {ch: curve(session, ch).knots for ch in (SHOULDER, ELBOW)}
    drag_knot(editor, KnotRef(SHOULDER, 1), 0.28 + 0.03, 0.47 + 0.05)
    for ch in (SHOULDER, ELBOW):
        after = curve(session, ch).knots
        for i in (0, 1):
            assert after[i].t_s == pytest.approx(before[ch][i].t_s + 0.03, abs=1e-6)
            assert after[i].value == pytest.approx(before[ch][i].value + 0.05, abs=1e-6)
        for i in (2, 3):  # unselected knots stay (their auto slopes follow the moved neighbours)
            assert (after[i].t_s, after[i].value) == (before[ch][i].t_s, before[ch][i].value)
    assert len(session.undo_labels()) == 1
    # a big group move: each knot clamps on its own, order is kept
    drag_knot(editor, KnotRef(SHOULDER, 1), 0.9, 0.52)
    ts = [k.t_s for k in curve(session, SHOULDER).knots]
    assert ts == sorted(ts) and ts[1] < 0.455 and ts[0] < ts[1]
    assert ts[0] > 0.31  # moved far side first: the left knot travels past the right one's old time


def test_copy_paste_left_to_right_and_to_another_sample(editor, session):
    drag_knot(editor, KnotRef(SWING, 1), 0.1, 0.09)
    editor.deselect_button.value = True  # nothing selected: Copy takes the whole curve
    editor.copy_button.value = True
    assert editor.clipboard.whole and "curve" in editor.clipboard_md.content
    editor.paste_other_button.value = True
    left, right = curve(session, SWING), curve(session, "right_foot.z")
    assert np.allclose([(k.t_s, k.value) for k in right.knots], [(k.t_s, k.value) for k in left.knots])
    assert editor.active_channel == "right_foot.z" and editor.interval == "right"
    editor.set_sample("forward_slow")  # 0.32 s swing: times rescale
    editor.set_active_channel(SWING)
    editor.paste_button.value = True
    slow = curve(session, SWING, "forward_slow")
    assert slow.knots[1].t_s == pytest.approx(0.1 * 0.32 / 0.28) and slow.knots[1].value == pytest.approx(0.09)
    # arms: copy the left shoulder, paste onto the right half a cycle later
    editor.set_sample("forward_fast")
    editor.set_active_channel(SHOULDER)
    drag_knot(editor, KnotRef(SHOULDER, 1), 0.28, 0.6)
    editor.clear_selection()
    editor.copy()
    assert editor.paste(to_other_side=True).ok
    l, r = curve(session, SHOULDER), curve(session, "joints.right_shoulder_pitch_joint")
    ts = np.linspace(0.0, 0.7, 29)
    assert np.allclose(r.evaluate(ts), l.evaluate(ts - 0.35))
    # a selection of knots pastes into the target's time span, keeping the rest
    editor.set_active_channel(SWING)
    editor.select([KnotRef(SWING, 1)])
    editor.copy()
    assert not editor.clipboard.whole
    editor.set_sample("in_place")
    assert editor.paste().ok
    ks = curve(session, SWING, "in_place").knots  # merged: the existing peak at 0.18 s stays
    assert [k.t_s for k in ks] == pytest.approx([0.0, 0.1 * 0.36 / 0.28, 0.18, 0.36])
    assert ks[1].value == pytest.approx(0.09) and editor.selection == (KnotRef(SWING, 1),)
    validate_style(session.style, session.ctx)


def test_mirror_negates_lateral_channels_and_cross_kind_paste_is_refused(editor, session):
    editor.set_active_channel("left_foot.y")
    editor.set_playhead(0.14)
    editor.add_knot_at_playhead()
    editor.frame_all()
    drag_knot(editor, KnotRef("left_foot.y", 1), 0.14, 0.03)
    editor.copy()
    assert editor.paste(to_other_side=True, mirror=True).ok
    assert curve(session, "right_foot.y").knots[1].value == pytest.approx(-0.03, abs=1e-6)
    editor.set_active_channel("pelvis.z")
    result = editor.paste()
    assert not result.ok and "swing" in result.message


# ----------------------------------------------------------------------------- session, undo, robustness


def test_undo_redo_from_elsewhere_redraws_and_keyboard_snippet_targets_the_buttons(editor, session):
    drag_knot(editor, KnotRef(SWING, 1), 0.14, 0.05)
    assert not editor.undo_button.disabled and editor.redo_button.disabled
    session.undo()  # e.g. another panel
    x, z = editor.graph_point(SWING, 0.14, 0.07)
    assert np.allclose(editor._knots.nodes["left_foot_z_1_key"].position, (x, 0.0, z))
    assert editor.undo_button.disabled and not editor.redo_button.disabled
    html = editor.keys_html.content
    assert editor.undo_button._impl.uuid in html and editor.redo_button._impl.uuid in html
    assert "onerror=" in html and "keydown" in html


def test_frame_selected_and_sample_switch(editor, session):
    editor.select([KnotRef(SWING, 1)])
    editor.frame_selected_button.value = True
    t_lo, t_hi, v_lo, v_hi = editor.view
    assert t_lo < 0.14 < t_hi and (t_hi - t_lo) < 0.28 and v_lo < 0.07 < v_hi
    editor.sample_dropdown.value = "in_place"
    assert editor.sample == "in_place" and editor.selection == ()
    assert editor.view[1] > 0.36  # reframed to the 0.36 s swing


def test_callbacks_are_guarded(editor, session):
    def boom() -> None:
        raise RuntimeError("boom")

    assert editor._guarded(boom) is None
    assert "boom" in editor.status and editor._drag is None
    drag_knot(editor, KnotRef(SWING, 1), 0.14, 0.05)  # still works afterwards
    assert curve(session, SWING).knots[1].value == pytest.approx(0.05, abs=1e-6)


def test_serial_worker_keeps_order_and_coalesces_updates():
    worker = SerialWorker("test")
    seen: list[str] = []
    gate = __import__("threading").Event()
    worker.post(lambda: (gate.wait(2), seen.append("start")))
    for i in range(5):
        worker.post(lambda i=i: seen.append(f"update{i}"), key="update")
    worker.post(lambda: seen.append("end"))
    gate.set()
    assert worker.wait_idle(2)
    worker.close()
    assert seen == ["start", "update4", "end"]


def test_real_drag_callbacks_reach_the_editor_in_order(editor, session, server):
    """The async on_drag callbacks registered on the knot nodes queue to the editor's worker."""
    ref = KnotRef(SWING, 1)
    node = editor._knots.nodes["left_foot_z_1_key"]
    callback = node._impl.drag_cb[0].callback
    start, goal = editor.knot_world_position(ref), editor.world_position(SWING, 0.15, 0.06)
    loop = __import__("asyncio").new_event_loop()
    for phase, end in (("start", start), ("update", goal), ("end", goal)):
        loop.run_until_complete(callback(event(phase, start, end)))
    loop.close()
    assert editor.wait_idle(5)
    k = curve(session, SWING).knots[1]
    assert (k.t_s, k.value) == pytest.approx((0.15, 0.06), abs=1e-6)


def test_camera_pose_sees_the_graph_head_on(editor):
    editor.root_frame.position = (1.0, 2.0, 0.3)
    editor.root_frame.wxyz = viser.transforms.SO3.from_z_radians(0.5).wxyz
    position, look_at, up = editor.camera_pose(fov=0.9, aspect=1.5)
    normal = viser.transforms.SO3.from_z_radians(0.5).as_matrix() @ np.array([0.0, -1.0, 0.0])
    assert np.allclose((position - look_at) / np.linalg.norm(position - look_at), normal)
    assert np.allclose(up, (0, 0, 1))
    # the drag math uses the moved frame: a knot's world position maps back onto the graph
    ref = KnotRef(SWING, 1)
    w = editor.knot_world_position(ref)
    assert np.allclose(editor._plane_point(w, None), editor.graph_point(SWING, 0.14, 0.07))


def test_works_for_talos(server, tmp_path, monkeypatch):
    monkeypatch.setattr(interaction, "PREVIEW_PERIOD_S", 0.0)
    session = _session("talos", StyleContext.for_robot("talos"), tmp_path)
    ed = CurveEditor(server, session)
    try:
        drag_knot(ed, KnotRef(SWING, 1), ed._curve(SWING).knots[1].t_s, 0.05)
        assert curve(session, SWING).knots[1].value == pytest.approx(0.05, abs=1e-6)
        arm = "joints.arm_left_1_joint"
        ed.set_active_channel(arm)
        assert rules.opposite_channel(arm) == "joints.arm_right_1_joint"
        ed.copy()
        assert ed.paste(to_other_side=True).ok
        validate_style(session.style, session.ctx)
    finally:
        ed.close()


def test_pure_helpers():
    ticks, dec = look.nice_ticks(-0.014, 0.294, 8)
    assert ticks == pytest.approx([0.0, 0.05, 0.1, 0.15, 0.2, 0.25]) and dec == 2
    assert rules.opposite_channel("pelvis.yaw") is None and rules.opposite_channel("joints.waist_yaw_joint") is None
    assert rules.mirror_sign("left_foot.y") == -1.0 and rules.mirror_sign("left_foot.z") == 1.0
    assert look.project_to_screen((0, 0, 1), (0, 0, 0), (1, 0, 0, 0), 1.0, 1.0) == pytest.approx((0.5, 0.5))


def test_a_drag_goes_on_past_the_view_and_keeps_to_one_axis(editor, session):
    """Issue 16: the knot follows the pointer past the graph's range (the range grows to show it), and a
    vertical drag keeps the knot's time, a horizontal one its value."""
    ref = KnotRef(SWING, 1)
    k0 = curve(session, SWING).knots[1]
    v_top = editor.view[3]
    hi = rules.channel_limits(SWING, session.style.sample("forward_fast"), session.ctx)[1]
    target = min(k0.value + 2.5 * (v_top - k0.value), hi - 1e-3)  # far above the top of the view
    assert target > v_top + 0.01
    drag_knot(editor, ref, k0.t_s + 0.002, target, steps=4)  # up, with a slight sideways wobble
    k1 = curve(session, SWING).knots[1]
    assert k1.value == pytest.approx(target, abs=1e-6) and k1.t_s == k0.t_s
    assert editor.view[3] > k1.value, "the view did not grow to show the dragged knot"
    x, z = editor.graph_point(SWING, k1.t_s, k1.value)
    assert 0.0 <= z <= editor.height_m
    drag_knot(editor, ref, k1.t_s + 0.03, k1.value + 0.001)  # sideways: the value stays
    k2 = curve(session, SWING).knots[1]
    assert k2.t_s == pytest.approx(k1.t_s + 0.03, abs=1e-6) and k2.value == k1.value


def test_the_axis_lock_follows_the_pointer_on_the_canvas(editor, session):
    """A drag straight up the canvas keeps the knot's time even when its point on the graph plane went
    sideways too (the studio's copy of the camera lags the browser's; a graph seen at an angle): the user
    aims along the screen. A diagonal on the canvas moves both."""
    ref = KnotRef(SWING, 1)
    k0 = curve(session, SWING).knots[1]
    start = editor.knot_world_position(ref)
    up = editor.world_position(SWING, k0.t_s + 0.02, k0.value + 0.01)  # on the plane: diagonal enough...
    (x0, z0), (x1, z1) = editor.graph_point(SWING, k0.t_s, k0.value), editor.graph_point(SWING, k0.t_s + 0.02,
                                                                                          k0.value + 0.01)
    assert abs(z1 - z0) < interaction.AXIS_LOCK_RATIO * abs(x1 - x0)  # ...that the plane alone would not lock

    def ev(phase, end, screen_end):
        return SimpleNamespace(phase=phase, start_position=np.asarray(start), end_position=np.asarray(end),
                               start_screen_pos=(0.5, 0.5), end_screen_pos=screen_end, client=None)

    editor.handle_knot_drag(ref, ev("start", start, (0.5, 0.5)))
    editor.handle_knot_drag(ref, ev("update", up, (0.5, 0.3)))  # ...but straight up on the canvas
    editor.handle_knot_drag(ref, ev("end", up, (0.5, 0.3)))
    k1 = curve(session, SWING).knots[1]
    assert k1.t_s == k0.t_s and k1.value == pytest.approx(k0.value + 0.01, abs=1e-6)
    start = editor.knot_world_position(ref)
    side = editor.world_position(SWING, k1.t_s + 0.02, k1.value + 0.01)
    editor.handle_knot_drag(ref, ev("start", start, (0.5, 0.5)))
    editor.handle_knot_drag(ref, ev("end", side, (0.6, 0.4)))  # 45° on the canvas: both axes move
    k2 = curve(session, SWING).knots[1]
    assert k2.t_s == pytest.approx(k1.t_s + 0.02, abs=1e-6) and k2.value == pytest.approx(k1.value + 0.01, abs=1e-6)


def test_switching_to_an_empty_channel_clears_the_knot_fields(editor, session):
    editor.handle_knot_click(KnotRef(SWING, 1))
    assert editor.value_input.value == pytest.approx(curve(session, SWING).knots[1].value, abs=1e-6)
    editor.set_active_channel("left_foot.x")  # no curve
    assert editor.primary is None and editor.value_input.value == 0.0 and editor.value_input.disabled


def test_typed_values_apply_once_when_the_keys_pause(server, session, monkeypatch):
    # a pause long enough that three assignments in a row never span it, even on a loaded machine
    monkeypatch.setattr(typing_pause, "TYPING_PAUSE_S", 1.5)
    ed = CurveEditor(server, session)
    try:
        ed.handle_knot_click(KnotRef(SWING, 1))
        for typed in (0.0, 0.05, 0.055):  # keystrokes "0", ".05", "5"
            ed.value_input.value = typed
        assert session.undo_labels() == []  # nothing applied while typing
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and not session.undo_labels():
            time.sleep(0.05)
        assert session.undo_labels() == [f"set knot on {SWING}"]  # one edit, the last value
        assert curve(session, SWING).knots[1].value == pytest.approx(0.055)
    finally:
        ed.close()
