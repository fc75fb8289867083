"""How fast a style's curves may change: the rate and acceleration the stack can follow (issue 13).

A curve's rate (value units per second) and acceleration (per second²) are part of what a robot
can walk: the whole-body controller turns a curve's acceleration into task accelerations, and a
knot pair a few milliseconds apart asks for hundreds of rad/s² at the swing foot or the pelvis
(random-2-0 of ``studio bench styles --seed 2 --extent 0.15``: its ``left_foot.yaw`` goes
−0.058 → +0.097 rad in 6 ms; the controller then commands 530 rad/s² of swing-foot rotation,
256 rad/s² of pelvis rotation — neutral: 12 and 6 — and the CoP leaves the plan for the heel
edge). Bounds per channel kind, in curve time (what the animator authors):

* ``joints.<joint>`` — rate: the joint's velocity limit in the robot model (at most the robot's
  ``joint_max_radps``); acceleration: ``joint_radps2``;
* foot positions (``x``, ``y``, ``z``) and angles (``yaw``, ``roll``, ``heel_pitch``,
  ``toe_pitch``), pelvis height and angles — one rate and acceleration per kind.

The bounds are the robot's (robots/<name>.toml ``[gait.curve_rates]``,
:class:`engine.robot.config.CurveRateLimits`). The defaults are twice the peak of the shipped
styles (G1 neutral, casual, sneak, injured; TALOS neutral; measured by :func:`curve_peaks`, held
by ``tests/gait/test_curve_rates.py``), rounded up: the shipped styles walk (60 s sweeps, slip
< 2 mm), twice their peak leaves room to author livelier motion, while the falling random styles
of ``studio bench styles`` before the generator was bounded were 10²–10⁴ times over them (README,
*Curve rates*). The shipped peaks: foot positions 0.98 m/s, 21.4 m/s² (``z``); foot angles
3.75 rad/s, 107 rad/s² (injured's toe-off); pelvis angles 0.64 rad/s, 7.9 rad/s²; pelvis height
0.095 m/s, 2.5 m/s²; upper-body joints 2.1 rad/s, 28.7 rad/s². G1 sets its bounds at about
once these peaks: at twice, random styles with curves near their bounds fell where the shipped
styles walk (README).

The peaks are exact: a cubic Hermite segment's acceleration is linear in time (largest at a
segment end) and its rate quadratic (largest at an end or its vertex).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from engine.gait.curves import HermiteCurve
from engine.robot.config import CurveRateLimits

if TYPE_CHECKING:
    from engine.gait.style import StyleContext


@dataclass(frozen=True)
class RateBound:
    rate: float  # value units / s
    accel: float  # value units / s²
    unit: str  # "m" or "rad"


JOINT_RATE_FALLBACK_RADPS = 6.0  # a joint whose model gives no velocity limit
FOOT_POSITIONS = ("x", "y", "z")


def rate_bound(channel: str, ctx: StyleContext | None = None) -> RateBound:
    """The rate and acceleration ``channel``'s curve may reach on ``ctx``'s robot (curve time;
    without a context: the default bounds, and ``JOINT_RATE_FALLBACK_RADPS`` for joints)."""
    limits = ctx.curve_rates if ctx is not None else CurveRateLimits()
    head, _, tail = channel.partition(".")
    if head in ("left_foot", "right_foot"):
        if tail in FOOT_POSITIONS:
            return RateBound(limits.foot_position_mps, limits.foot_position_mps2, "m")
        return RateBound(limits.foot_angle_radps, limits.foot_angle_radps2, "rad")
    if channel == "pelvis.z":
        return RateBound(limits.pelvis_height_mps, limits.pelvis_height_mps2, "m")
    if head == "pelvis":
        return RateBound(limits.pelvis_angle_radps, limits.pelvis_angle_radps2, "rad")
    limit = (ctx.joint_velocity_limits if ctx is not None else {}).get(tail, 0.0)
    rate = float(limit) if limit > 0.0 else JOINT_RATE_FALLBACK_RADPS
    return RateBound(min(rate, limits.joint_max_radps), limits.joint_radps2, "rad")


@dataclass(frozen=True)
class CurvePeaks:
    rate: float  # largest |dv/dt|
    rate_t_s: float  # curve time where it is reached
    accel: float  # largest |d²v/dt²|
    accel_t_s: float


def curve_peaks(curve: HermiteCurve) -> CurvePeaks:
    """The curve's largest |rate| and |acceleration| and where (curve time), exactly."""
    rate = accel = 0.0
    rate_t = accel_t = 0.0
    seg = curve.segments()
    if len(seg) == 0:  # 0 or 1 knot: a constant
        return CurvePeaks(0.0, 0.0, 0.0, 0.0)
    h_all = [float(row[0]) for row in seg]  # segment start times
    ends = h_all[1:] + ([h_all[0] + curve.duration_s] if curve.periodic else [curve.knots[-1].t_s])
    for (t0, _a, b, c, d), t1 in zip(seg.tolist(), ends):
        h = t1 - t0
        candidates = [0.0, h]
        if abs(d) > 1e-15 and 0.0 < -c / (3.0 * d) < h:
            candidates.append(-c / (3.0 * d))
        for tau in candidates:
            r = abs(b + tau * (2.0 * c + 3.0 * d * tau))
            if r > rate:
                rate, rate_t = r, t0 + tau
        for tau in (0.0, h):
            acc = abs(2.0 * c + 6.0 * d * tau)
            if acc > accel:
                accel, accel_t = acc, t0 + tau
    period = curve.duration_s
    return CurvePeaks(rate, rate_t % period if curve.periodic else rate_t,
                      accel, accel_t % period if curve.periodic else accel_t)


def over_bound(curve: HermiteCurve, bound: RateBound) -> float:
    """How many times the curve exceeds its bound (≤ 1: within it)."""
    peaks = curve_peaks(curve)
    return max(peaks.rate / bound.rate, peaks.accel / bound.accel)
