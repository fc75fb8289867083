"""The style-space benchmark's generator: every style it draws passes validation, is authored
like an animator would (knots at least a tenth of their interval apart, every curve within the
rate and acceleration its channel follows), and really spreads over the validated ranges."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.gait.style import StyleContext, load_style, styles_dir, validate_style
from engine.gait.curve_rates import over_bound, rate_bound
from engine.gait.style_space import MIN_KNOT_PHASE, NoReachableStyle, random_reachable_style, random_style


@lru_cache(maxsize=None)
def robot_context(robot: str):
    ctx = StyleContext.for_robot(robot)
    return ctx, load_style(styles_dir(robot) / "neutral.json", ctx)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(robot=st.sampled_from(["g1", "talos"]), seed=st.integers(0, 2**32 - 1), extent=st.floats(0.0, 1.0))
def test_the_generator_only_produces_valid_styles(robot, seed, extent):
    ctx, neutral = robot_context(robot)
    style = random_style(np.random.default_rng(seed), ctx, neutral, extent)
    validate_style(style, ctx)  # raises StyleError on any violation
    for sample in style.samples.values():
        for channel, curve in sample.curves.items():
            assert over_bound(curve, rate_bound(channel, ctx)) <= 1.0, channel
            times = np.array([k.t_s for k in curve.knots])
            gaps = np.diff(np.append(times, times[0] + curve.duration_s) if curve.periodic else times)
            if len(times) > 1:
                assert gaps.min() >= MIN_KNOT_PHASE * curve.duration_s * (1 - 1e-9), channel


def test_the_generator_spans_the_validated_ranges():
    ctx, neutral = robot_context("g1")
    rng = np.random.default_rng(0)
    heights, widths, cycles = [], [], []
    for _ in range(20):
        style = random_style(rng, ctx, neutral, 1.0)
        for sample in style.samples.values():
            heights.append(sample.attributes.pelvis_height_m)
            widths.append(sample.attributes.stance_width_m)
            cycles.append(sample.intervals.cycle_s)
    lo, hi = ctx.pelvis_height_range_m
    assert min(heights) < lo + 0.1 * (hi - lo) and max(heights) > hi - 0.1 * (hi - lo)
    lo, hi = ctx.stance_width_range_m
    assert min(widths) < lo + 0.1 * (hi - lo) and max(widths) > hi - 0.1 * (hi - lo)
    assert max(cycles) > 0.8 * ctx.max_cycle_s
    # The same seed draws the same styles.
    a = random_style(np.random.default_rng(7), ctx, neutral).to_dict()
    assert a == random_style(np.random.default_rng(7), ctx, neutral).to_dict()


def test_swings_pulled_within_g1s_rate_bounds_still_lift_the_foot():
    """G1's curve-rate bounds are its shipped peaks: pulling a swing whose apex comes early down to
    them left the foot 8–9 mm off the floor (the check's "barely lifts"); the generator spreads the
    knots first. Near neutral (apex 50–70 mm drawn) every swing lifts at least MIN_SWING_APEX_M
    (without the spreading, these draw swings of 7.3 mm at extent 0 and 9.5 mm at 0.15)."""
    from engine.gait.style_space import MIN_SWING_APEX_M

    ctx, neutral = robot_context("g1")
    for extent in (0.0, 0.15):
        rng = np.random.default_rng(2)
        for _ in range(6):
            style = random_style(rng, ctx, neutral, extent)
            for name, sample in style.samples.items():
                for side in ("left", "right"):
                    apex = sample.curves[f"{side}_foot.z"].value_range()[1]
                    assert apex >= MIN_SWING_APEX_M, (extent, name, side, apex)


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(robot=st.sampled_from(["g1", "talos"]), seed=st.integers(0, 2**32 - 1), extent=st.floats(0.2, 1.0))
def test_the_reachable_generator_draws_valid_styles_the_predicate_accepts(robot, seed, extent):
    """A stand-in predicate (the bench's is the feasibility check's reach): every sample's pelvis in the upper
    half of the validated heights. Each sample of the drawn style passes it, and the style passes validation."""
    ctx, neutral = robot_context(robot)
    lo, hi = ctx.pelvis_height_range_m
    calls: list[str] = []

    def unreachable(style, sample):
        calls.append(sample)
        return style.samples[sample].attributes.pelvis_height_m < 0.5 * (lo + hi)

    style, draws = random_reachable_style(np.random.default_rng(seed), ctx, neutral, unreachable, extent)
    validate_style(style, ctx)
    assert all(s.attributes.pelvis_height_m >= 0.5 * (lo + hi) for s in style.samples.values())
    assert draws >= len(style.samples) and set(calls) == set(style.samples)
    again, _ = random_reachable_style(np.random.default_rng(seed), ctx, neutral, unreachable, extent)
    assert again.to_dict() == style.to_dict()  # the same seed, the same style


def test_the_reachable_generator_gives_up_on_a_space_it_never_reaches():
    ctx, neutral = robot_context("g1")
    try:
        random_reachable_style(np.random.default_rng(0), ctx, neutral, lambda style, sample: True, 1.0,
                               name="never", max_draws_per_sample=5, restarts=2)
    except NoReachableStyle as exc:
        assert "never" in str(exc) and "2 starts of up to 5 draws" in str(exc)
    else:
        raise AssertionError("expected NoReachableStyle")


def test_reachable_styles_pass_the_feasibility_checks_reach():
    """The bench's --space reachable: the drawn G1 style's every sample has no reach or clearance finding."""
    from engine.bench.styles import KINEMATIC_KINDS, style_jobs
    from engine.gait.feasibility import check_style
    from engine.robot.model import load_robot

    (style, job), = style_jobs("g1", 1, 3, 10.0, 1.0, "reachable")
    assert style.name == "reachable-3-0" and job["style"]["name"] == "reachable-3-0"
    assert not [f for f in check_style(load_robot("g1"), style) if f.kind in KINEMATIC_KINDS]
