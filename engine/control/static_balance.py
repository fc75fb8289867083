"""Static balance: joint torques that hold a posture against gravity on its contacts.

Used as the feed-forward of the standing controller: with it, joint PD only has to correct
errors instead of holding the robot's weight by sagging.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engine.robot.model import RobotModel, contact_frame_names


def static_contact_torques(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """τ (actuated joints) balancing gravity at rest, weight spread over the contact points.

    Solves the floating-base rows  g_base(q) = J_base(q)ᵀ f  for the minimum-norm contact
    forces f, then τ = g_joints(q) − J_jointsᵀ f.
    """
    model = robot.pin_model
    data = model.createData()
    gravity = pin.computeGeneralizedGravity(model, data, q)
    frames = contact_frame_names(robot.config)
    if not frames:
        return np.zeros(robot.n_joints)
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    jac = np.vstack([
        pin.getFrameJacobian(model, data, model.getFrameId(f), pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
        for f in frames
    ])
    forces, *_ = np.linalg.lstsq(jac[:, :6].T, gravity[:6], rcond=None)
    return gravity[6:] - jac[:, 6:].T @ forces
