"""Footstep plan (paper §4.2): stance transforms (Eq. 4), footholds and the safe stepping region."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from engine.geometry import wrap_angle


@dataclass(frozen=True)
class Foothold:
    """A planar foothold: sole-centre position on the ground and yaw."""

    x: float
    y: float
    yaw: float

    def as_array(self) -> np.ndarray:
        return np.array([self.x, self.y, self.yaw])

    def position(self) -> np.ndarray:
        return np.array([self.x, self.y, 0.0])

    def to_local(self, other: "Foothold") -> np.ndarray:
        """(x, y, yaw) of ``other`` expressed in this foothold's frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        dx, dy = other.x - self.x, other.y - self.y
        return np.array([c * dx + s * dy, -s * dx + c * dy, wrap_angle(other.yaw - self.yaw)])

    def from_local(self, local: np.ndarray) -> "Foothold":
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Foothold(self.x + c * local[0] - s * local[1], self.y + s * local[0] + c * local[1], self.yaw + local[2])

    def corners(self, length_m: float, width_m: float, front_trim_m: float = 0.0) -> np.ndarray:
        """(4, 2) sole corners on the ground, counter-clockwise: back-left, back-right, front-right, front-left.
        ``front_trim_m`` cuts the rectangle short at the toe (the heel stays)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        trim = min(max(front_trim_m, 0.0), 0.9 * length_m)
        hl, hw = 0.5 * (length_m - trim), 0.5 * width_m
        x, y = self.x - c * 0.5 * trim, self.y - s * 0.5 * trim
        return np.array([[x - c * hl - s * hw, y - s * hl + c * hw], [x - c * hl + s * hw, y - s * hl - c * hw],
                         [x + c * hl + s * hw, y + s * hl - c * hw], [x + c * hl - s * hw, y + s * hl + c * hw]])


def stance_offset(side: str, width_m: float, splay_rad: float, x_bias_m: float) -> np.ndarray:
    """p_stance of Eq. 4 (Fig. 7): the foot's planar pose in the path frame at zero velocity."""
    return np.array(stance_offset_xy_yaw(side, width_m, splay_rad, x_bias_m))


def stance_offset_xy_yaw(side: str, width_m: float, splay_rad: float, x_bias_m: float) -> tuple[float, float, float]:
    """:func:`stance_offset` as floats (x, y, yaw)."""
    sign = 1.0 if side == "left" else -1.0
    return sign * 0.5 * x_bias_m, sign * 0.5 * width_m, sign * 0.5 * splay_rad


def foothold_from_path(path_pose: np.ndarray | Sequence[float], stance: np.ndarray | Sequence[float]) -> Foothold:
    """Eq. 4: p_foothold = p^v(t_foothold) ⊕ p_stance."""
    c, s = math.cos(path_pose[2]), math.sin(path_pose[2])
    return Foothold(path_pose[0] + c * stance[0] - s * stance[1], path_pose[1] + s * stance[0] + c * stance[1],
                    path_pose[2] + stance[2])


@dataclass(frozen=True)
class SafeRegion:
    """Where a swing foot may land relative to the support foot (in the support foot's frame).

    Three regions as in the paper — beside (|y| ≥ side_m on the swing foot's own side), in
    front (x ≥ front_m) and behind (x ≤ −front_m), the latter two still at least cross_m on
    the own side so legs never cross. A target outside all three is clipped to the nearest
    point on their boundary. Relative yaw is limited to ±max_yaw_rad.
    """

    side_m: float
    front_m: float
    cross_m: float
    max_yaw_rad: float = 0.7

    @classmethod
    def for_sole(cls, length_m: float, width_m: float) -> "SafeRegion":
        return cls(side_m=width_m + 0.03, front_m=length_m + 0.02, cross_m=0.5 * width_m + 0.02)


def project_to_safe_region(support: Foothold, target: Foothold, swing_side: str, region: SafeRegion) -> Foothold:
    """The paper's conservative heuristic for a foothold overlapping the support foot."""
    # support.to_local(target) on floats (the same numbers, without the array)
    c, s = math.cos(support.yaw), math.sin(support.yaw)
    dx, dy = float(target.x - support.x), float(target.y - support.y)
    local_yaw = float(wrap_angle(target.yaw - support.yaw))
    sign = 1.0 if swing_side == "left" else -1.0
    x, y_own = c * dx + s * dy, sign * (-s * dx + c * dy)  # y_own > 0: on the swing foot's own side
    candidates = (
        (x, max(y_own, region.side_m)),  # beside
        (max(x, region.front_m), max(y_own, region.cross_m)),  # in front / behind (still not crossing)
        (min(x, -region.front_m), max(y_own, region.cross_m)),
    )
    # The nearest candidate (the first of equals: min() with this key, without its calls)
    best, best_d2 = candidates[0], (candidates[0][0] - x) ** 2 + (candidates[0][1] - y_own) ** 2
    for p in candidates[1:]:
        d2 = (p[0] - x) ** 2 + (p[1] - y_own) ** 2
        if d2 < best_d2:
            best, best_d2 = p, d2
    yaw = min(max(local_yaw, -region.max_yaw_rad), region.max_yaw_rad)  # np.clip's order: max, then min
    if best == (x, y_own) and yaw == local_yaw:
        return target
    return support.from_local(np.array([best[0], sign * best[1], yaw]))
