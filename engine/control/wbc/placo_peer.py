"""placo's DynamicsSolver behind the whole-body controller interface (peer and fallback).

Same reference (:class:`~engine.control.wbc.WbcReference`), same tracked
quantities and gains as our task-space ID, same joint set-point integration, so the two
can be swapped and measured against each other:

* feet: a frame task per sole (``left_foot``/``right_foot`` frames added at the sole
  centres); a foot with any active corner gets a planar contact (unilateral 6-D wrench,
  ZMP inside the sole rectangle, friction μ) and a hard frame task holding it still; a
  swing foot gets a soft frame task on the planner's pose/velocity,
* CoM task on x, y (PD on the MPC reference plus its acceleration),
* pelvis height (position task, z) and orientation,
* upper-body joints task, torque limits, placo's torque regularisation.

Differences from the paper's QP: placo models each sole contact as one 6-D wrench with a
ZMP rectangle (not per-corner friction pyramids), so a heel/toe contact still uses the
whole sole rectangle; there is no angular-momentum damping task. placo's joint limits are
hard constraints: once a landing impact pushes a joint past its limit the QP has no solution
and stays without one, so they are off here (our QP's limits are the paper's soft ones).
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
import placo
from numpy.typing import NDArray

from engine.control.controller import JointCommand, RobotState
from engine.constants import CONTROL_PERIOD_S, SIDES
from engine.control.wbc.reference import WbcDiagnostics, WbcGains, WbcReference
from engine.control.wbc.setpoints import fallback_hold, integrate_setpoints
from engine.robot.model import RobotModel
from engine.robot.urdf import with_extra_frames

FloatArray = NDArray[np.float64]

__all__ = ["PlacoWbc"]

TORQUE_LIMITS = True  # placo's actuator torque limits (hard, like ours)


def _pose(rotation: FloatArray, position: FloatArray) -> FloatArray:
    t = np.eye(4)
    t[:3, :3] = rotation
    t[:3, 3] = position
    return t


class PlacoWbc:
    """Whole-body control with placo 0.10's ``DynamicsSolver``: ``compute(state, ref) -> JointCommand``."""

    name = "placo-dynamics"

    def __init__(self, robot: RobotModel, gains: WbcGains | None = None,
                 upper_body_joints: Sequence[str] | None = None, dt_s: float = CONTROL_PERIOD_S):
        if set(robot.config.soles) != set(SIDES):
            raise ValueError(f"{robot.name}: the placo controller needs left and right soles")
        self.robot = robot
        self.gains = g = gains or WbcGains.for_robot(robot)
        self.dt_s = dt_s
        self.upper_body_joints = list(robot.config.upper_body_joints if upper_body_joints is None else upper_body_joints)
        frames = {f"{s}_foot": (robot.config.soles[s].link, _pose(np.eye(3), np.asarray(robot.config.soles[s].center)))
                  for s in SIDES}
        if robot.config.trunk_link:
            frames["trunk"] = (robot.config.trunk_link, np.eye(4))
        urdf = with_extra_frames(robot.urdf_text, frames)
        self.wrapper = placo.RobotWrapper("", placo.Flags.ignore_collisions, urdf)
        names = list(self.wrapper.joint_names())
        if names != robot.joint_names:
            raise ValueError(f"{robot.name}: placo joint order differs from pinocchio's")
        for jn in robot.joint_names:
            rule = robot.config.gain_rule(jn)
            if rule is not None and rule.armature > 0:
                self.wrapper.set_rotor_inertia(jn, rule.armature)

        s = self.solver = placo.DynamicsSolver(self.wrapper)
        s.dt = dt_s
        s.enable_joint_limits(False)
        s.enable_torque_limits(TORQUE_LIMITS)
        self.foot_tasks = []
        self.contacts = []
        for side in SIDES:
            task = s.add_frame_task(f"{side}_foot", np.eye(4))
            task.configure(f"{side}_foot", "hard", 1.0, 1.0)
            contact = s.add_planar_contact(task)
            sole = robot.config.soles[side]
            contact.length = sole.length_m
            contact.width = sole.width_m
            contact.mu = g.friction_mu
            contact.weight_forces = 1e-5
            contact.weight_moments = 1e-4
            self.foot_tasks.append(task)
            self.contacts.append(contact)
        self.com_task = s.add_com_task(np.zeros(3))
        self.com_task.configure("com", "soft", g.com_weight)
        self.com_task.mask.set_axises("xy")
        self.com_task.kp, self.com_task.kd = g.com_kp, g.com_kd
        root = robot.config.root_link
        self.pelvis_height_task = s.add_position_task(root, np.zeros(3))
        self.pelvis_height_task.configure("pelvis_height", "soft", g.pelvis_height_weight)
        self.pelvis_height_task.mask.set_axises("z")
        self.pelvis_height_task.kp, self.pelvis_height_task.kd = g.pelvis_height_kp, g.pelvis_height_kd
        self.pelvis_rot_task = s.add_orientation_task(root, np.eye(3))
        self.pelvis_rot_task.configure("pelvis_rot", "soft", g.pelvis_rot_weight)
        self.pelvis_rot_task.kp, self.pelvis_rot_task.kd = g.pelvis_rot_kp, g.pelvis_rot_kd
        self.joints_task = s.add_joints_task()
        self.joints_task.configure("upper_body", "soft", g.upper_body_weight)
        self.joints_task.kp, self.joints_task.kd = g.upper_body_kp, g.upper_body_kd

        self._servo_kp = g.servo_kp_scale * robot.kp
        self._servo_kd = g.servo_kd_scale * robot.kd
        self.q_des: FloatArray | None = None
        self.qd_des: FloatArray | None = None
        self.last_tau = np.zeros(robot.n_joints)
        self.diagnostics = WbcDiagnostics(status="not_run", backend="placo")

    def reset(self, state: RobotState) -> None:
        self.q_des = np.array(state.q[7:], dtype=float)
        self.qd_des = np.array(state.v[6:], dtype=float)
        self.last_tau = np.zeros(self.robot.n_joints)

    def compute(self, state: RobotState, ref: WbcReference) -> JointCommand:
        """One control tick. Never raises; ``self.diagnostics`` describes the result."""
        t0 = time.perf_counter()
        try:
            return self._compute(state, ref, t0)
        except Exception as exc:  # noqa: BLE001 - a controller must not take the simulation down
            return self._fallback(state, "fallback_exception", f"{type(exc).__name__}: {exc}", t0)

    def _compute(self, state: RobotState, ref: WbcReference, t0: float) -> JointCommand:
        q = np.asarray(state.q, dtype=float)
        v = np.asarray(state.v, dtype=float)
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            return self._fallback(state, "fallback_invalid_state", "state is not finite", t0)
        if self.q_des is None:
            self.reset(state)
        if not ref.is_finite():
            return self._fallback(state, "fallback_invalid_reference", "reference has non-finite values", t0)
        contact = np.asarray(ref.contact, dtype=bool).reshape(len(SIDES), 4)
        if not contact.any():
            return self._fallback(state, "fallback_no_contact", "no active contact", t0)
        g = self.gains
        self.wrapper.state.q = q
        self.wrapper.state.qd = v
        self.wrapper.update_kinematics()
        for i, (task, cont) in enumerate(zip(self.foot_tasks, self.contacts)):
            task.T_world_frame = _pose(ref.foot_rotation[i], ref.foot_pos_m[i])
            pos, ori = task.position(), task.orientation()
            if contact[i].any():
                cont.active = True
                task.configure(f"{SIDES[i]}_foot", "hard", 1.0, 1.0)
                pos.kp, pos.kd, ori.kp, ori.kd = 0.0, g.contact_foot_kd, 0.0, g.contact_foot_kd
                pos.dtarget_world = np.zeros(3)
                ori.omega_world = np.zeros(3)
            else:
                cont.active = False
                task.configure(f"{SIDES[i]}_foot", "soft", g.swing_foot_weight, g.swing_foot_rotation_weight)
                pos.kp, pos.kd, ori.kp, ori.kd = g.swing_foot_kp, g.swing_foot_kd, g.swing_foot_kp, g.swing_foot_kd
                pos.dtarget_world = np.asarray(ref.foot_lin_vel_mps[i], dtype=float)
                ori.omega_world = np.asarray(ref.foot_ang_vel_radps[i], dtype=float)
                if ref.foot_lin_acc_mps2 is not None:
                    pos.ddtarget_world = np.asarray(ref.foot_lin_acc_mps2[i], dtype=float)
        self.com_task.target_world = np.array([ref.com_xy_m[0], ref.com_xy_m[1], 0.0])
        self.com_task.dtarget_world = np.array([ref.com_xy_vel_mps[0], ref.com_xy_vel_mps[1], 0.0])
        self.com_task.ddtarget_world = np.array([ref.com_xy_acc_mps2[0], ref.com_xy_acc_mps2[1], 0.0])
        self.pelvis_height_task.target_world = np.array([0.0, 0.0, ref.pelvis_height_m])
        self.pelvis_height_task.dtarget_world = np.array([0.0, 0.0, ref.pelvis_height_rate_mps])
        self.pelvis_rot_task.R_world_frame = np.asarray(ref.pelvis_rotation, dtype=float)
        self.pelvis_rot_task.omega_world = np.asarray(ref.pelvis_ang_vel_radps, dtype=float)
        self.joints_task.set_joints(dict(zip(self.upper_body_joints, map(float, ref.upper_body_q_rad))))
        self.joints_task.set_joints_velocities(dict(zip(self.upper_body_joints, map(float, ref.upper_body_qd_radps))))
        if ref.external_wrench is not None:
            self.solver.extra_force = self._external_generalized_force(np.asarray(ref.external_wrench, dtype=float))
        else:
            self.solver.extra_force = np.zeros(0)
        t1 = time.perf_counter()
        result = self.solver.solve(False)
        t2 = time.perf_counter()
        if not result.success:
            return self._fallback(state, "fallback_solver", "placo: QP failed", t0)
        tau = np.asarray(result.tau)[6:].copy()
        qdd = np.asarray(result.qdd).copy()
        if not (np.all(np.isfinite(tau)) and np.all(np.isfinite(qdd))):
            return self._fallback(state, "fallback_solver", "placo: non-finite solution", t0)
        assert self.q_des is not None and self.qd_des is not None, "_compute resets the integrators first"
        self.q_des, self.qd_des = integrate_setpoints(self.q_des, self.qd_des, qdd[6:], state, g, self.dt_s)
        self.last_tau = tau
        self.diagnostics = WbcDiagnostics(status="solved", backend="placo", qdd=qdd, tau_nm=tau,
                                          build_s=t1 - t0, qp_s=t2 - t1, total_s=time.perf_counter() - t0)
        return JointCommand(self.q_des.copy(), self.qd_des.copy(), tau.copy(), self._servo_kp, self._servo_kd)

    def _external_generalized_force(self, wrench: FloatArray) -> FloatArray:
        """−J_comᵀ-style generalised force of a wrench at the CoM (placo's ``extra_force`` adds to the bias)."""
        jac_com = self.wrapper.com_jacobian()  # (3, nv)
        gen = -(jac_com.T @ wrench[:3])
        # The torque about the CoM acts on the base rotation (base angular rows, world → base axes).
        rot = self.wrapper.get_T_world_fbase()[:3, :3]
        gen[3:6] -= rot.T @ wrench[3:6]
        return gen

    def _fallback(self, state: RobotState, status: str, message: str, t0: float) -> JointCommand:
        cmd = fallback_hold(self.robot, state, self.q_des, self.last_tau, self.dt_s, self.gains.fallback_decay_s)
        self.q_des, self.qd_des, self.last_tau = cmd.q_des.copy(), cmd.qd_des.copy(), cmd.tau_ff.copy()
        self.diagnostics = WbcDiagnostics(status=status, message=message, backend="placo", tau_nm=self.last_tau.copy(),
                                          total_s=time.perf_counter() - t0)
        return cmd
