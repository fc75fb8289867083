"""Smooth scalar blends (smoothstep, smooth min/max) used by the gait planner's timings."""

from __future__ import annotations

import math


def smoothstep(s: float) -> float:
    """3s² − 2s³ on [0, 1] (zero slope at both ends)."""
    s = 0.0 if s < 0 else (1.0 if s > 1 else s)
    return s * s * (3.0 - 2.0 * s)


def smooth_min(a: float, b: float, eps: float) -> float:
    """C∞ approximation of min(a, b), below it by at most eps/2."""
    return 0.5 * (a + b - math.sqrt((a - b) ** 2 + eps * eps))


def smooth_max(a: float, b: float, eps: float) -> float:
    """C∞ approximation of max(a, b), above it by at most eps/2."""
    return 0.5 * (a + b + math.sqrt((a - b) ** 2 + eps * eps))


def smoothstep_rate(s: float) -> float:
    return 6.0 * s * (1.0 - s) if 0.0 < s < 1.0 else 0.0
