"""The curve editor's editing rules (engine/gait/curve_editing.py) against the validator: one source of truth.

Whatever a knot drag asks for, the curve it produces passes validation (the drag clamps to exactly
the range the validator enforces), and a value one step outside that range is refused by the validator.
"""

from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.gait.curve_editing import (
    Clipboard,
    all_channels,
    channel_interval,
    channel_limits,
    interval_duration,
    is_pinned,
    merge_knots,
    mirror_sign,
    move_knots,
    opposite_channel,
    paste_knots,
)
from engine.gait.curves import HermiteCurve, Knot, TangentMode
from engine.gait.style import StyleContext, StyleError, channel_value_range, load_style, validate_style
from engine.gait.velocity_sampler import SAMPLE_NAMES
from tests.conftest import REPO


@pytest.fixture(scope="module")
def g1() -> tuple[StyleContext, object]:
    return StyleContext.for_robot("g1"), load_style(REPO / "styles" / "g1" / "neutral.json")


def _curve_for(channel: str, sample, ctx: StyleContext) -> HermiteCurve:
    """The sample's curve on ``channel``, or a small valid one (three knots) when it has none."""
    existing = sample.curve(channel)
    if existing is not None:
        return existing
    d = interval_duration(sample, channel_interval(channel))
    if channel_interval(channel) == "cycle":
        v = 0.0 if not channel.startswith("joints.") else ctx.standing_angles.get(channel.split(".", 1)[1], 0.0)
        return HermiteCurve([Knot(0.0, v), Knot(0.5 * d, v)], d, periodic=True)
    flat = TangentMode.FLAT
    return HermiteCurve([Knot(0.0, 0.0, mode=flat), Knot(0.5 * d, 0.0), Knot(d, 0.0, mode=flat)], d, periodic=False)


def test_editor_limits_are_the_validators_ranges(g1):
    ctx, style = g1
    sample = style.sample(SAMPLE_NAMES[0])
    for channel in all_channels(ctx):
        value_range = channel_value_range(channel, sample.attributes.pelvis_height_m, ctx)
        assert value_range is not None, channel
        assert channel_limits(channel, sample, ctx) == value_range[:2]
        lo, hi = value_range[:2]
        assert lo < hi and math.isfinite(lo) and math.isfinite(hi), channel


def test_a_swing_roll_drag_stops_at_the_ankle_roll_joints_range(g1):
    """The editor clamps a swing foot's roll where G1's ankle roll joint stops (±0.262 rad: the validator's
    robot-level bound, engine/gait/leg_reach.py), not at the generic foot-angle bound."""
    ctx, style = g1
    sample = style.sample("forward_slow")
    lo, hi = channel_limits("right_foot.roll", sample, ctx)
    assert (lo, hi) == pytest.approx((-0.2618, 0.2618), abs=1e-4)
    curve = _curve_for("right_foot.roll", sample, ctx)
    moved, notes = move_knots("right_foot.roll", curve, [1], 0.0, 0.5, (lo, hi))
    assert moved.knots[1].value == pytest.approx(hi) and any("clamped" in n for n in notes)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), dv=st.floats(-5.0, 5.0), dt_frac=st.floats(-0.5, 0.5))
def test_a_drag_anywhere_yields_a_valid_style(g1, data, dv, dt_frac):
    ctx, style = g1
    name = data.draw(st.sampled_from(SAMPLE_NAMES))
    sample = style.sample(name)
    channel = data.draw(st.sampled_from(all_channels(ctx)))
    curve = _curve_for(channel, sample, ctx)
    movable = [i for i in range(curve.n_knots) if not is_pinned(channel, i, curve.n_knots)]
    if not movable:
        return
    idx = data.draw(st.sampled_from(movable))
    moved, notes = move_knots(channel, curve, [idx], dt_frac * curve.duration_s, dv,
                              channel_limits(channel, sample, ctx))
    lo, hi = channel_limits(channel, sample, ctx)
    assert lo - 1e-9 <= moved.knots[idx].value <= hi + 1e-9
    if abs(dv) > (hi - lo) * 2:
        assert any("clamped" in n for n in notes)
    # the moved knot is inside the range; the curve between knots may overshoot (Hermite), so the
    # validator's verdict is checked on a curve whose every knot is flat (no overshoot).
    flat = HermiteCurve([Knot(k.t_s, k.value, mode=TangentMode.FLAT) for k in moved.knots], moved.duration_s,
                        moved.periodic)
    validate_style(style.with_sample(name, sample.with_curve(channel, flat)), ctx)


@pytest.mark.parametrize("channel", ["left_foot.z", "left_foot.y", "left_foot.roll", "pelvis.z", "pelvis.roll",
                                     "joints.left_elbow_joint"])
def test_one_step_past_the_editor_limit_is_refused_by_the_validator(g1, channel):
    ctx, style = g1
    name = SAMPLE_NAMES[0]
    sample = style.sample(name)
    curve = _curve_for(channel, sample, ctx)
    lo, hi = channel_limits(channel, sample, ctx)
    idx = next(i for i in range(curve.n_knots) if not is_pinned(channel, i, curve.n_knots))
    k = curve.knots[idx]
    over = curve.with_knot_moved(idx, k.t_s, hi + 0.01)
    flat = HermiteCurve([Knot(q.t_s, q.value, mode=TangentMode.FLAT) for q in over.knots], over.duration_s,
                        over.periodic)
    with pytest.raises(StyleError):
        validate_style(style.with_sample(name, sample.with_curve(channel, flat)), ctx)


def test_paste_to_the_other_side_mirrors_and_merges(g1):
    ctx, style = g1
    sample = style.sample("forward_fast")
    src = _curve_for("left_foot.y", sample, ctx)
    clip = Clipboard("left_foot.y", "forward_fast", src.duration_s, src.periodic, src.knots, whole=True)
    target = opposite_channel("left_foot.y")
    assert target == "right_foot.y"
    d = interval_duration(sample, channel_interval(target))
    pasted = paste_knots(clip, target, d, mirror=True, half_cycle=False)
    assert [p.t_s for p in pasted] == sorted(p.t_s for p in pasted)
    assert pasted[-1].t_s == pytest.approx(d)
    sign = mirror_sign("left_foot.y")
    assert sign == -1.0
    for a, b in zip(src.knots, pasted):
        assert b.value == pytest.approx(sign * a.value)
    merged = merge_knots(target, sample.curve(target), pasted[1:-1] or pasted, d)
    assert merged.n_knots >= 2 and merged.duration_s == pytest.approx(d)
