"""Mocap → style: a recorded span becomes periodic upper-body curves of one gait sample."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.gait.style import StyleContext, load_style, styles_dir, validate_style
from engine.retarget.humanoid_arm.style_curves import gesture_curves, style_with_gesture


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 32), st.floats(0.5, 2.0), st.integers(0, 10_000))
def test_curves_pass_through_the_recording_at_their_knots_and_loop(n_knots, cycle_s, seed):
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 3, 40))
    t = np.unique(t)
    q = rng.uniform(-1, 1, (len(t), 2))
    curves = gesture_curves(t, q, ["a", "b"], cycle_s, n_knots, {"a": (-0.5, 0.5)})
    phase = (t - t[0]) / (t[-1] - t[0])
    for k, name in enumerate(("a", "b")):
        c = curves[f"joints.{name}"]
        assert c.periodic and c.n_knots == n_knots and c.duration_s == pytest.approx(cycle_s)
        knot_t = np.arange(n_knots) / n_knots * cycle_s
        loop = q[:, k] - (phase - 0.5) * (q[-1, k] - q[0, k])  # the drift over the span taken out
        assert loop[0] == pytest.approx(loop[-1])  # start and end meet
        expected = np.interp(knot_t / cycle_s, phase, loop)
        if name == "a":
            expected = np.clip(expected, -0.5, 0.5)
        np.testing.assert_allclose(c.evaluate(knot_t), expected, atol=1e-9)
        assert c.evaluate(0.0) == pytest.approx(c.evaluate(cycle_s - 1e-12), abs=1e-6)  # periodic


@settings(max_examples=40, deadline=None)
@given(st.integers(4, 32), st.integers(0, 10_000))
def test_a_recording_that_ends_far_from_its_start_loops_without_a_jump(n_knots, seed):
    """The wrap from the last knot to the first is no steeper than the gesture itself: a 2 s recording of a
    shoulder rising 1 rad with a wave on top (0.1 rad) becomes a loop whose steepest slope is the wave's, not a jump of
    1 rad in the last knot interval."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2, 121)
    wave = 0.1 * np.sin(2 * np.pi * t * rng.uniform(0.5, 1.5) + rng.uniform(0, 2 * np.pi))
    q = (0.5 * t + wave)[:, None]  # rises 1 rad over the span
    cycle_s = 1.0
    c = gesture_curves(t, q, ["a"], cycle_s, n_knots)["joints.a"]
    tt = np.linspace(0, cycle_s, 2001)
    slope = np.abs(np.diff(c.evaluate(tt))) / np.diff(tt)
    # the raw data would jump back 0.8–1.2 rad in the last knot interval (a slope ≥ 0.8 n_knots rad/s); the wave
    # alone is at most 0.1 · 2π · 3 Hz ≈ 1.9 rad/s on the 1 s cycle (1.5 Hz over 2 s, stretched 2×)
    bound = 0.5 * n_knots if n_knots >= 8 else 2.5
    assert slope.max() < bound
    if n_knots >= 8:  # and the same curve without the loop closure does jump (so this test can fail)
        from engine.gait.curves import HermiteCurve, Knot

        phases = np.arange(n_knots) / n_knots
        raw = HermiteCurve([Knot(float(p * cycle_s), float(v)) for p, v in zip(phases, np.interp(phases, t / 2, q[:, 0]))],
                           cycle_s, True)
        assert (np.abs(np.diff(raw.evaluate(tt))) / np.diff(tt)).max() > bound


def test_a_recording_becomes_a_valid_style_edit_of_in_place():
    ctx = StyleContext.for_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json", ctx) if (styles_dir("g1") / "neutral.json").is_file() else None
    if style is None:
        pytest.skip("no g1 neutral style")
    joints = ("left_shoulder_pitch_joint", "left_elbow_joint", "right_shoulder_pitch_joint", "right_elbow_joint")
    t = np.linspace(0, 2, 41)
    q = np.stack([-0.5 + 0.3 * np.sin(2 * np.pi * t / 2), 0.8 + 0 * t, -1.2 + 0 * t, 0.5 + 0.2 * t], axis=1)
    new = style_with_gesture(style, "in_place", t, q, joints, 8, ctx)
    validate_style(new, ctx)
    curve = new.sample("in_place").curve("joints.right_shoulder_pitch_joint")
    assert curve is not None and curve.evaluate(0.0) == pytest.approx(-1.2)
    elbow = new.sample("in_place").curve("joints.right_elbow_joint")  # 0.5 → 0.9 over the span: a steady drift
    assert elbow is not None and np.ptp(elbow.evaluate(np.linspace(0, elbow.duration_s, 50))) < 1e-9  # the loop holds 0.7
    assert elbow.evaluate(0.0) == pytest.approx(0.7)
    assert style.sample("in_place").curve("joints.right_shoulder_pitch_joint") != curve  # the original is untouched
    with pytest.raises(ValueError, match="not upper-body joints"):
        style_with_gesture(style, "in_place", t, q[:, :1], ("left_hip_pitch_joint",), 8, ctx)
    with pytest.raises(ValueError, match="knots"):
        gesture_curves(t, q, joints, 1.0, 1)
