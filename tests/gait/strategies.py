"""Hypothesis strategies: random *valid* gait samples and styles for G1, and smooth commands."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from hypothesis import strategies as st

from engine.gait.curves import HermiteCurve, Knot, TangentMode
from engine.gait.style import Attributes, GaitSample, Intervals, Style, StyleContext
from engine.gait.velocity_sampler import SAMPLE_NAMES, SampleVelocities

FLAT = TangentMode.FLAT


@lru_cache(maxsize=None)
def g1_context() -> StyleContext:
    return StyleContext.for_robot("g1")


@st.composite
def intervals(draw, ctx: StyleContext | None = None) -> Intervals:
    ctx = ctx or g1_context()
    ss, ds = ctx.min_single_support_s, ctx.min_double_support_s
    left = draw(st.floats(ss, 0.7))
    right = draw(st.floats(ss, 0.7))
    ds1 = draw(st.floats(ds, 0.3))
    ds2 = draw(st.floats(ds, 0.3))
    cycle = left + ds1 + right + ds2
    return Intervals(cycle, (0.0, left), (left + ds1, left + ds1 + right))


def _swing_curve(duration: float, inner: list[tuple[float, float]]) -> HermiteCurve:
    knots = [Knot(0.0, 0.0, mode=FLAT)] + [Knot(f * duration, v) for f, v in inner] + [Knot(duration, 0.0, mode=FLAT)]
    return HermiteCurve(knots, duration)


@st.composite
def gait_samples(draw, heel_toe: bool = True, ctx: StyleContext | None = None) -> GaitSample:
    ctx = ctx or g1_context()
    iv = draw(intervals(ctx))
    curves: dict[str, HermiteCurve] = {}
    for side in ("left", "right"):
        d = iv.swing_duration_s(side)
        peak = draw(st.floats(0.3, 0.7))
        curves[f"{side}_foot.z"] = _swing_curve(d, [(peak, draw(st.floats(0.02, 0.15)))])
        if draw(st.booleans()):
            curves[f"{side}_foot.x"] = _swing_curve(d, [(0.5, draw(st.floats(-0.05, 0.05)))])
        if draw(st.booleans()):
            curves[f"{side}_foot.y"] = _swing_curve(d, [(0.5, draw(st.floats(-0.03, 0.03)))])
        if draw(st.booleans()):
            curves[f"{side}_foot.roll"] = _swing_curve(d, [(0.5, draw(st.floats(-0.25, 0.25)))])  # (G1 ankle roll ±0.262)
        if draw(st.booleans()):
            curves[f"{side}_foot.yaw"] = _swing_curve(d, [(0.5, draw(st.floats(-0.3, 0.3)))])
        if heel_toe and draw(st.booleans()):
            toe = draw(st.floats(0.0, 0.6))
            heel = draw(st.floats(-0.6, 0.0))
            curves[f"{side}_foot.toe_pitch"] = HermiteCurve(
                [Knot(0.0, toe, mode=FLAT), Knot(0.5 * d, 0.0, mode=FLAT), Knot(d, 0.0, mode=FLAT)], d)
            curves[f"{side}_foot.heel_pitch"] = HermiteCurve(
                [Knot(0.0, 0.0, mode=FLAT), Knot(0.5 * d, 0.0, mode=FLAT), Knot(d, heel, mode=FLAT)], d)
    period = iv.cycle_s
    if draw(st.booleans()):
        amp = draw(st.floats(0.0, 0.02))
        curves["pelvis.z"] = HermiteCurve([Knot(0.0, amp), Knot(0.25 * period, -amp), Knot(0.5 * period, amp),
                                           Knot(0.75 * period, -amp)], period, periodic=True)
    if draw(st.booleans()):
        amp = draw(st.floats(0.0, 0.15))
        curves["pelvis.yaw"] = HermiteCurve([Knot(0.1 * period, amp), Knot(0.6 * period, -amp)], period, periodic=True)
    if draw(st.booleans()):
        joint = "left_shoulder_pitch_joint"
        lo, hi = ctx.joint_limits[joint]
        a, b = draw(st.floats(max(lo, -1.0), min(hi, 1.0))), draw(st.floats(max(lo, -1.0), min(hi, 1.0)))
        curves[f"joints.{joint}"] = HermiteCurve([Knot(0.0, a), Knot(0.5 * period, b)], period, periodic=True)
    lo_w, hi_w = ctx.stance_width_range_m
    lo_z, hi_z = ctx.pelvis_height_range_m
    attrs = Attributes(
        stance_width_m=draw(st.floats(max(lo_w, 0.2), min(hi_w, 0.32))),
        stance_splay_rad=draw(st.floats(-0.3, 0.3)),
        stance_x_bias_m=draw(st.floats(-0.08, 0.08)),
        liftoff_transition_s=draw(st.floats(0.0, 0.2)),
        touchdown_transition_s=draw(st.floats(0.0, 0.2)),
        pelvis_height_m=draw(st.floats(lo_z + 0.03, hi_z - 0.03)),
    )
    return GaitSample(iv, attrs, curves)


@st.composite
def styles(draw, heel_toe: bool = True) -> Style:
    samples = {name: draw(gait_samples(heel_toe)) for name in SAMPLE_NAMES}
    return Style("random", "g1", SampleVelocities(0.5, 0.25, 0.15, 1.0), samples, blend_eta=draw(st.floats(0.0, 1.0)))


@st.composite
def smooth_commands(draw, v: SampleVelocities = SampleVelocities(0.5, 0.25, 0.15, 1.0)):
    """A smooth command path: sums of slow sinusoids within the style's limits."""
    amps = [draw(st.floats(0.0, 1.0)) for _ in range(3)]
    freqs = [draw(st.floats(0.05, 0.4)) for _ in range(3)]
    phases = [draw(st.floats(0.0, 2 * math.pi)) for _ in range(3)]
    lims = (v.x_max_mps, v.y_max_mps, v.yaw_max_radps)

    def command(t: float) -> np.ndarray:
        return np.array([a * lim * math.sin(2 * math.pi * f * t + p) for a, lim, f, p in zip(amps, lims, freqs, phases)])

    return command
