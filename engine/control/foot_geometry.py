"""The robot's foot geometry the walking controller plans with: which joint holds the CoP at the toe
(the ankle pitch above the sole), and how much shorter at the toe the MPC's soles must be for that joint's
actuators to hold the CoP there (ankle torque = distance ahead of the ankle · load · m g)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engine.constants import GRAVITY_MPS2
from engine.control.walking_parameters import WalkingParameters
from engine.gait.style import SIDES
from engine.robot.model import RobotModel


def ankle_pitch_joint(robot: RobotModel, side: str) -> tuple[str, float]:
    """(name, x offset from the sole centre along the foot, m) of the joint nearest the sole
    whose axis is the foot's lateral axis: the ankle pitch that must hold the CoP at the toe."""
    model = robot.pin_model
    data = model.createData()
    q = robot.q_standing
    fid = model.getFrameId(f"{side}_foot")
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    sole = data.oMf[fid]
    jac = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)
    lateral, forward = sole.rotation[:, 1], sole.rotation[:, 0]
    j = model.frames[fid].parentJoint
    while j > 1:  # 0: universe, 1: the free base
        col = model.joints[j].idx_v
        axis = jac[3:, col]
        if np.linalg.norm(axis) > 0.5 and abs(axis @ lateral) > 0.9 * np.linalg.norm(axis):
            return model.names[j], float((data.oMi[j].translation - sole.translation) @ forward)
        j = model.parents[j]
    raise ValueError(f"{robot.name}: no ankle pitch joint above {side}_foot")


def toe_trim_m(robot: RobotModel, margin_m: float, load_factor: float = WalkingParameters.ankle_load_factor,
               torque_fraction: float = 0.9) -> float:
    """How much shorter at the toe the MPC's soles must be for the ankle pitch actuators to hold
    the CoP there: a CoP a distance d ahead of the ankle needs d · load · m g of ankle torque."""
    trims = []
    for side in SIDES:
        name, offset = ankle_pitch_joint(robot, side)
        effort = float(robot.effort_limits[robot.joint_names.index(name)])
        if effort <= 0.0:
            continue
        reach = torque_fraction * effort / (load_factor * robot.mass_kg * GRAVITY_MPS2) + offset
        half = 0.5 * robot.config.soles[side].length_m - margin_m
        trims.append(max(half - reach, 0.0))
    return max(trims, default=0.0)
