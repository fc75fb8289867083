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

from engine.constants import FOOT_FRAMES  # (re-exported: the soles' frames)
RESEED_ERROR_M = 0.01  # a warm-started solve missing by more than this is solved again from standing
MAX_STEP = 0.2  # largest Gauss-Newton step (norm over base m/rad and joint rad)
COM_WEIGHT = 0.1  # the CoM plan gives way to the reference (feet, pelvis) where both cannot be met


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
        legs = sorted(leg_joints, key=lambda j: self.model.joints[j].idx_v)
        self.leg_v = [self.model.joints[j].idx_v for j in legs]
        self.active_v = np.array(list(range(6)) + self.leg_v)
        leg_q = np.array([self.model.joints[j].idx_q for j in legs], dtype=int)
        self._leg_q = leg_q
        self._leg_lower = self.model.lowerPositionLimit[leg_q]
        self._leg_upper = self.model.upperPositionLimit[leg_q]
        names = robot.joint_names
        self.upper_q_index = np.array([7 + names.index(j) for j in upper_joints], dtype=int)
        self.q = robot.q_standing.copy()
        self.last_error = 0.0  # residual of the reference: both soles (6-D), pelvis height and rotation
        self.last_com_error = 0.0  # how far the CoM is from the plan's (it gives way where the feet cannot reach)
        self.last_iterations = 0

    def reset(self, q: np.ndarray | None = None) -> None:
        self.q = (self.robot.q_standing if q is None else q).copy()

    def solve(self, ref: GaitReference, com_xy: np.ndarray, q_init: np.ndarray | None = None) -> np.ndarray:
        """Configuration realising ``ref`` with the horizontal CoM at ``com_xy`` (warm-started).

        A warm start can leave the legs in a fold the damped steps cannot undo (a knee pinned at its
        limit): when the warm-started solve misses by more than ``RESEED_ERROR_M`` it is solved again
        from the standing pose placed at the reference pelvis, and the better of the two is kept."""
        q, norm, errors, iterations = self._iterate(self.q if q_init is None else q_init, ref, com_xy)
        if norm > RESEED_ERROR_M:
            seed = self.robot.q_standing.copy()
            seed[:2] = com_xy
            seed[2] = ref.pelvis_z
            seed[3:7] = pin.Quaternion(ref.pelvis_rot).coeffs()  # pinocchio's free flyer: x, y, z, w
            q2, norm2, errors2, it2 = self._iterate(seed, ref, com_xy)
            iterations += it2
            if norm2 < norm:
                q, norm, errors = q2, norm2, errors2
        self.last_error, self.last_com_error = errors
        self.last_iterations = iterations
        self.q = q
        return q.copy()

    def _iterate(self, q_start: np.ndarray, ref: GaitReference,
                 com_xy: np.ndarray) -> tuple[np.ndarray, float, tuple[float, float], int]:
        """Damped, weighted Gauss-Newton from ``q_start``: (configuration, weighted residual norm,
        (reference residual, CoM residual), iterations). Square (18 equations, 18 coordinates):
        where the reference is reachable every row is met whatever the weights; where it is not,
        the CoM (weight ``COM_WEIGHT``) gives way first, so the pelvis moves until the feet reach.
        Steps are capped (``MAX_STEP``) and the best iterate is kept: a miss degrades, never diverges."""
        model, data = self.model, self.data
        q = q_start.copy()
        if len(self.upper_q_index):
            q[self.upper_q_index] = ref.upper_q
        targets = [pin.SE3(ref.foot_rot[i], ref.foot_pos[i]) for i in range(2)]
        rows = 6 + 6 + 1 + 3 + 2
        err = np.zeros(rows)
        jac = np.zeros((rows, model.nv))
        norm = np.inf
        weight = np.ones(rows)
        weight[16:18] = COM_WEIGHT
        best_q, best_norm, best_errors = q, np.inf, (np.inf, np.inf)
        it = 0
        for it in range(self.max_iterations + 1):  # the last pass only measures the last step
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
            norm = float(np.linalg.norm(weight * err))
            if norm < best_norm:
                best_q, best_norm = q, norm
                best_errors = (float(np.linalg.norm(err[:16])), float(np.linalg.norm(err[16:18])))
            if norm < self.tolerance or it == self.max_iterations:
                break
            step = self._step(q, weight[:, None] * jac[:, self.active_v], weight * err)
            size = float(np.linalg.norm(step))
            if size > MAX_STEP:  # a target out of reach makes the legs' Jacobian singular: no leaps
                step *= MAX_STEP / size
            dv = np.zeros(model.nv)
            dv[self.active_v] = step
            q = pin.integrate(model, q, dv)
            q[7:] = np.clip(q[7:], model.lowerPositionLimit[7:], model.upperPositionLimit[7:])
        return best_q, best_norm, best_errors, it + 1

    def _step(self, q: np.ndarray, ja: np.ndarray, rhs: np.ndarray) -> np.ndarray:
        """Damped least-squares step over the active coordinates; a leg joint at a limit that the
        step would push further is held (its column dropped) and the step solved again, so the
        other coordinates take up what it cannot (clipping alone would stall the iteration)."""
        leg = q[self._leg_q]
        at_lower = leg <= self._leg_lower + 1e-9
        at_upper = leg >= self._leg_upper - 1e-9
        free = np.ones(ja.shape[1], dtype=bool)
        step = np.zeros(ja.shape[1])
        for _ in range(4):
            a = ja[:, free]
            step[:] = 0.0
            step[free] = np.linalg.solve(a.T @ a + self.damping * np.eye(a.shape[1]), a.T @ rhs)
            blocked = (at_lower & (step[6:] < 0.0)) | (at_upper & (step[6:] > 0.0))
            if not blocked.any():
                break
            free[6:] &= ~blocked
        return step


class SupportCenterComPlan:
    """A simple horizontal CoM plan: part-way to the support centre, critically damped.

    Stands in wherever no MPC runs (a smoothed sway toward the stance foot); the control
    stack's CoM MPC replaces it when the robot is simulated. The support centre moves with
    the path, so the path's velocity is fed forward: a critically damped follower without it
    trails a target moving at v by 2τv (11 cm at 0.45 m/s), which holds the pelvis back of the
    feet until the front foot leaves the leg's reach. The MPC's CoM has no such lag (dino
    neutral at 0.45 m/s: 2 cm behind the feet's middle, this plan 9 cm without the feed-forward).
    ``feed_forward=False`` is the trailing follower (the feasibility check's findings were
    calibrated with it).
    """

    def __init__(self, time_constant_s: float = 0.12, sway_fraction: float = 0.6, feed_forward: bool = True):
        self.tau = time_constant_s
        self.sway = sway_fraction
        self.feed_forward = feed_forward
        self.pos: np.ndarray | None = None
        self.vel = np.zeros(2)
        self._path_xy: np.ndarray | None = None

    def reset(self, com_xy: np.ndarray) -> None:
        self.pos = np.asarray(com_xy, dtype=float).copy()
        self.vel = np.zeros(2)
        self._path_xy = None

    def step(self, dt_s: float, ref: GaitReference) -> np.ndarray:
        down = [i for i in range(2) if ref.contact[i]]
        middle = ref.foot_pos[:, :2].mean(axis=0)
        support = ref.foot_pos[down, :2].mean(axis=0) if down else middle
        target = middle + self.sway * (support - middle)
        path_xy = np.asarray(ref.path_pose[:2], dtype=float)
        moved = self.feed_forward and self._path_xy is not None and dt_s > 0
        path_vel = (path_xy - self._path_xy) / dt_s if moved else np.zeros(2)
        self._path_xy = path_xy.copy()
        if self.pos is None:
            self.reset(target)
            self._path_xy = path_xy.copy()
        pos = self.pos if self.pos is not None else target
        w = 1.0 / self.tau
        acc = w * w * (target - pos) + 2.0 * w * (path_vel - self.vel)
        self.vel = self.vel + dt_s * acc
        self.pos = pos + dt_s * self.vel
        return self.pos.copy()
