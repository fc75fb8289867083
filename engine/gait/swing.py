"""Nominal swing trajectory (paper Eqs. 5–6): cubic α with zero end rates, linear position, SLERP yaw."""

from __future__ import annotations

from engine.geometry import smoothstep, smoothstep_rate, wrap_angle
from engine.gait.footsteps import Foothold


def nominal_swing(start: Foothold, target: Foothold, progress: float) -> tuple[float, float, float, float]:
    """(x, y, yaw, dα/ds) of the nominal foot on the ground at swing progress s ∈ [0, 1].

    The nominal swing lies in the ground plane; the vertical motion comes from the style's
    curves. Planar rotations make SLERP a linear interpolation of the wrapped yaw difference.
    """
    a = smoothstep(progress)
    x = (1.0 - a) * start.x + a * target.x
    y = (1.0 - a) * start.y + a * target.y
    yaw = start.yaw + a * wrap_angle(target.yaw - start.yaw)
    return x, y, yaw, smoothstep_rate(progress)
