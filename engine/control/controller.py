"""The controller slot: what every whole-body controller consumes and produces.

The simulation calls ``compute`` at the control rate (500 Hz) with the robot state and
tracks the returned joint set-points with PD plus feed-forward torque, exactly as joint
servos do on hardware:  τ = kp (q* − q) + kd (q̇* − q̇) + τ_ff, clipped to the effort limits.
A standing PD controller, the paper's task-space inverse dynamics and placo's dynamics
solver all sit behind this one interface.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass
class RobotState:
    """Robot state in pinocchio conventions (q: xyz, quat xyzw, joints; v: base-frame twist, joints)."""

    t_s: float
    q: np.ndarray
    v: np.ndarray
    imu: object | None = None  # an estimator.ImuSample from the robot's IMU, when simulated


@dataclass
class JointCommand:
    """Joint-level set-points for the servos (all arrays in the robot's actuated-joint order)."""

    q_des: np.ndarray
    qd_des: np.ndarray
    tau_ff: np.ndarray
    kp: np.ndarray
    kd: np.ndarray

    def torque(self, q: np.ndarray, qd: np.ndarray, limits: np.ndarray,
               neg_limits: np.ndarray | None = None) -> np.ndarray:
        """kp (q* − q) + kd (q̇* − q̇) + τ_ff clipped to ±``limits`` (``neg_limits``: −limits, when the
        caller keeps it). In place on one new array: the same operations, in the same order, as the
        expression ``np.clip(kp * (q* − q) + kd * (q̇* − q̇) + τ_ff, −limits, limits)``."""
        tau = self.q_des - q
        tau *= self.kp
        rate = self.qd_des - qd
        rate *= self.kd
        tau += rate
        tau += self.tau_ff
        np.maximum(tau, -limits if neg_limits is None else neg_limits, out=tau)
        return np.minimum(tau, limits, out=tau)


class Controller(Protocol):
    """A whole-body controller running at the control rate."""

    name: str

    def reset(self, state: RobotState) -> None: ...

    def compute(self, state: RobotState) -> JointCommand: ...


class StandingPdController:
    """Holds a posture with joint PD around a constant feed-forward (e.g. static balance torques)."""

    name = "standing-pd"

    def __init__(self, q_joints: np.ndarray, kp: np.ndarray, kd: np.ndarray, tau_ff: np.ndarray | None = None):
        self.q_joints = np.asarray(q_joints, dtype=float).copy()
        self.kp = np.asarray(kp, dtype=float)
        self.kd = np.asarray(kd, dtype=float)
        self.tau_ff = np.zeros_like(self.q_joints) if tau_ff is None else np.asarray(tau_ff, dtype=float)

    def reset(self, state: RobotState) -> None:
        pass

    def compute(self, state: RobotState) -> JointCommand:
        n = self.q_joints.size
        return JointCommand(self.q_joints, np.zeros(n), self.tau_ff, self.kp, self.kd)
