"""The gait planner's invariants (paper §4): event ordering, footholds, stance, ground, C1."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.gait.planner import START_HOLD_S, GaitPlanner
from engine.gait.style import load_style
from tests.conftest import REPO
from tests.gait.strategies import g1_context, smooth_commands, styles

SETTINGS = settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
SOLE = (0.17, 0.055)
DT = 1.0 / 125.0


def run(style, command, seconds: float, dt: float = DT):
    planner = GaitPlanner(style, g1_context(), *SOLE)
    refs = []
    for k in range(int(round(seconds / dt))):
        refs.append(planner.step(dt, command((k + 1) * dt), with_preview=False))
    return planner, refs


@SETTINGS
@given(styles(), smooth_commands())
def test_contact_events_follow_the_walk_cycle(style, command):
    _, refs = run(style, command, 6.0)
    contact = np.array([r.contact for r in refs])
    assert contact.any(axis=1).all(), "never both feet in the air"
    changes = []
    for k in range(1, len(contact)):
        for i, side in enumerate(("L", "R")):
            if contact[k, i] != contact[k - 1, i]:
                changes.append(side + ("TD" if contact[k, i] else "LO"))
    cycle = ["LLO", "LTD", "RLO", "RTD"]
    assert len(changes) >= 8
    start = cycle.index(changes[0])
    assert changes == [cycle[(start + i) % 4] for i in range(len(changes))]


@SETTINGS
@given(styles(heel_toe=False), smooth_commands())
def test_swing_feet_land_exactly_on_their_footholds_and_stay(style, command):
    _, refs = run(style, command, 6.0)
    for k in range(1, len(refs)):
        for i, side in enumerate(("left", "right")):
            if refs[k].contact[i] and not refs[k - 1].contact[i]:  # touchdown
                hold = refs[k].footholds[side]
                np.testing.assert_allclose(refs[k].foot_pos[i], [hold.x, hold.y, 0.0], atol=1e-9)
                assert math.atan2(refs[k].foot_rot[i][1, 0], refs[k].foot_rot[i][0, 0]) == pytest.approx(
                    math.atan2(math.sin(hold.yaw), math.cos(hold.yaw)), abs=1e-9)


@SETTINGS
@given(styles(heel_toe=True), smooth_commands())
def test_flat_feet_do_not_move_and_soles_stay_above_ground(style, command):
    _, refs = run(style, command, 6.0)
    for k in range(len(refs)):
        assert refs[k].sole_corners[:, :, 2].min() >= -1e-4, "sole corner below the ground"
        if k == 0:
            continue
        for i in range(2):
            flat_now = refs[k].contact[i] and not refs[k].sole_corners[i, :, 2].any()
            flat_before = refs[k - 1].contact[i] and not refs[k - 1].sole_corners[i, :, 2].any()
            if flat_now and flat_before:
                np.testing.assert_allclose(refs[k].foot_pos[i], refs[k - 1].foot_pos[i], atol=1e-12)
                np.testing.assert_allclose(refs[k].foot_rot[i], refs[k - 1].foot_rot[i], atol=1e-12)
            # In support (flat or on a heel/toe edge) some corner touches the ground: no slip upward.
            if refs[k].contact[i]:
                assert refs[k].corner_contact[i].any()


def _max_velocity_jump(refs, dt):
    pos = np.array([np.concatenate([r.foot_pos.ravel(), [r.pelvis_z], r.upper_q]) for r in refs])
    vel = np.diff(pos, axis=0) / dt
    return np.abs(np.diff(vel, axis=0)).max()


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(styles(heel_toe=True), smooth_commands())
def test_reference_is_c1_while_the_command_changes_smoothly(style, command):
    """Velocity jumps shrink with the time step (a C1 signal's Δv ~ a·dt; a kink's would not).

    Compared at 2 ms and 0.25 ms: blending samples whose timing proportions differ a lot from
    the phase map's nominal ones makes the time warp steep (still C1) near contact events,
    which coarser steps cannot resolve. A kink keeps Δv at every step (ratio ≈ 1); a C1
    signal's shrinks toward 1/8.
    """
    coarse_dt, fine_dt = DT / 4, DT / 32
    _, coarse = run(style, command, 2.0, dt=coarse_dt)
    _, fine = run(style, command, 2.0, dt=fine_dt)
    jump_coarse = _max_velocity_jump(coarse, coarse_dt)
    jump_fine = _max_velocity_jump(fine, fine_dt)
    assert jump_fine < 0.6 * jump_coarse + 1e-6, (jump_coarse, jump_fine)
    assert _max_velocity_jump(run(style, command, 2.0, dt=DT)[1], DT) / DT < 600.0  # bounded differences at 125 Hz


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(styles(), styles(), st.floats(0.05, 3.0))
def test_live_edit_does_not_jump_the_feet(style_a, style_b, switch_s):
    planner = GaitPlanner(style_a, g1_context(), *SOLE)
    refs = []
    for k in range(int(4.0 / DT)):
        if abs(k * DT - switch_s) < DT / 2:
            planner.set_style(style_b)
        refs.append(planner.step(DT, np.array([0.2, 0.0, 0.1]), with_preview=False))
    pos = np.array([r.foot_pos for r in refs])
    speed = np.linalg.norm(np.diff(pos, axis=0), axis=2).max() / DT
    assert speed < 6.0, f"a foot jumped ({speed:.1f} m/s)"


@SETTINGS
@given(styles(), smooth_commands())
def test_sample_weights_are_convex(style, command):
    _, refs = run(style, command, 3.0)
    w = np.array([r.sample_weights for r in refs])
    assert (w >= 0).all() and np.allclose(w.sum(axis=1), 1.0)


def test_path_frame_follows_the_command():
    style = load_style(REPO / "styles/g1/neutral.json")
    planner, refs = run(style, lambda t: np.array([0.3, 0.0, 0.0]), 10.0)
    ease = 0.5 * START_HOLD_S  # the clock eases in from rest over the first START_HOLD_S
    assert refs[-1].path_pose[0] == pytest.approx(0.3 * (10.0 - ease), abs=5e-3)
    feet_x = refs[-1].foot_pos[:, 0].mean()
    assert 2.6 < feet_x < 3.4
    planner, refs = run(style, lambda t: np.array([0.0, 0.0, 0.5]), 6.0)
    assert refs[-1].path_pose[2] == pytest.approx(0.5 * (6.0 - ease), abs=5e-3)
    yaws = [math.atan2(r[1, 0], r[0, 0]) for r in refs[-1].foot_rot]
    assert abs(math.remainder(yaws[0] - refs[-1].path_pose[2], 2 * math.pi)) < 0.7


def test_impossible_command_is_clamped():
    style = load_style(REPO / "styles/g1/neutral.json")
    planner = GaitPlanner(style, g1_context(), *SOLE)
    ref = planner.step(DT, np.array([50.0, -3.0, float("nan")]))
    assert planner.command_clamped
    np.testing.assert_allclose(ref.command, [0.5, -0.15, 0.0])


def test_overlapping_foothold_is_projected_to_the_safe_region():
    style = load_style(REPO / "styles/g1/neutral.json")
    planner = GaitPlanner(style, g1_context(), *SOLE)
    # Strafing right hard while turning left would put the left foot onto/over the right one.
    _, refs = run(style, lambda t: np.array([0.0, -0.15, 1.0]), 8.0)
    for r in refs:
        left, right = r.footholds["left"], r.footholds["right"]
        local = right.to_local(left)
        assert local[1] >= 0.5 * SOLE[1] + 0.02 - 1e-9  # the left foot stays left of the right foot


def test_preview_covers_two_seconds_with_valid_polygons():
    style = load_style(REPO / "styles/g1/neutral.json")
    planner = GaitPlanner(style, g1_context(), *SOLE)
    for _ in range(100):
        ref = planner.step(DT, np.array([0.4, 0.0, 0.3]))
    phases = ref.preview
    assert phases[0].t_start_s == pytest.approx(ref.t_s) and phases[-1].t_end_s >= ref.t_s + 2.0
    for a, b in zip(phases, phases[1:]):
        assert a.t_end_s == pytest.approx(b.t_start_s)
    for p in phases:
        assert len(p.footholds) in (1, 2) and len(p.polygon) >= 4
        x, y = p.polygon[:, 0], p.polygon[:, 1]
        area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        assert area > 0  # counter-clockwise and not degenerate


def _heel_strike_style(pitch_rad: float):
    """G1 neutral with every swing ending on the heel (toe up by ``pitch_rad``) and rolling flat after."""
    import copy
    import json

    from engine.gait.style import style_from_dict

    data = json.loads((REPO / "styles/g1/neutral.json").read_text())
    for sample in data["samples"].values():
        lo, td = sample["intervals"]["left_swing_s"]
        dur = td - lo
        sample["attributes"]["touchdown_transition_s"] = 0.1
        for side in ("left", "right"):
            sample["curves"][f"{side}_foot.heel_pitch"] = copy.deepcopy(
                {"knots": [[0.0, 0.0, 0.0, 0.0, "flat"], [0.6 * dur, 0.0, 0.0, 0.0, "auto_clamped"],
                           [dur, -pitch_rad, 0.0, 0.0, "flat"]]})
    return style_from_dict(data, g1_context())


def _heel_edge_feet(phase) -> list[str]:
    """The feet of a double-support phase whose polygon vertices all lie on their heel strip."""
    from engine.gait.planner import EDGE_SUPPORT_DEPTH_M

    on_heel = []
    for side, hold in phase.footholds.items():
        c, s = math.cos(hold.yaw), math.sin(hold.yaw)
        d = phase.polygon - np.array([hold.x, hold.y])
        local = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])
        mine = (np.abs(local[:, 0]) <= 0.5 * SOLE[0] + 1e-9) & (np.abs(local[:, 1]) <= 0.5 * SOLE[1] + 1e-9)
        if mine.any() and (local[mine, 0] <= -0.5 * SOLE[0] + EDGE_SUPPORT_DEPTH_M + 1e-9).all():
            on_heel.append(side)
    return on_heel


@pytest.mark.parametrize("pitch_rad, rolling", [(0.0, 0), (0.3, 1)])
def test_preview_supports_a_heel_strike_on_the_heel_edge_only(pitch_rad, rolling):
    """While a foot rolls from its heel to flat after touchdown, only its heel edge touches the ground:
    the MPC's double-support polygon takes that strip of it, not the whole sole."""
    style = _heel_strike_style(pitch_rad) if pitch_rad else load_style(REPO / "styles/g1/neutral.json")
    planner = GaitPlanner(style, g1_context(), *SOLE)
    for _ in range(250):
        ref = planner.step(DT, np.array([0.4, 0.0, 0.0]))
    double = [p for p in ref.preview[1:] if len(p.footholds) == 2]
    assert double
    for p in double:
        assert len(_heel_edge_feet(p)) == rolling


def test_stance_width_edit_mid_step_keeps_the_stance_foot_and_the_timing():
    """The soak's live edit (issues 13/14): the in_place sample's stance width changed while stepping in
    place, sent as a whole style mid-swing. The cross-fade must not move the foot on the ground (its latched
    foothold, its reference and the MPC preview's support), nor the clock (contact events), and the swing
    target may only drift toward the new width, continuously; after the edit the feet stand at the new width."""
    from dataclasses import replace

    from engine.gait.style import style_from_dict, style_to_json_dict

    style = load_style(REPO / "styles/g1/neutral.json")
    sample = style.samples["in_place"]
    edited = style_from_dict(style_to_json_dict(style.with_sample(
        "in_place", replace(sample, attributes=replace(sample.attributes, stance_width_m=sample.attributes.stance_width_m + 0.02)))),
        g1_context(), expected_robot="g1")
    plain, edit = GaitPlanner(style, g1_context(), *SOLE), GaitPlanner(style, g1_context(), *SOLE)
    zero = np.zeros(3)
    edited_at = None
    stance_before = None
    checked = 0
    for k in range(int(6.0 / DT)):
        swinging_left = edit.in_swing("left", edit.phi)
        if edited_at is None and k * DT > 3.0 and swinging_left:  # mid-swing of the left foot
            edited_at = k
            stance_before = edit.latched["right"]
            edit.set_style(edited)
        a = plain.step(DT, zero)
        b = edit.step(DT, zero)
        assert b.phase == a.phase and (b.contact == a.contact).all(), "the edit moved the clock"
        if edited_at is not None and k - edited_at == checked and edit.in_swing("left", edit.phi):  # that swing
            checked += 1
            assert edit.latched["right"] == stance_before, "the edit moved the stance foot's foothold"
            assert np.abs(b.foot_pos[1] - a.foot_pos[1]).max() < 1e-9, "the edit moved the stance foot"
            stance_support = b.preview[0].footholds["right"]
            assert (stance_support.x, stance_support.y) == (stance_before.x, stance_before.y), \
                "the MPC's support is not the foot on the ground"
            drift = abs(edit.target["left"].y - plain.target["left"].y)
            assert drift <= 0.5 * 0.02 + 1e-9, f"the swing target moved {drift:.4f} m"
    assert edited_at is not None and checked > 5
    gap = lambda p: math.hypot(p.latched["left"].x - p.latched["right"].x, p.latched["left"].y - p.latched["right"].y)  # noqa: E731
    assert gap(plain) == pytest.approx(sample.attributes.stance_width_m, abs=2e-3)
    assert gap(edit) == pytest.approx(sample.attributes.stance_width_m + 0.02, abs=2e-3)


def test_gait_reference_field_order_is_what_evaluate_builds_positionally():
    """GaitPlanner.evaluate builds GaitReference positionally (keywords cost more per tick): inserting or reordering a
    field would silently shift its values, so the order is pinned here — update evaluate's call with it."""
    import dataclasses

    from engine.gait.planner import GaitReference

    assert [f.name for f in dataclasses.fields(GaitReference)] == [
        "t_s", "phase", "command", "sample_weights", "path_pose", "pelvis_z", "pelvis_z_rate", "pelvis_rot",
        "pelvis_ang_vel", "foot_pos", "foot_rot", "foot_lin_vel", "foot_ang_vel", "contact", "corner_contact",
        "sole_corners", "upper_q", "upper_qd", "footholds", "preview", "cycle_s", "swing_progress"]
