"""Curve rates are part of what is feasible (issue 13): the exact peaks of a curve's rate and
acceleration, the shipped styles within their channels' bounds, and a knot pair too close for its
change flagged by the feasibility check with the curve and the phase."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from engine.gait.curve_rates import curve_peaks, over_bound, rate_bound
from engine.gait.curves import HermiteCurve, Knot, TangentMode
from engine.gait.style import StyleContext, load_style, styles_dir, validate_style
from engine.robot.config import CurveRateLimits
from tests.conftest import REPO

SHIPPED = [("g1", "neutral"), ("g1", "casual"), ("g1", "sneak"), ("g1", "injured"), ("talos", "neutral")]


@example(times=[0.0, 0.38624570659643104, 0.3875149965673141], values=[1.0, 0.0, -1.0, 0.0, 0.0], periodic=True)
@settings(max_examples=60, deadline=None)
@given(times=st.lists(st.floats(0.0, 0.99), min_size=2, max_size=5, unique=True),
       values=st.lists(st.floats(-1.0, 1.0), min_size=5, max_size=5), periodic=st.booleans())
def test_the_peaks_are_the_densely_sampled_maxima(times, values, periodic):
    times = sorted(times)
    if min(np.diff(times)) < 1e-3:
        return
    curve = HermiteCurve([Knot(t, v) for t, v in zip(times, values)], 1.0, periodic=periodic)
    peaks = curve_peaks(curve)
    t = np.linspace(0.0, 1.0, 20001)[:-1] if periodic else np.linspace(times[0], times[-1], 20001)
    # the second derivative is linear on each segment, so its peak is a one-sided limit at a knot: sample both
    # sides of every knot too (a grid point on a knot reads one side only)
    near = np.concatenate([np.asarray(times) - 1e-9, np.asarray(times) + 1e-9])
    near = np.mod(near, 1.0) if periodic else near[(near >= times[0]) & (near <= times[-1])]
    # and every segment densely on its own: a segment 1.3 ms long got 25 grid points, and the sampled rate peak
    # read 0.1 % under the exact one
    ends = list(times) + ([times[0] + 1.0] if periodic else [])
    inside = np.concatenate([np.linspace(a, b, 2001) for a, b in zip(ends, ends[1:])])
    inside = np.mod(inside, 1.0) if periodic else inside
    t = np.concatenate([t, near, inside])
    rate = np.abs(curve.derivative(t))
    accel = np.abs(curve.second_derivative(t))
    assert peaks.rate >= rate.max() - 1e-9 and peaks.rate <= rate.max() * 1.001 + 1e-6
    assert peaks.accel >= accel.max() - 1e-9 and peaks.accel <= accel.max() * 1.01 + 1e-6


@pytest.mark.parametrize(("robot", "name"), SHIPPED, ids=lambda x: x)
def test_shipped_styles_are_within_their_channels_bounds(robot, name):
    """Within the robot's own bounds (robots/<name>.toml [gait.curve_rates]: no false alarm), and
    within half the default bounds (twice the shipped peaks)."""
    ctx = StyleContext.for_robot(robot)
    defaults = dataclasses.replace(ctx, curve_rates=CurveRateLimits())
    style = load_style(REPO / "styles" / robot / f"{name}.json", ctx)
    for sample_name, sample in style.samples.items():
        for channel, curve in sample.curves.items():
            assert over_bound(curve, rate_bound(channel, ctx)) <= 1.0, (sample_name, channel)
            over = over_bound(curve, rate_bound(channel, defaults))
            # twice the shipped peaks: the steepest shipped curve uses about half its bound
            assert over <= 0.55, (sample_name, channel, over)


def test_g1_bounds_are_about_its_shipped_peaks():
    """G1's bounds are its shipped styles' peaks rounded up: for each kind of channel, the steepest
    shipped curve uses at least 90 % of its bound (at twice the peaks, random styles fell)."""
    ctx = StyleContext.for_robot("g1")
    steepest: dict[str, float] = {}
    for name in ("neutral", "casual", "sneak", "injured"):
        style = load_style(REPO / "styles" / "g1" / f"{name}.json", ctx)
        for sample in style.samples.values():
            for channel, curve in sample.curves.items():
                head, _, tail = channel.partition(".")
                kind = head if head in ("pelvis", "joints") else f"foot {'position' if tail in 'xyz' else 'angle'}"
                kind = "pelvis.z" if channel == "pelvis.z" else kind
                steepest[kind] = max(steepest.get(kind, 0.0), over_bound(curve, rate_bound(channel, ctx)))
    assert set(steepest) == {"foot position", "foot angle", "pelvis", "pelvis.z", "joints"}
    assert all(0.9 <= v <= 1.0 for v in steepest.values()), steepest


def test_a_knot_pair_too_close_is_flagged_with_the_curve_and_the_phase():
    """The bench's random-2-0 in small: a foot yaw that turns 0.15 rad in 6 ms mid-swing. The
    validator accepts it (a file with it still loads); the check names the curve and the phase."""
    from engine.gait.feasibility import check_style
    from engine.robot.model import load_robot

    ctx = StyleContext.for_robot("g1")
    neutral = load_style(styles_dir("g1") / "neutral.json", ctx)
    sample = neutral.samples["in_place"]
    d = sample.intervals.swing_duration_s("left")
    yaw = HermiteCurve([Knot(0.0, 0.0, mode=TangentMode.FLAT), Knot(0.5 * d, -0.058), Knot(0.5 * d + 0.006, 0.097),
                        Knot(d, 0.0, mode=TangentMode.FLAT)], d)
    style = neutral.with_sample("in_place", sample.with_curve("left_foot.yaw", yaw))
    validate_style(style, ctx)
    findings = [f for f in check_style(load_robot("g1"), style, samples=("in_place",)) if f.kind == "curve_rate"]
    assert len(findings) == 1 and findings[0].side == "left_foot.yaw", [f.text() for f in findings]
    start, end = sample.intervals.swing_s("left")
    cycle = sample.intervals.cycle_s
    assert 100 * start / cycle <= findings[0].phase_pct <= 100 * end / cycle
    assert "left_foot.yaw" in findings[0].text() and "further apart" in findings[0].message
    # The same change over a third of the swing is within the bound: not flagged.
    slow = HermiteCurve([Knot(0.0, 0.0, mode=TangentMode.FLAT), Knot(0.33 * d, -0.058), Knot(0.66 * d, 0.097),
                         Knot(d, 0.0, mode=TangentMode.FLAT)], d)
    style = neutral.with_sample("in_place", dataclasses.replace(sample, curves={**sample.curves, "left_foot.yaw": slow}))
    assert not [f for f in check_style(load_robot("g1"), style, samples=("in_place",)) if f.kind == "curve_rate"]


def test_an_arm_faster_than_its_joint_is_flagged():
    """A joint curve's rate bound is the joint's velocity limit in the robot model (TALOS arm 1: 2.7 rad/s)."""
    from engine.gait.feasibility import check_style
    from engine.robot.model import load_robot

    ctx = StyleContext.for_robot("talos")
    neutral = load_style(styles_dir("talos") / "neutral.json", ctx)
    sample = neutral.samples["forward_slow"]
    cycle = sample.intervals.cycle_s
    joint = "arm_left_1_joint"
    lo, hi = ctx.joint_limits[joint]
    centre = ctx.standing_angles[joint]
    step = 0.5 if hi - centre > centre - lo else -0.5  # toward the farther limit
    swing = HermiteCurve([Knot(0.0, centre), Knot(0.1 * cycle, centre + step), Knot(0.2 * cycle, centre)], cycle, periodic=True)
    assert rate_bound(f"joints.{joint}", ctx).rate == pytest.approx(2.7)
    style = neutral.with_sample("forward_slow", sample.with_curve(f"joints.{joint}", swing))
    validate_style(style, ctx)
    findings = [f for f in check_style(load_robot("talos"), style, samples=("forward_slow",)) if f.kind == "curve_rate"]
    assert findings and findings[0].side == f"joints.{joint}" and 0.0 <= findings[0].phase_pct <= 20.0, \
        [f.text() for f in findings]


def test_the_bench_judges_only_the_samples_the_sweep_reaches():
    """The sweep walks backward at x_slow: a finding in reverse_fast says nothing about it."""
    from engine.bench.styles import reached_samples, totals

    style = load_style(styles_dir("g1") / "neutral.json")
    assert reached_samples(style, "sweep", 8.0) == {"forward_fast", "forward_slow", "in_place"}
    assert "reverse_fast" not in reached_samples(style, "sweep", 60.0)
    assert {"left_turn", "right_turn", "left_strafe", "right_strafe", "reverse_slow"} <= reached_samples(style, "sweep", 60.0)
    rows = [{"fell": True, "flagged": False}, {"fell": False, "flagged": True, "slip_mm": 1.0, "cop_in": 1.0, "over_rating": True},
            {"fell": False, "flagged": False, "slip_mm": 3.0, "cop_in": 1.0, "over_rating": False}]
    total = totals(rows, "g1", 0)
    assert total["fell"] == "walked 2/3" and total["flagged"] == "silent falls 1/1, false alarms 1/2"
    assert total["over_rating"] == "walked above a rated joint speed 1/2"
