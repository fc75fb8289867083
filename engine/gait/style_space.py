"""Random styles over the validated style space (the style-space benchmark's generator).

Every field the validator bounds is drawn between the robot's neutral value and the
validator's bounds: ``extent = 1`` spans the whole validated range of every field, a smaller
extent shrinks each range toward neutral by that factor (``extent = 0`` is neutral with fresh
random curves of zero amplitude). What is drawn, per sample (each of the nine independently):

* timings — cycle T_S in [2 (min single + min double support), max_cycle_s], then the
  swings and double supports as random shares of it that respect the minimum durations;
* attributes — stance width, splay, x-bias, liftoff/touchdown heel-toe transitions, pelvis height;
* swing curves — height (apex time and value up to max_swing_height_m), x/y offsets, yaw,
  roll (within the ankle roll joint's range: the validator's robot-level bound), and heel/toe
  pitch with the contact rule (heel or toe at zero at each switch);
* cycle curves — pelvis height offset and yaw/pitch/roll, every upper-body joint within its
  limits, periodic, 1–3 knots;
* the style's sample velocities (drawn within [0.5, 1.5] × neutral scaled by ``extent``, x_slow <
  x_max, and below the speed at which a sample's step leaves the legs' reach — the validator's step
  bound, engine/gait/leg_reach.py: there the range is drawn below that speed) and the blend gain η.

Drawn with a numpy Generator: the same seed gives the same styles.

:func:`random_reachable_style` draws from the part of that space the legs can reach: a sample whose
reference no leg posture follows (a caller's predicate, the feasibility check's reach and clearance
findings in ``studio bench styles --space reachable``) is drawn again, with the same rules, until one
is reachable. Over the whole validated range (``extent = 1``) about one G1 sample in eight passes (one
TALOS sample in twenty):
the ranges are per field, and their combinations mostly ask for feet out of reach (README, issue 13).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from engine.gait.curve_rates import RateBound, over_bound, rate_bound
from engine.gait.curves import HermiteCurve, Knot, TangentMode
from engine.gait.style import (
    MAX_SPLAY_RAD,
    MAX_TRANSITION_S,
    MAX_X_BIAS_M,
    MAX_FOOT_ANGLE_RAD,
    MAX_FOOT_OFFSET_M,
    MAX_PELVIS_ANGLE_RAD,
    MAX_PELVIS_Z_OFFSET_M,
    SIDES,
    Attributes,
    StyleError,
    GaitSample,
    Intervals,
    VELOCITY_FIELD,
    Style,
    StyleContext,
    channel_value_range,
    validate_style,
)
from engine.gait.leg_reach import max_reachable_speed
from engine.gait.velocity_sampler import SAMPLE_NAMES, SampleVelocities

EDGE = 1e-6  # stay this far inside closed bounds (rounding in the JSON round trip)
# What an animator authors: knots at least this share of their interval apart (swing or cycle),
# and curves that change no faster than their channel follows (engine/gait/curve_rates.py; drawn
# to this share of the bound so a JSON round trip stays within it).
MIN_KNOT_PHASE = 0.1
RATE_SHARE = 0.98
# A swing height pulled within its rate bound still lifts the foot this high where it can: below it the
# feasibility check flags "barely lifts" (engine/gait/feasibility.py MIN_CLEARANCE_M), which an animator
# would not author; its interior knots are then spread evenly over the swing first (the check's advice:
# "move its knots further apart"). G1's bounds (≈ its shipped peaks) pulled swings of 20–40 mm rising at
# 15 % of the swing down to 8–9 mm (README, *Curve rates*).
MIN_SWING_APEX_M = 0.01


def _around(rng: np.random.Generator, centre: float, lo: float, hi: float, extent: float) -> float:
    """Uniform in [centre − extent (centre − lo), centre + extent (hi − centre)]."""
    centre = min(max(centre, lo), hi)
    a, b = centre - extent * (centre - lo), centre + extent * (hi - centre)
    return float(rng.uniform(a + EDGE, b - EDGE)) if b - a > 2 * EDGE else centre


def random_intervals(rng: np.random.Generator, ctx: StyleContext, neutral: Intervals, extent: float) -> Intervals:
    ss, ds = ctx.min_single_support_s, ctx.min_double_support_s
    shortest = 2.0 * (ss + ds)
    cycle = _around(rng, neutral.cycle_s, shortest + 4 * EDGE, ctx.max_cycle_s, extent)
    slack = cycle - shortest  # shared out among the four phases
    n_ltd, n_rlo, n_rtd, _ = neutral.events_s
    n_shares = np.array([n_ltd - ss, n_rlo - n_ltd - ds, n_rtd - n_rlo - ss, neutral.cycle_s - n_rtd - ds])
    n_shares = np.clip(n_shares, 1e-3, None)
    n_shares /= n_shares.sum()
    random_shares = rng.dirichlet(np.ones(4))
    shares = (1.0 - extent) * n_shares + extent * random_shares
    lengths = np.array([ss, ds, ss, ds]) + slack * shares
    t_ltd = lengths[0]
    t_rlo = t_ltd + lengths[1]
    t_rtd = t_rlo + lengths[2]
    return Intervals(round(cycle, 6), (0.0, round(t_ltd, 6)), (round(t_rlo, 6), round(t_rtd, 6)))


def random_attributes(rng: np.random.Generator, ctx: StyleContext, neutral: Attributes, extent: float) -> Attributes:
    return Attributes(
        stance_width_m=_around(rng, neutral.stance_width_m, *ctx.stance_width_range_m, extent),
        stance_splay_rad=_around(rng, neutral.stance_splay_rad, -MAX_SPLAY_RAD, MAX_SPLAY_RAD, extent),
        stance_x_bias_m=_around(rng, neutral.stance_x_bias_m, -MAX_X_BIAS_M, MAX_X_BIAS_M, extent),
        liftoff_transition_s=_around(rng, neutral.liftoff_transition_s, 0.0, MAX_TRANSITION_S, extent),
        touchdown_transition_s=_around(rng, neutral.touchdown_transition_s, 0.0, MAX_TRANSITION_S, extent),
        pelvis_height_m=_around(rng, neutral.pelvis_height_m, *ctx.pelvis_height_range_m, extent),
    )


def _spaced_times(rng: np.random.Generator, n: int, lo: float, hi: float, gap: float) -> np.ndarray:
    """``n`` sorted uniform times in [lo, hi] at least ``gap`` apart (uniform over such sets)."""
    free = (hi - lo) - (n - 1) * gap
    if free <= 0.0:
        return np.linspace(lo, hi, n)
    return lo + np.sort(rng.uniform(0.0, free, n)) + gap * np.arange(n)


def _within_rates(curve: HermiteCurve, centre: float, bound: RateBound) -> HermiteCurve:
    """The curve with its knot values pulled toward ``centre`` until its rate and acceleration are
    within ``bound`` (a Hermite curve's derivatives scale with its values around a constant)."""
    over = over_bound(curve, bound)
    if over <= RATE_SHARE:
        return curve
    f = RATE_SHARE / over
    knots = [replace(k, value=centre + f * (k.value - centre), in_slope=f * k.in_slope, out_slope=f * k.out_slope)
             for k in curve.knots]
    return HermiteCurve(knots, curve.duration_s, curve.periodic)


def _swing_curve(rng: np.random.Generator, duration_s: float, lo: float, hi: float, extent: float, bound: RateBound,
                 start: float = 0.0, end: float = 0.0, centre: float = 0.0, min_peak: float = 0.0) -> HermiteCurve:
    """Flat at both ends (values ``start``/``end``), 1–2 interior knots within [lo, hi], at least
    ``MIN_KNOT_PHASE`` of the swing apart; rates within ``bound`` (values pulled toward 0). When that
    pull leaves the curve's peak below ``min_peak``, the interior knots are first spread evenly."""
    n = int(rng.integers(1, 3))
    times = _spaced_times(rng, n, 0.15, 0.85, MIN_KNOT_PHASE) * duration_s
    knots = [Knot(0.0, start, mode=TangentMode.FLAT)]
    knots += [Knot(float(t), _around(rng, centre, lo, hi, extent)) for t in times]
    knots.append(Knot(duration_s, end, mode=TangentMode.FLAT))
    curve = _within_rates(HermiteCurve(knots, duration_s), 0.0, bound)
    if curve.value_range()[1] < min_peak <= HermiteCurve(knots, duration_s).value_range()[1]:
        even = np.linspace(0.0, duration_s, n + 2)[1:-1]
        knots = [knots[0], *(replace(k, t_s=float(t)) for k, t in zip(knots[1:-1], even)), knots[-1]]
        curve = _within_rates(HermiteCurve(knots, duration_s), 0.0, bound)
    return curve


def _cycle_curve(rng: np.random.Generator, cycle_s: float, lo: float, hi: float, centre: float, extent: float,
                 bound: RateBound) -> HermiteCurve:
    """1–3 knots around the loop, at least ``MIN_KNOT_PHASE`` of the cycle apart (across the wrap
    too); rates within ``bound`` (values pulled toward ``centre``)."""
    n = int(rng.integers(1, 4))
    phases = np.sort((_spaced_times(rng, n, 0.0, 1.0 - MIN_KNOT_PHASE, MIN_KNOT_PHASE) + rng.uniform()) % 1.0)
    times = [float(p) * cycle_s for p in phases]
    curve = HermiteCurve([Knot(t, _around(rng, centre, lo, hi, extent)) for t in times], cycle_s, periodic=True)
    return _within_rates(curve, centre, bound)


def random_curves(rng: np.random.Generator, ctx: StyleContext, intervals: Intervals, attributes: Attributes,
                  extent: float, neutral: GaitSample) -> dict[str, HermiteCurve]:
    curves: dict[str, HermiteCurve] = {}
    for side in SIDES:
        d = intervals.swing_duration_s(side)
        # Height: the neutral apex as the centre of the range [0, max_swing_height_m].
        apex = neutral.curves.get(f"{side}_foot.z")
        centre = apex.value_range()[1] if apex is not None else 0.5 * ctx.max_swing_height_m
        curves[f"{side}_foot.z"] = _swing_curve(rng, d, 0.0, ctx.max_swing_height_m, extent, rate_bound(f"{side}_foot.z", ctx),
                                                centre=centre, min_peak=MIN_SWING_APEX_M)
        roll_range = channel_value_range(f"{side}_foot.roll", attributes.pelvis_height_m, ctx)
        roll_bound = roll_range[1] if roll_range is not None else MAX_FOOT_ANGLE_RAD  # (the ankle's, symmetric)
        for tail, bound in (("x", MAX_FOOT_OFFSET_M), ("y", MAX_FOOT_OFFSET_M), ("yaw", MAX_FOOT_ANGLE_RAD),
                            ("roll", roll_bound)):
            if rng.random() < 0.5:
                curves[f"{side}_foot.{tail}"] = _swing_curve(rng, d, -bound, bound, extent, rate_bound(f"{side}_foot.{tail}", ctx))
        # Heel/toe pitch: at each contact switch the foot is on its heel or on its toe (or flat).
        lo_kind, td_kind = rng.choice(["flat", "heel", "toe"]), rng.choice(["flat", "heel", "toe"])
        half_pi = 0.5 * math.pi
        heel_lo = _around(rng, 0.0, -half_pi, 0.0, extent) if lo_kind == "heel" else 0.0
        toe_lo = _around(rng, 0.0, 0.0, half_pi, extent) if lo_kind == "toe" else 0.0
        heel_td = _around(rng, 0.0, -half_pi, 0.0, extent) if td_kind == "heel" else 0.0
        toe_td = _around(rng, 0.0, 0.0, half_pi, extent) if td_kind == "toe" else 0.0
        if heel_lo or heel_td or rng.random() < 0.3:
            curves[f"{side}_foot.heel_pitch"] = _swing_curve(rng, d, -half_pi, 0.0, extent, rate_bound("left_foot.heel_pitch", ctx),
                                                             heel_lo, heel_td)
        if toe_lo or toe_td or rng.random() < 0.3:
            curves[f"{side}_foot.toe_pitch"] = _swing_curve(rng, d, 0.0, half_pi, extent, rate_bound("left_foot.toe_pitch", ctx),
                                                            toe_lo, toe_td)
    cycle = intervals.cycle_s
    z_lo = max(-MAX_PELVIS_Z_OFFSET_M, ctx.pelvis_height_range_m[0] - attributes.pelvis_height_m)
    z_hi = min(MAX_PELVIS_Z_OFFSET_M, ctx.pelvis_height_range_m[1] - attributes.pelvis_height_m)
    if rng.random() < 0.5 and z_hi - z_lo > 4 * EDGE:
        curves["pelvis.z"] = _cycle_curve(rng, cycle, z_lo, z_hi, 0.0, extent, rate_bound("pelvis.z", ctx))
    for tail in ("yaw", "pitch", "roll"):
        if rng.random() < 0.5:
            curves[f"pelvis.{tail}"] = _cycle_curve(rng, cycle, -MAX_PELVIS_ANGLE_RAD, MAX_PELVIS_ANGLE_RAD, 0.0, extent,
                                                    rate_bound(f"pelvis.{tail}", ctx))
    for joint in ctx.upper_joints:
        if rng.random() < 0.4:
            lo, hi = ctx.joint_limits[joint]
            curves[f"joints.{joint}"] = _cycle_curve(rng, cycle, lo, hi, ctx.standing_angles[joint], extent,
                                                     rate_bound(f"joints.{joint}", ctx))
    return curves


def reachable_velocities(ctx: StyleContext, samples: dict[str, GaitSample], hi: float = 10.0) -> dict[str, float]:
    """Per velocity field, the largest value whose samples' steps the legs reach (``hi`` without a bound):
    the validator's step bound (engine/gait/leg_reach.py), which couples a sample's velocity and timings."""
    out = {name: hi for name in set(VELOCITY_FIELD.values())}
    if ctx.leg_reach is None:
        return out
    probe = SampleVelocities(1.0, 0.5, 1.0, 1.0)
    for sample_name, field_name in VELOCITY_FIELD.items():
        unit = tuple(math.copysign(1.0, v) if v else 0.0 for v in probe.velocity_of(sample_name))
        out[field_name] = min(out[field_name], max_reachable_speed(ctx.leg_reach, samples[sample_name], unit, hi))
    return out


def random_velocities(rng: np.random.Generator, neutral: SampleVelocities, extent: float,
                      top: dict[str, float] | None = None) -> SampleVelocities:
    """Within [0.5, 1.5] × neutral scaled by ``extent``, and below ``top`` (per field) where it is lower."""
    top = top or {}

    def draw(field_name: str, value: float) -> float:
        cap = (1.0 - 1e-3) * top.get(field_name, math.inf)
        lo, hi = value * (1.0 - 0.5 * extent), value * (1.0 + 0.5 * extent)
        if cap <= lo:  # the legs reach less than the range's low end: below the cap
            return float(rng.uniform(0.5 * cap, cap))
        return float(rng.uniform(lo, min(hi, cap)))

    x_max = draw("x_max_mps", neutral.x_max_mps)
    x_slow = min(draw("x_slow_mps", neutral.x_slow_mps), 0.9 * x_max)
    return SampleVelocities(x_max, x_slow, draw("y_max_mps", neutral.y_max_mps), draw("yaw_max_radps", neutral.yaw_max_radps))


def random_sample(rng: np.random.Generator, ctx: StyleContext, base: GaitSample, extent: float) -> GaitSample:
    """One sample's timings, attributes and curves around ``base`` (the neutral style's sample)."""
    intervals = random_intervals(rng, ctx, base.intervals, extent)
    attributes = random_attributes(rng, ctx, base.attributes, extent)
    curves = random_curves(rng, ctx, intervals, attributes, extent, base)
    return GaitSample(intervals, attributes, curves)


def random_style(rng: np.random.Generator, ctx: StyleContext, neutral: Style, extent: float = 1.0,
                 name: str = "random") -> Style:
    """A random style that passes validation (see the module docstring for what is drawn)."""
    extent = float(min(max(extent, 0.0), 1.0))
    samples = {sample_name: random_sample(rng, ctx, neutral.samples[sample_name], extent) for sample_name in SAMPLE_NAMES}
    eta = _around(rng, neutral.blend_eta, 0.0, 1.0, extent)
    velocities = random_velocities(rng, neutral.velocities, extent, reachable_velocities(ctx, samples))
    return replace(neutral, name=name, description=f"random style (extent {extent:g})",
                   velocities=velocities, samples=samples, blend_eta=eta)


Unreachable = Callable[[Style, str], bool]  # (style, sample name) -> no leg posture follows that sample's reference
MAX_PASSES = 4  # passes over the samples until none is drawn again
MAX_RESTARTS = 5  # styles started over (new velocities) before giving up


class NoReachableStyle(RuntimeError):
    """No reachable draw within the budget (a space the legs almost never reach)."""


def random_reachable_style(rng: np.random.Generator, ctx: StyleContext, neutral: Style, unreachable: Unreachable,
                           extent: float = 1.0, name: str = "random", max_draws_per_sample: int = 400,
                           restarts: int = MAX_RESTARTS) -> tuple[Style, int]:
    """A random style that passes validation and whose every sample the legs reach (``unreachable`` false for
    each), and how many samples were drawn for it. The style's velocities are drawn once (with the first draw of
    its samples); a sample drawn again must keep them within the validator's step bound. Each sample is then
    drawn from the validated space conditioned on being reachable at those velocities; a sample that finds no
    such draw in ``max_draws_per_sample`` starts the style over (new velocities), up to ``restarts`` times."""
    extent = float(min(max(extent, 0.0), 1.0))
    draws = 0
    for _ in range(restarts):
        style = random_style(rng, ctx, neutral, extent, name)
        reached, redraws = _redraw_unreachable(rng, ctx, neutral, style, unreachable, extent, max_draws_per_sample)
        draws += len(SAMPLE_NAMES) + redraws
        if reached is not None:
            return reached, draws
    raise NoReachableStyle(f"{name}: no reachable style in {restarts} starts of up to {max_draws_per_sample} draws "
                           f"per sample at extent {extent:g}")


def _redraw_unreachable(rng: np.random.Generator, ctx: StyleContext, neutral: Style, style: Style,
                        unreachable: Unreachable, extent: float, max_draws_per_sample: int) -> tuple[Style | None, int]:
    """``style`` with each unreachable sample drawn again until every sample passes, and how many samples were
    drawn; None when a sample finds no reachable draw in ``max_draws_per_sample`` or the passes run out."""
    tries = dict.fromkeys(SAMPLE_NAMES, 0)
    for _ in range(MAX_PASSES):
        # A sample is checked within its style (the planner blends its neighbours in at its own velocity): one drawn
        # again can make another fail, so the samples are passed over until all of them pass.
        redrawn = False
        for sample_name in SAMPLE_NAMES:
            while unreachable(style, sample_name):
                if tries[sample_name] == max_draws_per_sample:
                    return None, sum(tries.values())
                tries[sample_name] += 1
                candidate = replace(style, samples={**style.samples,
                                                    sample_name: random_sample(rng, ctx, neutral.samples[sample_name], extent)})
                try:
                    validate_style(candidate, ctx)
                except StyleError:  # this draw's steps are past the legs' reach at the style's velocity
                    continue
                style, redrawn = candidate, True
        if not redrawn:
            return style, sum(tries.values())
    return None, sum(tries.values())
