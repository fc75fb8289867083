"""Shared by the whole-body controllers: joint set-points integrated from q̈ (clipped to a band around
the measured state) and the fallback hold."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from engine.control.controller import JointCommand, RobotState
from engine.robot.model import RobotModel
from engine.control.wbc.reference import WbcGains

FloatArray = NDArray[np.float64]


# ----------------------------------------------------------------------------- shared by the whole-body controllers


def integrate_setpoints(q_des: FloatArray, qd_des: FloatArray, qdd_joints: FloatArray, state: RobotState,
                        gains: WbcGains, dt_s: float) -> tuple[FloatArray, FloatArray]:
    """Integrate joint accelerations into position/velocity set-points, each clipped to a band
    around the measured joint state (the servo never chases a set-point that ran away)."""
    qj, vj = state.q[7:], state.v[6:]
    # np.minimum/np.maximum: the same clip at a fraction of np.clip's call overhead
    qd = np.minimum(np.maximum(qd_des + qdd_joints * dt_s, vj - gains.max_velocity_error_radps),
                    vj + gains.max_velocity_error_radps)
    q = np.minimum(np.maximum(q_des + qd * dt_s, qj - gains.max_position_error_rad), qj + gains.max_position_error_rad)
    return q, qd


def fallback_hold(robot: RobotModel, state: RobotState, q_des: FloatArray | None, last_tau: FloatArray,
                  dt_s: float, decay_s: float) -> JointCommand:
    """Stiff PD hold of the last set-point (else the measured joints, else the standing pose)
    with the last good torques decaying over ``decay_s``: finite whatever came in."""
    n = robot.n_joints
    q_meas = np.asarray(state.q, dtype=float)[7:] if np.shape(state.q) == (robot.pin_model.nq,) else np.full(n, np.nan)
    hold = q_des if q_des is not None and np.shape(q_des) == (n,) and np.all(np.isfinite(q_des)) else q_meas
    if not np.all(np.isfinite(hold)):
        hold = robot.q_standing[7:]
    tau = np.where(np.isfinite(last_tau), last_tau, 0.0) * math.exp(-dt_s / decay_s)
    return JointCommand(np.array(hold, dtype=float), np.zeros(n), tau, robot.kp.copy(), robot.kd.copy())
