"""Author the shipped styles (styles/g1/*.json, styles/talos/neutral.json, styles/dino/*.json) from compact recipes.

Run ``.venv/bin/python tools/author_styles.py`` to regenerate them. Each style is built with
the style data model and validated against its robot before it is written, exactly as the
studio's editor would save it; animators then refine them in the studio.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from engine.gait.curves import HermiteCurve, Knot, TangentMode  # noqa: E402
from engine.gait.style import (  # noqa: E402
    Attributes,
    GaitSample,
    Intervals,
    Style,
    StyleContext,
    save_style,
    validate_style,
)
from engine.gait.velocity_sampler import SAMPLE_NAMES, SampleVelocities  # noqa: E402

FLAT = TangentMode.FLAT


def swing_bump(duration: float, height: float, peak: float = 0.5) -> HermiteCurve:
    """Foot height over a swing: zero and flat at liftoff/touchdown, one smooth peak."""
    return HermiteCurve([Knot(0.0, 0.0, mode=FLAT), Knot(peak * duration, height),
                         Knot(duration, 0.0, mode=FLAT)], duration)


def swing_profile(duration: float, points: list[tuple[float, float]]) -> HermiteCurve:
    """A swing curve through (fraction, value) points, pinned flat at zero at both ends."""
    knots = [Knot(0.0, 0.0, mode=FLAT)] + [Knot(f * duration, v) for f, v in points] + [Knot(duration, 0.0, mode=FLAT)]
    return HermiteCurve(knots, duration)


def swing_pitch(duration: float, start: float, end: float, mid: float = 0.0, mid_at: float = 0.5) -> HermiteCurve:
    """Heel or toe pitch over a swing: ``start`` at liftoff, ``end`` at touchdown (flat tangents)."""
    knots = [Knot(0.0, start, mode=FLAT)]
    if mid != 0.0 or start != 0.0 and end != 0.0:
        knots.append(Knot(mid_at * duration, mid))
    knots.append(Knot(duration, end, mode=FLAT))
    return HermiteCurve(knots, duration)


def cycle_wave(period: float, mean: float, amplitude: float, peak_s: float, harmonics: int = 1) -> HermiteCurve:
    """A periodic curve, ``harmonics`` peaks per cycle, maxima at ``peak_s`` (mod period/harmonics)."""
    knots = []
    step = period / (4 * harmonics)
    for i in range(4 * harmonics):
        t = (peak_s + i * step) % period
        value = mean + amplitude * math.cos(2 * math.pi * harmonics * (t - peak_s) / period)
        knots.append(Knot(t, round(value, 6)))
    knots.sort(key=lambda k: k.t_s)
    return HermiteCurve(knots, period, periodic=True)


def cycle_const(period: float, value: float) -> HermiteCurve:
    return HermiteCurve([Knot(0.0, value)], period, periodic=True)


@dataclass
class Recipe:
    """One sample's parameters; the curves are derived from these numbers."""

    cycle_s: float
    swing_s: float  # left swing duration
    right_swing_s: float | None = None  # defaults to swing_s (symmetric)
    swing_height_m: float = 0.07
    swing_peak: float = 0.5
    width_m: float = 0.24
    splay_rad: float = 0.0
    x_bias_m: float = 0.0
    pelvis_height_m: float = 0.72
    pelvis_bob_m: float = 0.0  # twice per cycle, lowest at mid double support
    pelvis_yaw_rad: float = 0.0  # counter-rotation amplitude (left hip forward at left touchdown)
    pelvis_roll_rad: float = 0.0  # hip drop toward the swing side
    pelvis_pitch_rad: float = 0.0  # constant forward lean
    spine_yaw_rad: float = 0.0  # waist yaw counter to the pelvis
    arm_swing_rad: float = 0.0  # shoulder pitch amplitude (counter to the legs)
    shoulder_pitch_rad: float | None = None  # arm carriage (mean)
    shoulder_roll_rad: float | None = None
    elbow_rad: float | None = None
    elbow_swing_rad: float = 0.0
    torso_pitch_rad: float | None = None
    heel_strike_rad: float = 0.0  # ψ_heel at touchdown (≤ 0 in the file)
    toe_off_rad: float = 0.0  # ψ_toe at liftoff (≥ 0)
    liftoff_transition_s: float = 0.0
    touchdown_transition_s: float = 0.0
    swing_toe_pitch_rad: float = 0.0  # toes point down mid-swing (walking backward leads with the toes)
    swing_x_m: list[tuple[float, float]] = field(default_factory=list)  # extra swing x profile points
    swing_y_m: list[tuple[float, float]] = field(default_factory=list)
    # Neck and tail (characters that have them, e.g. the dino).
    neck_pitch_rad: float | None = None  # neck carriage (mean); + leans the neck forward
    head_bob_rad: float = 0.0  # neck pitch amplitude, twice per cycle: head lowest at each touchdown
    head_hold_rad: float = 0.0  # head pitch counter to the neck bob (share of it): the bird-like stabilised head
    head_yaw_rad: float = 0.0  # neck yaw sway, once per cycle, toward the stance side
    tail_swing_rad: float = 0.0  # tail yaw amplitude, once per cycle, counter to the hips (toward the swing leg)
    tail_lag_s: float = 0.0  # how far the tail tip lags its root (the wave travels down the tail)
    tail_lift_rad: float | None = None  # tail pitch carriage (mean); − raises the tip
    tail_bob_rad: float = 0.0  # tail pitch amplitude, twice per cycle


@dataclass(frozen=True)
class Joints:
    """Upper-body joint names of a robot, by role (None when the robot lacks it)."""

    shoulder_pitch: tuple[str, str]
    shoulder_roll: tuple[str, str] | None
    elbow: tuple[str, str] | None
    spine_yaw: str | None
    torso_pitch: str | None
    elbow_sign: float = 1.0  # + bends the elbow on G1, − on TALOS
    neck: tuple[str, str, str] | None = None  # (neck pitch, neck yaw, head pitch)
    tail: tuple[str, ...] = ()  # alternating yaw, pitch, yaw from the root


G1 = Joints(("left_shoulder_pitch_joint", "right_shoulder_pitch_joint"),
            ("left_shoulder_roll_joint", "right_shoulder_roll_joint"),
            ("left_elbow_joint", "right_elbow_joint"), "waist_yaw_joint", "waist_pitch_joint")
TALOS = Joints(("arm_left_1_joint", "arm_right_1_joint"), ("arm_left_2_joint", "arm_right_2_joint"),
               ("arm_left_4_joint", "arm_right_4_joint"), "torso_1_joint", "torso_2_joint", elbow_sign=-1.0)
DINO = Joints(("left_shoulder_pitch_joint", "right_shoulder_pitch_joint"), None, None, None, None,
              neck=("neck_pitch_joint", "neck_yaw_joint", "head_pitch_joint"),
              tail=("tail_yaw_1_joint", "tail_pitch_2_joint", "tail_yaw_3_joint"))


def build_sample(r: Recipe, joints: Joints, ctx: StyleContext) -> GaitSample:
    right = r.right_swing_s if r.right_swing_s is not None else r.swing_s
    ds = 0.5 * (r.cycle_s - r.swing_s - right)
    iv = Intervals(r.cycle_s, (0.0, r.swing_s), (r.swing_s + ds, r.swing_s + ds + right))
    t_ltd, t_rlo, t_rtd, period = iv.events_s
    curves: dict[str, HermiteCurve] = {}
    for side, d in (("left", r.swing_s), ("right", right)):
        curves[f"{side}_foot.z"] = swing_bump(d, r.swing_height_m, r.swing_peak)
        if r.heel_strike_rad or r.toe_off_rad:
            curves[f"{side}_foot.toe_pitch"] = swing_pitch(d, r.toe_off_rad, 0.0)
            curves[f"{side}_foot.heel_pitch"] = swing_pitch(d, 0.0, -r.heel_strike_rad)
        elif r.swing_toe_pitch_rad:
            curves[f"{side}_foot.toe_pitch"] = swing_profile(d, [(0.5, r.swing_toe_pitch_rad)])
        if r.swing_x_m:
            curves[f"{side}_foot.x"] = swing_profile(d, r.swing_x_m)
        if r.swing_y_m:
            sign = 1.0 if side == "left" else -1.0
            curves[f"{side}_foot.y"] = swing_profile(d, [(f, sign * v) for f, v in r.swing_y_m])
    mid_ds1 = 0.5 * (t_ltd + t_rlo)
    if r.pelvis_bob_m:
        # Highest mid single support, lowest in double support: two bobs per cycle.
        curves["pelvis.z"] = cycle_wave(period, 0.0, r.pelvis_bob_m, (mid_ds1 + period / 4) % period, harmonics=2)
    if r.pelvis_yaw_rad:
        curves["pelvis.yaw"] = cycle_wave(period, 0.0, r.pelvis_yaw_rad, t_rtd)  # right hip forward at RTD
    if r.pelvis_roll_rad:
        curves["pelvis.roll"] = cycle_wave(period, 0.0, r.pelvis_roll_rad, 0.5 * (t_rlo + t_rtd))
    if r.pelvis_pitch_rad:
        curves["pelvis.pitch"] = cycle_const(period, r.pelvis_pitch_rad)
    if joints.spine_yaw and r.spine_yaw_rad:
        curves[f"joints.{joints.spine_yaw}"] = cycle_wave(period, 0.0, r.spine_yaw_rad, t_ltd)
    if joints.torso_pitch and r.torso_pitch_rad is not None:
        curves[f"joints.{joints.torso_pitch}"] = cycle_const(period, r.torso_pitch_rad)
    for i, side in enumerate(("left", "right")):
        sp = joints.shoulder_pitch[i]
        mean = ctx.standing_angles[sp] if r.shoulder_pitch_rad is None else r.shoulder_pitch_rad
        # Arm swings back (+pitch) when the same-side leg swings forward: left arm back at LTD.
        back_at = t_ltd if side == "left" else t_rtd
        if r.arm_swing_rad:
            curves[f"joints.{sp}"] = cycle_wave(period, mean, r.arm_swing_rad, back_at)
        elif r.shoulder_pitch_rad is not None:
            curves[f"joints.{sp}"] = cycle_const(period, mean)
        if r.shoulder_roll_rad is not None and joints.shoulder_roll:
            sign = 1.0 if side == "left" else -1.0
            curves[f"joints.{joints.shoulder_roll[i]}"] = cycle_const(period, sign * r.shoulder_roll_rad)
        if joints.elbow is None:
            continue
        el = joints.elbow[i]
        el_mean = ctx.standing_angles[el] if r.elbow_rad is None else joints.elbow_sign * r.elbow_rad
        if r.elbow_swing_rad:
            # Elbows bend more as the arm swings forward.
            curves[f"joints.{el}"] = cycle_wave(period, el_mean, joints.elbow_sign * r.elbow_swing_rad,
                                                 (back_at + period / 2) % period)
        elif r.elbow_rad is not None:
            curves[f"joints.{el}"] = cycle_const(period, el_mean)
    if joints.neck:
        _neck_curves(r, joints, ctx, curves, (t_ltd, t_rtd, period))
    if joints.tail:
        _tail_curves(r, joints, ctx, curves, (t_ltd, t_rlo, t_rtd, period))
    attrs = Attributes(stance_width_m=r.width_m, stance_splay_rad=r.splay_rad, stance_x_bias_m=r.x_bias_m,
                       liftoff_transition_s=r.liftoff_transition_s, touchdown_transition_s=r.touchdown_transition_s,
                       pelvis_height_m=r.pelvis_height_m)
    return GaitSample(iv, attrs, curves)


def _neck_curves(r: Recipe, joints: Joints, ctx: StyleContext, curves: dict[str, HermiteCurve],
                 events: tuple[float, float, float]) -> None:
    """Bird-like neck: the neck pitches down at each touchdown (two bobs per cycle) while the head
    pitches back against it, and the neck sways toward the stance side once per cycle."""
    t_ltd, t_rtd, period = events
    neck_pitch, neck_yaw, head_pitch = joints.neck
    mean = ctx.standing_angles[neck_pitch] if r.neck_pitch_rad is None else r.neck_pitch_rad
    head_mean = ctx.standing_angles[head_pitch] - (mean - ctx.standing_angles[neck_pitch])
    if r.head_bob_rad:
        curves[f"joints.{neck_pitch}"] = cycle_wave(period, mean, r.head_bob_rad, t_ltd, harmonics=2)
        curves[f"joints.{head_pitch}"] = cycle_wave(period, head_mean, -r.head_hold_rad * r.head_bob_rad, t_ltd,
                                                    harmonics=2)
    elif r.neck_pitch_rad is not None:
        curves[f"joints.{neck_pitch}"] = cycle_const(period, mean)
        curves[f"joints.{head_pitch}"] = cycle_const(period, head_mean)
    if r.head_yaw_rad:
        # + yaw turns the head left: toward the left foot while it stands (right swing).
        curves[f"joints.{neck_yaw}"] = cycle_wave(period, 0.0, r.head_yaw_rad, 0.5 * (t_ltd + t_rtd) % period)


def _tail_curves(r: Recipe, joints: Joints, ctx: StyleContext, curves: dict[str, HermiteCurve],
                 events: tuple[float, float, float, float]) -> None:
    """Theropod tail: yaw segments swing once per cycle toward the swing leg's side (balancing the
    hips), each segment ``tail_lag_s`` behind the previous; pitch segments carry and bob the tail."""
    t_ltd, t_rlo, t_rtd, period = events
    lag = 0.0
    for k, joint in enumerate(joints.tail):
        if k % 2 == 0:  # yaw: + swings the tail to the left (tip toward +y behind the body)
            if r.tail_swing_rad:
                # The tail is furthest right while the left leg swings (mid left swing: t_ltd / 2).
                peak_left = (0.5 * (t_rlo + t_rtd) + lag) % period
                curves[f"joints.{joint}"] = cycle_wave(period, 0.0, r.tail_swing_rad * (1.0 + 0.25 * k), peak_left)
            lag += r.tail_lag_s
        else:  # pitch
            mean = ctx.standing_angles[joint] if r.tail_lift_rad is None else r.tail_lift_rad
            if r.tail_bob_rad:
                curves[f"joints.{joint}"] = cycle_wave(period, mean, r.tail_bob_rad, (t_ltd + lag) % period,
                                                       harmonics=2)
            elif r.tail_lift_rad is not None:
                curves[f"joints.{joint}"] = cycle_const(period, mean)


def make_style(name: str, robot: str, description: str, velocities: SampleVelocities,
               recipes: dict[str, Recipe], joints: Joints) -> Style:
    ctx = StyleContext.for_robot(robot)
    samples = {n: build_sample(recipes[n], joints, ctx) for n in SAMPLE_NAMES}
    style = Style(name, robot, velocities, samples, blend_eta=0.5, description=description)
    validate_style(style, ctx)
    return style


def with_(base: Recipe, **changes) -> Recipe:
    from dataclasses import replace

    return replace(base, **changes)


def nine(in_place: Recipe, forward_slow: Recipe, forward_fast: Recipe, reverse_slow: Recipe | None = None,
         reverse_fast: Recipe | None = None, strafe: Recipe | None = None, turn: Recipe | None = None) -> dict[str, Recipe]:
    return {
        "forward_fast": forward_fast, "forward_slow": forward_slow, "in_place": in_place,
        "reverse_slow": reverse_slow or forward_slow, "reverse_fast": reverse_fast or forward_slow,
        "left_strafe": strafe or in_place, "right_strafe": strafe or in_place,
        "left_turn": turn or in_place, "right_turn": turn or in_place,
    }


# ----------------------------------------------------------------------------- G1 styles


def g1_neutral() -> Style:
    base = Recipe(cycle_s=0.9, swing_s=0.36, swing_height_m=0.06, pelvis_height_m=0.67, arm_swing_rad=0.0)
    slow = with_(base, cycle_s=0.8, swing_s=0.32, swing_height_m=0.07, arm_swing_rad=0.12)
    # Cadence rises with speed (0.175 m steps at 0.5 m/s): G1's legs cannot reach longer steps.
    fast = with_(base, cycle_s=0.7, swing_s=0.28, swing_height_m=0.07, pelvis_height_m=0.66, arm_swing_rad=0.22,
                 elbow_swing_rad=0.1)
    rev = with_(slow, arm_swing_rad=0.08, swing_height_m=0.05, swing_toe_pitch_rad=0.35)
    strafe = with_(base, cycle_s=0.75, swing_s=0.3, width_m=0.22, swing_height_m=0.06)
    return make_style("neutral", "g1", "The nominal gait: even timing, modest arm swing, no frills.",
                      SampleVelocities(0.5, 0.2, 0.15, 1.0),
                      nine(base, slow, fast, rev, with_(rev, cycle_s=0.75, swing_s=0.3), strafe, base), G1)


def g1_casual() -> Style:
    base = Recipe(cycle_s=1.3, swing_s=0.5, swing_height_m=0.06, width_m=0.3, splay_rad=0.3, pelvis_height_m=0.67,
                  pelvis_bob_m=0.008, pelvis_yaw_rad=0.08, spine_yaw_rad=0.16, pelvis_roll_rad=0.04,
                  arm_swing_rad=0.25, elbow_swing_rad=0.15, shoulder_roll_rad=0.22, elbow_rad=0.55)
    slow = with_(base, cycle_s=1.2, swing_s=0.46, arm_swing_rad=0.32, pelvis_yaw_rad=0.1, spine_yaw_rad=0.2)
    fast = with_(base, cycle_s=1.0, swing_s=0.38, swing_height_m=0.07, arm_swing_rad=0.4, pelvis_yaw_rad=0.12,
                 spine_yaw_rad=0.24, width_m=0.28)
    strafe = with_(base, cycle_s=0.95, swing_s=0.36, width_m=0.24, splay_rad=0.15, pelvis_yaw_rad=0.04,
                   spine_yaw_rad=0.08)
    return make_style("casual", "g1", "Relaxed: slow cycle, open toes-out stance, hips and shoulders counter-rotate, "
                      "loose arm swing (paper §8.2).", SampleVelocities(0.4, 0.2, 0.1, 0.8),
                      nine(base, slow, fast,
                           with_(slow, cycle_s=0.95, swing_s=0.36, arm_swing_rad=0.2, width_m=0.23, splay_rad=0.15,
                                 pelvis_roll_rad=0.02, swing_toe_pitch_rad=0.35,
                                 swing_height_m=0.04),
                           with_(slow, cycle_s=0.9, swing_s=0.34, arm_swing_rad=0.25, width_m=0.23, splay_rad=0.15,
                                 pelvis_roll_rad=0.02, swing_toe_pitch_rad=0.35,
                                 swing_height_m=0.04),
                           strafe, base), G1)


def g1_sneak() -> Style:
    base = Recipe(cycle_s=1.6, swing_s=0.62, swing_height_m=0.12, swing_peak=0.4, width_m=0.28, pelvis_height_m=0.64,
                  pelvis_pitch_rad=0.12, torso_pitch_rad=0.25, shoulder_pitch_rad=-0.55, shoulder_roll_rad=0.3,
                  elbow_rad=1.35, arm_swing_rad=0.06, swing_x_m=[(0.55, 0.03)])
    slow = with_(base, cycle_s=1.5, swing_s=0.58)
    fast = with_(base, cycle_s=1.3, swing_s=0.5, swing_height_m=0.13)
    strafe = with_(base, cycle_s=1.1, swing_s=0.42, width_m=0.22, swing_height_m=0.09, pelvis_height_m=0.66)
    return make_style("sneak", "g1", "Sneaking: low pelvis, long slow high-knee swings, arms carried forward and "
                      "bent, leaning in.", SampleVelocities(0.3, 0.15, 0.08, 0.6),
                      nine(base, slow, fast, with_(slow, swing_toe_pitch_rad=0.4, swing_height_m=0.08),
                           with_(slow, swing_toe_pitch_rad=0.4, swing_height_m=0.08), strafe, base), G1)


def g1_injured() -> Style:
    # Asymmetric at slow speeds: a short left swing (hurry off the hurt right leg), a positive
    # x-bias and a pelvis dropping over the right leg; symmetric at Forward Fast (paper §8.1).
    limp = Recipe(cycle_s=1.1, swing_s=0.3, right_swing_s=0.5, swing_height_m=0.05, x_bias_m=0.06,
                  pelvis_height_m=0.66, pelvis_roll_rad=0.06, pelvis_yaw_rad=0.05, arm_swing_rad=0.1,
                  shoulder_roll_rad=0.25, swing_toe_pitch_rad=0.3)
    slow = with_(limp, cycle_s=1.0, swing_s=0.28, right_swing_s=0.46)
    fast = Recipe(cycle_s=0.8, swing_s=0.32, swing_height_m=0.08, pelvis_height_m=0.68, arm_swing_rad=0.22,
                  elbow_swing_rad=0.1)
    strafe = with_(limp, cycle_s=0.95, swing_s=0.28, right_swing_s=0.4, x_bias_m=0.03, width_m=0.22)
    reverse = with_(slow, x_bias_m=0.03, swing_height_m=0.045, swing_toe_pitch_rad=0.35)
    return make_style("injured", "g1", "Limping on a hurt right leg at slow speeds; blends back to a symmetric gait "
                      "at Forward Fast (paper §8.1).", SampleVelocities(0.45, 0.15, 0.1, 0.8),
                      nine(limp, slow, fast, reverse, reverse, strafe, limp), G1)


# ----------------------------------------------------------------------------- TALOS


def talos_neutral() -> Style:
    base = Recipe(cycle_s=1.3, swing_s=0.5, swing_height_m=0.06, width_m=0.2, pelvis_height_m=0.98,
                  shoulder_pitch_rad=0.25, shoulder_roll_rad=0.17, elbow_rad=0.5)
    slow = with_(base, cycle_s=1.2, swing_s=0.46, arm_swing_rad=0.1)
    fast = with_(base, cycle_s=1.1, swing_s=0.42, swing_height_m=0.07, arm_swing_rad=0.18)
    return make_style("neutral", "talos", "The nominal TALOS gait: even timing, gentle arm swing.",
                      SampleVelocities(0.4, 0.2, 0.1, 0.6), nine(base, slow, fast, slow, slow, base, base), TALOS)


# ----------------------------------------------------------------------------- dino


def dino_neutral() -> Style:
    # A short-legged character (ω = √(g/z) ≈ 5 /s against G1's 3.8): quick steps. Forward slow and
    # fast hurry the cadence so that a push (velocity adjustment → Forward Fast) is caught with
    # short steps the legs can reach. Turns step quickly too: a stance foot that must turn more
    # than ~0.2 rad per step lands late and slides (measured: 7 mm at 0.8 rad/s with 0.7 s cycles).
    base = Recipe(cycle_s=0.7, swing_s=0.28, swing_height_m=0.04, width_m=0.15, pelvis_height_m=0.39)
    slow = with_(base, cycle_s=0.56, swing_s=0.23)
    fast = with_(base, cycle_s=0.5, swing_s=0.2, swing_height_m=0.045, pelvis_height_m=0.385)
    rev = with_(slow, swing_height_m=0.035, swing_toe_pitch_rad=0.3)
    strafe = with_(base, cycle_s=0.6, swing_s=0.24, width_m=0.16)
    turn = with_(base, cycle_s=0.6, swing_s=0.25, swing_peak=0.4, swing_height_m=0.035)
    return make_style("neutral", "dino", "The nominal dino gait: even timing, quick steps, neck and tail held still.",
                      SampleVelocities(0.45, 0.15, 0.1, 0.5),
                      nine(base, slow, fast, rev, with_(rev, cycle_s=0.52, swing_s=0.21), strafe, turn), DINO)


def dino_strut() -> Style:
    # Paper §8.1's "dino gait": symmetric swings, a cycle that halves from in place to forward
    # fast (a casual cadence in place, short quick steps at speed), the head bobbing like a
    # bird's and the tail swinging against the hips with the wave travelling down it.
    base = Recipe(cycle_s=1.0, swing_s=0.4, swing_height_m=0.05, width_m=0.15, pelvis_height_m=0.38,
                  pelvis_bob_m=0.006, neck_pitch_rad=0.35, head_bob_rad=0.12, head_hold_rad=0.8, head_yaw_rad=0.05,
                  tail_swing_rad=0.1, tail_lag_s=0.06, tail_lift_rad=-0.1, tail_bob_rad=0.05,
                  arm_swing_rad=0.15, pelvis_yaw_rad=0.04)
    slow = with_(base, cycle_s=0.7, swing_s=0.28, head_bob_rad=0.15, tail_swing_rad=0.12)
    fast = with_(base, cycle_s=0.5, swing_s=0.2, swing_height_m=0.045, pelvis_height_m=0.375, neck_pitch_rad=0.5,
                 head_bob_rad=0.1, tail_swing_rad=0.08, tail_lag_s=0.04, tail_lift_rad=-0.15, pelvis_bob_m=0.004)
    rev = with_(slow, swing_height_m=0.035, swing_toe_pitch_rad=0.3, head_bob_rad=0.08)
    strafe = with_(base, cycle_s=0.62, swing_s=0.25, width_m=0.16, tail_swing_rad=0.14)
    turn = with_(base, cycle_s=0.6, swing_s=0.25, swing_peak=0.4, swing_height_m=0.035, head_bob_rad=0.08,
                 tail_swing_rad=0.08, pelvis_yaw_rad=0.0)
    return make_style("strut", "dino", "Paper §8.1's dino gait: cadence doubles with speed, bird-like head bob "
                      "(neck dips at each touchdown, head held level), tail swings against the hips.",
                      SampleVelocities(0.4, 0.15, 0.1, 0.5),
                      nine(base, slow, fast, rev, with_(rev, cycle_s=0.56, swing_s=0.22), strafe, turn), DINO)


STYLES = {
    ("g1", "neutral"): g1_neutral, ("g1", "casual"): g1_casual, ("g1", "sneak"): g1_sneak,
    ("g1", "injured"): g1_injured, ("talos", "neutral"): talos_neutral,
    ("dino", "neutral"): dino_neutral, ("dino", "strut"): dino_strut,
}


def main(argv: list[str] | None = None) -> int:
    only = set((argv if argv is not None else sys.argv[1:]))  # robot names; all when empty
    for (robot, name), make in STYLES.items():
        if only and robot not in only:
            continue
        path = REPO / "styles" / robot / f"{name}.json"
        save_style(path, make())
        print(f"wrote {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
