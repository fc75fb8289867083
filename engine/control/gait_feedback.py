"""Gait feedback (paper §7.1): velocity adjustment, step adjustment and time scaling.

All three act on the horizontal CoM error e = x̂_com − r_com (estimate minus MPC reference):

* velocity adjustment Δ_vel — a deadband and a 0.15 Hz low-pass on a combination of the
  position and velocity errors, added to the command: persistent errors accelerate the
  robot toward them ("buying time at the expense of drift");
* step adjustment Δ_step — the upcoming foothold moves toward the error (capture-point-like
  combination), so the next support catches the CoM;
* time scaling κ = exp(k_p ε + k_d ε̇), with ε, ε̇ the errors along the axis from the current
  to the next foothold, bounded separately in single and double support: κ > 1 speeds the
  reference up so it catches a CoM that runs ahead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from engine.constants import GRAVITY_MPS2


@dataclass(frozen=True)
class GaitFeedbackGains:
    velocity_kp_per_s: float = 0.8  # Δ_vel from position error (1/s)
    velocity_kd: float = 0.4  # Δ_vel from velocity error
    velocity_deadband_mps: float = 0.04
    velocity_cutoff_hz: float = 0.15
    velocity_max_mps: float = 0.4
    step_gain: float = 0.8  # × capture-point error
    step_deadband_m: float = 0.01
    step_max_m: float = 0.15
    time_kp_per_m: float = 4.0
    time_kd_s_per_m: float = 1.0
    kappa_single: tuple[float, float] = (0.75, 1.35)
    kappa_double: tuple[float, float] = (0.5, 2.0)

    @classmethod
    def for_robot(cls, name: str) -> "GaitFeedbackGains":
        """The defaults with the robot's ``[control.gait_feedback]`` table (robots/<name>.toml) applied."""
        return cls().with_config_overrides(name)

    def with_config_overrides(self, name: str) -> "GaitFeedbackGains":
        """These gains with robot ``name``'s ``[control.gait_feedback]`` table applied."""
        from dataclasses import fields, replace

        from engine.robot.config import RobotConfigError, load_robot_config

        cfg = load_robot_config(name)
        known = {f.name: f for f in fields(self)}
        values: dict[str, Any] = {}  # float or (low, high) per field, checked against the field above
        for key, value in cfg.gait_feedback.items():
            if key not in known:
                raise RobotConfigError(f"{cfg.path.name}: control.gait_feedback.{key}: unknown gain; expected one of "
                                       f"{', '.join(sorted(known))}")
            is_pair = isinstance(getattr(self, key), tuple)
            if is_pair != isinstance(value, tuple):
                raise RobotConfigError(f"{cfg.path.name}: control.gait_feedback.{key}: expected "
                                       f"{'[low, high]' if is_pair else 'a number'}, got {value!r}")
            values[key] = value
        return replace(self, **values) if values else self


@dataclass
class FeedbackOutput:
    velocity_adjust_mps: np.ndarray  # (2,) path frame, added to the command's [vx, vy]
    step_adjust_m: np.ndarray  # (2,) world, added to the upcoming foothold
    kappa: float
    epsilon_m: float
    epsilon_rate_mps: float
    error_m: np.ndarray  # (2,) world CoM position error


def _deadband_xy(x: float, y: float, width: float) -> tuple[float, float]:
    """(x, y) shrunk toward 0 by ``width`` (0 within it)."""
    norm = math.sqrt(x * x + y * y)
    if norm <= width:
        return 0.0, 0.0
    f = 1.0 - width / norm
    return x * f, y * f


class GaitFeedback:
    def __init__(self, gains: GaitFeedbackGains | None = None, enabled: bool = True):
        self.gains = gains or GaitFeedbackGains()
        self.enabled = enabled
        self.velocity_adjust = np.zeros(2)
        self.last = FeedbackOutput(np.zeros(2), np.zeros(2), 1.0, 0.0, 0.0, np.zeros(2))

    def reset(self) -> None:
        self.velocity_adjust = np.zeros(2)
        self.last = FeedbackOutput(np.zeros(2), np.zeros(2), 1.0, 0.0, 0.0, np.zeros(2))

    def update(self, dt_s: float, com_xy: np.ndarray, com_vel_xy: np.ndarray, ref_com_xy: np.ndarray,
               ref_com_vel_xy: np.ndarray, com_height_m: float, path_yaw_rad: float,
               stance_xy: np.ndarray | None, next_xy: np.ndarray | None, single_support: bool) -> FeedbackOutput:
        # On floats (x, y): the same IEEE operations as the former 2-vector numpy expressions (a 2-vector
        # dot is x0·y0 + x1·y1, unfused); tests/control/test_stack_speed_references.py keeps that version.
        g = self.gains
        cx, cy = np.asarray(com_xy, dtype=float).tolist()
        rx, ry = np.asarray(ref_com_xy, dtype=float).tolist()
        vx, vy = np.asarray(com_vel_xy, dtype=float).tolist()
        wx, wy = np.asarray(ref_com_vel_xy, dtype=float).tolist()
        ex, ey, edx, edy = cx - rx, cy - ry, vx - wx, vy - wy
        e = np.array([ex, ey])
        if not self.enabled or not (math.isfinite(ex) and math.isfinite(ey) and math.isfinite(edx) and math.isfinite(edy)):
            self.last = FeedbackOutput(np.zeros(2), np.zeros(2), 1.0, 0.0, 0.0, np.where(np.isfinite(e), e, 0.0))
            return self.last
        # Velocity adjustment: deadband, then a first-order low-pass at 0.15 Hz; path frame.
        kp, kd = g.velocity_kp_per_s, g.velocity_kd
        raw_x, raw_y = _deadband_xy(kp * ex + kd * edx, kp * ey + kd * edy, g.velocity_deadband_mps)
        alpha = 1.0 - math.exp(-2.0 * math.pi * g.velocity_cutoff_hz * dt_s)
        ax, ay = self.velocity_adjust.tolist()
        ax, ay = ax + alpha * (raw_x - ax), ay + alpha * (raw_y - ay)
        norm = math.sqrt(ax * ax + ay * ay)
        if norm > g.velocity_max_mps:
            f = g.velocity_max_mps / norm
            ax, ay = ax * f, ay * f
        self.velocity_adjust[0], self.velocity_adjust[1] = ax, ay
        c, s = math.cos(path_yaw_rad), math.sin(path_yaw_rad)
        vel_path = np.array([c * ax + s * ay, -s * ax + c * ay])
        # Step adjustment toward the capture-point error.
        omega = math.sqrt(GRAVITY_MPS2 / max(com_height_m, 0.2))
        gain = g.step_gain
        sx, sy = _deadband_xy(gain * (ex + edx / omega), gain * (ey + edy / omega), g.step_deadband_m)
        norm = math.sqrt(sx * sx + sy * sy)
        if norm > g.step_max_m:
            f = g.step_max_m / norm
            sx, sy = sx * f, sy * f
        step = np.array([sx, sy])
        # Time scaling along the axis from the current to the next foothold.
        eps = eps_rate = 0.0
        if stance_xy is not None and next_xy is not None:
            nx, ny = np.asarray(next_xy, dtype=float).tolist()
            px, py = np.asarray(stance_xy, dtype=float).tolist()
            axis_x, axis_y = nx - px, ny - py
            length = math.sqrt(axis_x * axis_x + axis_y * axis_y)
            if length > 1e-3:
                ux, uy = axis_x / length, axis_y / length
                eps, eps_rate = ex * ux + ey * uy, edx * ux + edy * uy
        lo, hi = g.kappa_single if single_support else g.kappa_double
        # np.clip's min(max(·)) on floats
        kappa = min(max(math.exp(min(max(g.time_kp_per_m * eps + g.time_kd_s_per_m * eps_rate, -5.0), 5.0)), lo), hi)
        self.last = FeedbackOutput(vel_path, step, kappa, eps, eps_rate, e)
        return self.last
