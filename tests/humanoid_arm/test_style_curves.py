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
        expected = np.interp(knot_t / cycle_s, phase, q[:, k])
        if name == "a":
            expected = np.clip(expected, -0.5, 0.5)
        np.testing.assert_allclose(c.evaluate(knot_t), expected, atol=1e-9)
        assert c.evaluate(0.0) == pytest.approx(c.evaluate(cycle_s - 1e-12), abs=1e-6)  # periodic


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
    assert style.sample("in_place").curve("joints.right_shoulder_pitch_joint") != curve  # the original is untouched
    with pytest.raises(ValueError, match="not upper-body joints"):
        style_with_gesture(style, "in_place", t, q[:, :1], ("left_hip_pitch_joint",), 8, ctx)
    with pytest.raises(ValueError, match="knots"):
        gesture_curves(t, q, joints, 1.0, 1)
