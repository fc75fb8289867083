"""The path frame (paper §4.1, Fig. 4): the integral of the planar velocity command."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


def arc_displacement(v: np.ndarray | Sequence[float], dt_s: float) -> tuple[float, float, float]:
    """Exact displacement (dx, dy, dθ) in the starting frame after ``dt_s`` at constant body
    velocity v = (ẋ, ẏ, θ̇): a circular arc ("a simple arc assuming zero acceleration")."""
    vx, vy, w = float(v[0]), float(v[1]), float(v[2])
    th = w * dt_s
    if abs(th) < 1e-9:
        c, s = 1.0 - 0.5 * th * th, th - th ** 3 / 6.0
        sinc, cosc = dt_s * (1.0 - th * th / 6.0), dt_s * (0.5 * th)
    else:
        s, c = math.sin(th), math.cos(th)
        sinc, cosc = s / w, (1.0 - c) / w
    dx = vx * sinc - vy * cosc
    dy = vx * cosc + vy * sinc
    return dx, dy, th


@dataclass
class PathFrame:
    """Planar pose (x, y, θ) of the walking path relative to the inertial origin."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    def pose(self) -> np.ndarray:
        return np.array([self.x, self.y, self.yaw])

    def advance(self, v: np.ndarray, dt_s: float) -> None:
        self.x, self.y, self.yaw = predict_xy_yaw(float(self.x), float(self.y), float(self.yaw), v, dt_s)

    def predicted(self, v: np.ndarray, dt_s: float) -> np.ndarray:
        return predict(self.pose(), v, dt_s)


def predict(pose: np.ndarray, v: np.ndarray, dt_s: float) -> np.ndarray:
    """Pose after ``dt_s`` along the arc of constant body velocity ``v``."""
    return np.array(predict_xy_yaw(float(pose[0]), float(pose[1]), float(pose[2]), v, dt_s))


def predict_xy_yaw(x: float, y: float, yaw: float, v: np.ndarray | Sequence[float],
                   dt_s: float) -> tuple[float, float, float]:
    """:func:`predict` on floats: (x, y, yaw) after ``dt_s`` along the arc of constant body velocity ``v``."""
    dx, dy, th = arc_displacement(v, dt_s)
    c, s = math.cos(yaw), math.sin(yaw)
    return x + c * dx - s * dy, y + s * dx + c * dy, yaw + th
