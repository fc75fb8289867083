"""Mocap → walking style (issue §7): a recorded span of LWL2's upper-body output becomes the ``joints.<joint>``
curves of one gait sample, so a performed gesture becomes part of a walking style.

The span is stretched over the sample's cycle (its start at phase 0, its end at phase 1) and closed into a
loop: a recording rarely ends where it began, and a periodic curve through its raw samples would jump back
from the end value to the start value in the last knot interval (an eighth of a cycle with 8 knots: several
rad/s, more than an arm can follow). So each joint's span has the straight line from its start to its end
value taken out and half of that difference put back (``q(φ) − (φ − ½)(q(1) − q(0))``): the start and the
end meet at their mean, the gesture's shape and mean are kept, only its drift over the span is removed (a
cycle can't drift). Each joint then gets a periodic curve with ``n_knots`` equally spaced knots
(auto-clamped tangents) whose values are that loop linearly interpolated at those phases, clipped to the
joint's limits. The result is a new :class:`~engine.gait.style.Style` — the studio applies it as one
undoable edit.
"""

from __future__ import annotations

import numpy as np

from engine.gait.curves import HermiteCurve, Knot
from engine.gait.style import GaitSample, Style, StyleContext

MIN_KNOTS, MAX_KNOTS = 2, 32


def gesture_curves(t_s: np.ndarray, q: np.ndarray, joint_names: list[str] | tuple[str, ...], cycle_s: float,
                   n_knots: int, limits: dict[str, tuple[float, float]] | None = None) -> dict[str, HermiteCurve]:
    """``{"joints.<name>": periodic HermiteCurve}`` from a recording ``q`` (N, K) at times ``t_s`` (N,)."""
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or len(t) != len(q) or q.shape[1] != len(joint_names):
        raise ValueError(f"recording: expected (N,) times and (N, {len(joint_names)}) angles, got {t.shape} and {q.shape}")
    if len(t) < 2 or not np.all(np.isfinite(q)) or not np.all(np.diff(t) > 0):
        raise ValueError("recording: expected at least two frames at increasing times with finite angles")
    if not MIN_KNOTS <= n_knots <= MAX_KNOTS:
        raise ValueError(f"knots: expected {MIN_KNOTS}..{MAX_KNOTS}, got {n_knots}")
    phase = (t - t[0]) / (t[-1] - t[0])
    knot_phase = np.arange(n_knots) / n_knots
    out = {}
    for k, name in enumerate(joint_names):
        drift = q[-1, k] - q[0, k]
        values = np.interp(knot_phase, phase, q[:, k]) - (knot_phase - 0.5) * drift  # closed into a loop
        if limits is not None and name in limits:
            lo, hi = limits[name]
            values = np.clip(values, lo, hi)
        out[f"joints.{name}"] = HermiteCurve([Knot(float(p * cycle_s), float(v)) for p, v in zip(knot_phase, values)],
                                             cycle_s, True)
    return out


def style_with_gesture(style: Style, sample_name: str, t_s: np.ndarray, q: np.ndarray,
                       joint_names: list[str] | tuple[str, ...], n_knots: int, ctx: StyleContext) -> Style:
    """``style`` whose sample ``sample_name`` carries the recording as its upper-body joint curves (joints the
    style does not drive are refused by name)."""
    unknown = [j for j in joint_names if j not in ctx.upper_joints]
    if unknown:
        raise ValueError(f"joints: {', '.join(unknown)} are not upper-body joints of {ctx.robot}")
    sample: GaitSample = style.sample(sample_name)
    curves = gesture_curves(t_s, q, joint_names, sample.intervals.cycle_s, n_knots, dict(ctx.joint_limits))
    for channel, curve in curves.items():
        sample = sample.with_curve(channel, curve)
    return style.with_sample(sample_name, sample)


__all__ = ["gesture_curves", "style_with_gesture", "MIN_KNOTS", "MAX_KNOTS"]
