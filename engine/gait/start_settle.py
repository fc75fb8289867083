"""Start settle: from a reset the reference's posture eases from the pose the robot stands in into the style's.

The gait reference r(t) of a style starts in the style's posture: its pelvis height, pelvis roll and pitch and
upper-body joints at the start phase. The robot, reset, stands in its standing pose. Without a settle the
whole-body controller meets the difference in one tick (a G1 style with the pelvis 14 cm below standing and
10–17° of pelvis roll and pitch: the pelvis drops 12 cm in 0.3 s, the feet take ±85 N of opposite horizontal
force and creep 2–3 mm before the first step; README "… settling into the style from the standing pose", stop 42).

:class:`StartSettle` blends, over ``duration_s`` from the reset and by a smoothstep s(t) (zero rate at both
ends), each posture channel of the reference from the start pose toward the style's value *now*:

* pelvis height ``z = z₀ + s (z_style − z₀)``, its rate ``s ż_style + ṡ (z_style − z₀)``;
* upper-body joints the same, per joint;
* pelvis orientation ``R = R₀ exp(s log(R₀ᵀ R_style))`` with R₀ the start pose's roll and pitch under the
  path's yaw now (the path turns: the start pose turns with it), its angular velocity
  ``s ω_style + ṡ R₀ log(R₀ᵀ R_style)``.

The feet and the CoM plan are not touched: the feet stand where the robot stands until its first step, and the
CoM MPC plans from the measured CoM. At ``t ≥ duration_s`` the reference is the style's, bit for bit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.geometry import smoothstep, smoothstep_rate
from engine.geometry.rotation import exp_so3, log_so3, roll_pitch_of, rot_zyx

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class StartPose:
    """The posture the robot stands in at a reset, in the terms of the gait reference."""

    pelvis_height_m: float  # world z of the pelvis (the floor at z = 0)
    pelvis_roll_rad: float
    pelvis_pitch_rad: float
    upper_q_rad: FloatArray  # (K,) the upper-body joints, in the reference's order

    @classmethod
    def from_state(cls, pelvis_z_m: float, pelvis_rot: FloatArray, upper_q_rad: FloatArray) -> StartPose:
        roll, pitch = roll_pitch_of(np.asarray(pelvis_rot, dtype=float))
        return cls(float(pelvis_z_m), float(roll), float(pitch), np.array(upper_q_rad, dtype=float))


class StartSettle:
    """Eases the reference's posture from a :class:`StartPose` into the style's over ``duration_s``."""

    def __init__(self, duration_s: float) -> None:
        self.duration_s = float(duration_s)
        self._pose: StartPose | None = None

    @property
    def enabled(self) -> bool:
        return self.duration_s > 0.0

    def reset(self, pose: StartPose | None) -> None:
        """Start easing from ``pose`` (None, or a zero duration: the style's posture from the first tick)."""
        self._pose = pose if self.enabled else None

    def active(self, t_s: float) -> bool:
        return self._pose is not None and t_s < self.duration_s

    def share(self, t_s: float) -> tuple[float, float]:
        """(s, ds/dt): the style's share of the posture ``t_s`` after the reset and its rate [1/s]."""
        if not self.enabled:
            return 1.0, 0.0
        u = t_s / self.duration_s
        return smoothstep(u), smoothstep_rate(min(max(u, 0.0), 1.0)) / self.duration_s

    def apply(self, t_s: float, path_yaw_rad: float, pelvis_z_m: float, pelvis_z_rate_mps: float,
              pelvis_rot: FloatArray, pelvis_ang_vel_radps: FloatArray, upper_q_rad: FloatArray,
              upper_qd_radps: FloatArray) -> tuple[float, float, FloatArray, FloatArray, FloatArray, FloatArray]:
        """The settled (pelvis z, its rate, pelvis rotation, its world angular velocity, upper joints, their rates)
        ``t_s`` after the reset, from the style's; the style's own values once settled (or without a pose)."""
        pose = self._pose
        if pose is None or t_s >= self.duration_s:
            return pelvis_z_m, pelvis_z_rate_mps, pelvis_rot, pelvis_ang_vel_radps, upper_q_rad, upper_qd_radps
        s, ds = self.share(t_s)
        dz = pelvis_z_m - pose.pelvis_height_m
        z = pose.pelvis_height_m + s * dz
        z_rate = s * pelvis_z_rate_mps + ds * dz
        dq = np.asarray(upper_q_rad, dtype=float) - pose.upper_q_rad
        q = pose.upper_q_rad + s * dq
        qd = s * np.asarray(upper_qd_radps, dtype=float) + ds * dq
        r0 = rot_zyx(path_yaw_rad, pose.pelvis_pitch_rad, pose.pelvis_roll_rad)
        w = log_so3(r0.T @ np.asarray(pelvis_rot, dtype=float))  # the start pose's rotation to the style's (body)
        rot = r0 @ exp_so3(s * w)
        ang_vel = s * np.asarray(pelvis_ang_vel_radps, dtype=float) + ds * (r0 @ w)
        return z, z_rate, rot, ang_vel, q, qd


__all__ = ["StartPose", "StartSettle"]
