"""Kinematic preview: whole-body inverse kinematics of the gait reference r(t).

Turns the planner's task-space reference (pelvis height and rotation, both sole poses,
upper-body joint angles) plus a horizontal CoM target into a full configuration q. The
studio's edit mode draws it as the translucent "reference ghost"; ``studio plan`` records
it. The horizontal CoM comes from the CoM plan (the MPC when available, else a smoothed
support-centre plan, :class:`SupportCenterComPlan`).

Solved by damped Gauss–Newton on pinocchio: 18 equations (two 6-D feet, pelvis z and
rotation, CoM xy) for the 6 base + leg coordinates; upper-body joints are set directly.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engine.gait.planner import GaitReference
from engine.robot.model import RobotModel

FOOT_FRAMES = ("left_foot", "right_foot")
RESEED_ERROR_M = 0.01  # a warm-started solve missing by more than this is solved again from standing


class KinematicPreview:
    def __init__(self, robot: RobotModel, upper_joints: tuple[str, ...], damping: float = 1e-6,
                 max_iterations: int = 12, tolerance: float = 1e-7):
        self.robot = robot
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.damping = damping
        self.max_iterations = max_iterations
        self.tolerance = tolerance
        self.foot_ids = [self.model.getFrameId(f) for f in FOOT_FRAMES]
        self.root_id = self.model.getFrameId(robot.config.root_link, pin.FrameType.BODY)
        # Coordinates the IK moves: the free base and the joints supporting the feet.
        leg_joints: set[int] = set()
        for fid in self.foot_ids:
            leg_joints.update(j for j in self.model.supports[self.model.frames[fid].parentJoint] if j > 1)
        self.leg_v = sorted(self.model.joints[j].idx_v for j in leg_joints)
        self.active_v = np.array(list(range(6)) + self.leg_v)
        names = robot.joint_names
        self.upper_q_index = np.array([7 + names.index(j) for j in upper_joints], dtype=int)
        self.q = robot.q_standing.copy()
        self.last_error = 0.0
        self.last_iterations = 0

    def reset(self, q: np.ndarray | None = None) -> None:
        self.q = (self.robot.q_standing if q is None else q).copy()

    def solve(self, ref: GaitReference, com_xy: np.ndarray, q_init: np.ndarray | None = None) -> np.ndarray:
        """Configuration realising ``ref`` with the horizontal CoM at ``com_xy`` (warm-started).

        A warm start can leave the legs in a fold the damped steps cannot undo (a knee pinned at its
        limit): when the warm-started solve misses by more than ``RESEED_ERROR_M`` it is solved again
        from the standing pose placed at the reference pelvis, and the better of the two is kept."""
        q, norm, iterations = self._iterate(self.q if q_init is None else q_init, ref, com_xy)
        if norm > RESEED_ERROR_M:
            seed = self.robot.q_standing.copy()
            seed[:2] = com_xy
            seed[2] = ref.pelvis_z
            seed[3:7] = pin.Quaternion(ref.pelvis_rot).coeffs()  # pinocchio's free flyer: x, y, z, w
            q2, norm2, it2 = self._iterate(seed, ref, com_xy)
            iterations += it2
            if norm2 < norm:
                q, norm = q2, norm2
        self.last_error = norm
        self.last_iterations = iterations
        self.q = q
        return q.copy()

    def _iterate(self, q_start: np.ndarray, ref: GaitReference, com_xy: np.ndarray) -> tuple[np.ndarray, float, int]:
        """Damped Gauss-Newton from ``q_start``: (configuration, residual norm, iterations)."""
        model, data = self.model, self.data
        q = q_start.copy()
        if len(self.upper_q_index):
            q[self.upper_q_index] = ref.upper_q
        targets = [pin.SE3(ref.foot_rot[i], ref.foot_pos[i]) for i in range(2)]
        rows = 6 + 6 + 1 + 3 + 2
        err = np.zeros(rows)
        jac = np.zeros((rows, model.nv))
        norm = np.inf
        for it in range(self.max_iterations):
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            com = pin.centerOfMass(model, data, q, False)
            jcom = pin.jacobianCenterOfMass(model, data, q, False)
            for i, fid in enumerate(self.foot_ids):
                cur = data.oMf[fid]
                err[6 * i:6 * i + 3] = targets[i].translation - cur.translation
                err[6 * i + 3:6 * i + 6] = pin.log3(targets[i].rotation @ cur.rotation.T)
                jac[6 * i:6 * i + 6] = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            root = data.oMf[self.root_id]
            jroot = pin.getFrameJacobian(model, data, self.root_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            err[12] = ref.pelvis_z - root.translation[2]
            jac[12] = jroot[2]
            err[13:16] = pin.log3(ref.pelvis_rot @ root.rotation.T)
            jac[13:16] = jroot[3:6]
            err[16:18] = com_xy - com[:2]
            jac[16:18] = jcom[:2]
            norm = float(np.linalg.norm(err))
            if norm < self.tolerance:
                break
            ja = jac[:, self.active_v]
            step = np.linalg.solve(ja.T @ ja + self.damping * np.eye(len(self.active_v)), ja.T @ err)
            dv = np.zeros(model.nv)
            dv[self.active_v] = step
            q = pin.integrate(model, q, dv)
            q[7:] = np.clip(q[7:], model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
        return q, norm, it + 1


class SupportCenterComPlan:
    """A simple horizontal CoM plan: part-way to the support centre, critically damped.

    Stands in wherever no MPC runs (a smoothed sway toward the stance foot); the control
    stack's CoM MPC replaces it when the robot is simulated.
    """

    def __init__(self, time_constant_s: float = 0.12, sway_fraction: float = 0.6):
        self.tau = time_constant_s
        self.sway = sway_fraction
        self.pos: np.ndarray | None = None
        self.vel = np.zeros(2)

    def reset(self, com_xy: np.ndarray) -> None:
        self.pos = np.asarray(com_xy, dtype=float).copy()
        self.vel = np.zeros(2)

    def step(self, dt_s: float, ref: GaitReference) -> np.ndarray:
        down = [i for i in range(2) if ref.contact[i]]
        middle = ref.foot_pos[:, :2].mean(axis=0)
        support = ref.foot_pos[down, :2].mean(axis=0) if down else middle
        target = middle + self.sway * (support - middle)
        if self.pos is None:
            self.reset(target)
        pos = self.pos if self.pos is not None else target
        w = 1.0 / self.tau
        acc = w * w * (target - pos) - 2.0 * w * self.vel
        self.vel = self.vel + dt_s * acc
        self.pos = pos + dt_s * self.vel
        return self.pos.copy()
