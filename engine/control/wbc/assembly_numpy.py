"""The whole-body QP of one tick assembled in numpy by the task objects: the reference the compiled kernels
are tested against (:func:`engine.control.wbc.kernels.build_qp`: the same numbers to rounding,
``tests/control/test_wbc_kernels.py``), and the path of ``TaskSpaceInverseDynamics(kernels="numpy")``.

One :meth:`NumpyQpAssembly.build` per tick: the tasks' targets from the reference, their stacked rows
(Eqs. 18, 20), the normal equations, the contact model (sole corners and friction-pyramid edges, Eq. 17),
the centroidal equality (Eq. 21), the soft joint limits (Eqs. 22–23) and the torque rows of Eq. 15.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from engine.constants import GRAVITY_MPS2, SIDES
from engine.control.wbc.qp import CentroidalQp
from engine.control.wbc.reference import N_BASIS, N_CORNERS, WbcGains, WbcReference
from engine.control.wbc.tasks import ComTask, DynamicsSnapshot, FramePoseTask, JointTask, PelvisTask, Task

FloatArray = NDArray[np.float64]


class NumpyQpAssembly:
    """Writes the controller's task objects' rows into its stacked buffers and builds the QP from them.

    ``tasks`` is the controller's stack in row order (the feet first, then pelvis, CoM, upper body, angular
    momentum); ``jac``, ``rhs``, ``w`` are its stacked rows (J, a* − J̇ q̇, weights), shared with the compiled
    path. The feet's gains, velocities and accelerations are rebound here to rows of (2, 6) arrays, so both
    feet's rows are computed at once. ``corner_offsets_t``: (2, 3, 4) sole corners in the foot frame, from
    the sole centre; ``basis_xy``: the pyramid edges' x and y rows per unit heading (see the controller)."""

    def __init__(self, gains: WbcGains, swing_weights: tuple[float, float], tasks: Sequence[Task],
                 foot_tasks: Sequence[FramePoseTask], pelvis_task: PelvisTask, com_task: ComTask,
                 upper_task: JointTask, jac: FloatArray, rhs: FloatArray, w: FloatArray,
                 corner_offsets_t: FloatArray, basis_xy: FloatArray, mass_kg: float, joint_lower: FloatArray,
                 joint_upper: FloatArray, joint_damping: FloatArray | None, torque_limit: FloatArray):
        self.gains = gains
        self._swing_weights = swing_weights
        self.tasks, self.foot_tasks = list(tasks), list(foot_tasks)
        self.pelvis_task, self.com_task, self.upper_task = pelvis_task, com_task, upper_task
        self._jac, self._rhs, self._w = jac, rhs, w
        self.nv = jac.shape[1]
        n_feet = len(self.foot_tasks)
        self._foot_rows = 6 * n_feet
        self._foot_kp, self._foot_kd = np.zeros((n_feet, 6)), np.zeros((n_feet, 6))
        self._foot_vel, self._foot_acc = np.zeros((n_feet, 6)), np.zeros((n_feet, 6))
        for i, foot in enumerate(self.foot_tasks):
            foot.kp, foot.kd, foot.velocity, foot.acceleration = (
                self._foot_kp[i], self._foot_kd[i], self._foot_vel[i], self._foot_acc[i])
        self._corner_offsets_t = corner_offsets_t
        self._basis_xy = basis_xy
        self._basis_template = np.zeros((len(SIDES), 3, N_BASIS))  # (2, 3, 4); z row constant
        self._basis_template[:, 2, :] = 1.0 / math.sqrt(1.0 + gains.friction_mu**2)
        self.n_rho = len(SIDES) * N_CORNERS * N_BASIS
        self._arms_buf = np.zeros((2 * len(SIDES) * N_CORNERS, 3))
        self._edges_buf = np.zeros((2 * len(SIDES) * N_CORNERS, 3, N_BASIS))
        self._wrench_buf = np.zeros((len(SIDES), 6, N_CORNERS * N_BASIS))
        self._skew = np.zeros((2 * len(SIDES) * N_CORNERS, 3, 3))
        self.mass_kg = mass_kg
        self._joint_lower, self._joint_upper = joint_lower, joint_upper
        self._joint_damping = joint_damping
        self._torque_limit = torque_limit

    def build(self, snap: DynamicsSnapshot, ref: WbcReference, contact: NDArray[np.bool_], rho_up: FloatArray,
              jac_filled: bool) -> tuple[CentroidalQp, FloatArray, FloatArray, FloatArray]:
        """The tick's QP (Eqs. 20–25 with Eq. 15's torque rows), the pyramid edges (2, 3, 4), the sole corners
        (2, 3, 4) and the τ̄ map (nv, 32). ``rho_up``: ρ's upper bounds for ``contact``; ``jac_filled``: the
        constant Jacobian rows are already in ``jac`` (not written again)."""
        g = self.gains
        self.set_targets(ref, contact)
        # ---- tasks: stacked weighted least squares on q̈ (Eq. 20); both feet at once (rows 0..11)
        self.write_rows(snap, jac_filled)
        p_qq, c_q, r_rr, g_rho, tau_map, basis, corners = self.assemble(snap)
        # ---- centroidal equality (21): A_h q̈ − G ρ = −Ȧ_h q̇ + [m g; 0] + w_ext
        b = -snap.centroidal_drift
        b[2] -= self.mass_kg * GRAVITY_MPS2
        if ref.external_wrench is not None:
            b = b + np.asarray(ref.external_wrench, dtype=float)

        # ---- soft joint limits (22, 23) within the acceleration limits; ρ bounds (24, 25)
        qj, vj = snap.q[7:], snap.v[6:]
        amax = g.max_joint_acc_radps2
        lo = np.minimum(np.maximum(g.joint_limit_kl * (self._joint_lower - qj) - g.joint_limit_bl * vj, -amax), amax)
        up = np.maximum(np.minimum(g.joint_limit_kl * (self._joint_upper - qj) - g.joint_limit_bl * vj, amax), lo)
        # ---- actuator torque limits on Eq. 15's joint rows: τ = M_j q̈ + T ρ + h_j
        bias = snap.nonlinear_effects[6:].copy()
        if self._joint_damping is not None:
            bias += self._joint_damping * snap.v[6:]
        qp = CentroidalQp(p_qq, c_q, r_rr, snap.centroidal_map, g_rho, b, lo, up, rho_up,
                          tau_qdd=snap.mass_matrix[6:], tau_rho=tau_map[6:], tau_bias=bias,
                          tau_lo=-self._torque_limit, tau_up=self._torque_limit)
        return qp, basis, corners, tau_map

    def set_targets(self, ref: WbcReference, contact: NDArray[np.bool_]) -> None:
        """The task objects' targets, gains and weights from the reference and the contact corners."""
        g = self.gains
        for i, task in enumerate(self.foot_tasks):
            lin_acc = None if ref.foot_lin_acc_mps2 is None else ref.foot_lin_acc_mps2[i]
            ang_acc = None if ref.foot_ang_acc_radps2 is None else ref.foot_ang_acc_radps2[i]
            task.set_target(ref.foot_pos_m[i], ref.foot_rotation[i], ref.foot_lin_vel_mps[i], ref.foot_ang_vel_radps[i],
                            lin_acc, ang_acc)
            if contact[i].all():  # flat on the ground: hold still (damping only, zero acceleration)
                task.kp[:] = 0.0
                task.kd[:] = g.contact_foot_kd
                task.weight[:] = g.contact_foot_weight
                task.velocity[:] = 0.0
                task.acceleration[:] = 0.0
            else:  # heel/toe contact (firm) or swing: follow the planned pose
                task.kp[:] = g.swing_foot_kp
                task.kd[:] = g.swing_foot_kd
                if contact[i].any():
                    task.weight[:] = g.contact_foot_weight
                else:
                    task.weight[:3], task.weight[3:] = self._swing_weights
        self.pelvis_task.set_target(ref.pelvis_height_m, ref.pelvis_rotation, ref.pelvis_height_rate_mps,
                                    ref.pelvis_ang_vel_radps)
        com = self.com_task  # targets written in place (the task owns its 3-vectors)
        com.position_m[:2] = ref.com_xy_m
        com.position_m[2] = 0.0 if ref.com_z_m is None else ref.com_z_m
        com.velocity_mps[:2] = ref.com_xy_vel_mps
        com.acceleration_mps2[:2] = ref.com_xy_acc_mps2
        com.weight[2] = g.com_z_weight if ref.com_z_m is not None else 0.0
        self.upper_task.set_target(ref.upper_body_q_rad, ref.upper_body_qd_radps)

    def write_rows(self, snap: DynamicsSnapshot, jac_filled: bool) -> None:
        """The tasks' rows (J, a* − J̇ q̇) written by the task objects (targets set by :meth:`set_targets`);
        the constant Jacobian rows only when not ``jac_filled``."""
        nv = self.nv
        jac, rhs, nf = self._jac, self._rhs, self._foot_rows
        jac[:nf] = snap.frame_jacobian.reshape(nf, nv)
        acc = self._foot_acc + self._foot_kd * (self._foot_vel - snap.frame_velocity)
        for i, foot in enumerate(self.foot_tasks):
            if foot.kp.any():  # swing or heel/toe: PD on the pose (a flat contact foot is damped only)
                acc[i] += foot.kp * foot.compute_error(snap)
        np.subtract(acc, snap.frame_drift, out=rhs[:nf].reshape(acc.shape))
        r = nf
        for task in self.tasks[len(self.foot_tasks):]:
            d = task.dim
            task.write_rows(snap, jac[r:r + d] if not task.constant_jacobian or not jac_filled else None,
                            rhs[r:r + d])
            r += d

    def assemble(self, snap: DynamicsSnapshot) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray,
                                                         FloatArray, FloatArray]:
        """The tasks' normal equations and the contact model (the reference of
        :func:`engine.control.wbc.kernels.assemble_qp`): P, c, R, G, the τ̄ map (all nv rows; rows 6: are τ̄),
        the pyramid edges and the sole corners."""
        g = self.gains
        nv = self.nv
        jac, rhs = self._jac, self._rhs
        wj = jac * self._w[:, None]
        p_qq = jac.T @ wj
        p_qq.flat[::nv + 1] += g.lambda_qdd
        c_q = -(wj.T @ rhs)

        # ---- contact model (Eq. 17): corners, friction pyramids (world z normal, foot-yaw tangents)
        rot = snap.frame_rotation  # (2, 3, 3)
        corner_rel = rot @ self._corner_offsets_t  # (2, 3, 4) world, from the sole centre
        corners = snap.frame_position_m[:, :, None] + corner_rel  # (2, 3, 4)
        heading = rot[:, :2, 0]  # foot x axes, horizontal part (2, 2)
        heading = heading / np.maximum(np.sqrt((heading * heading).sum(axis=1)), 1e-9)[:, None]
        basis = self._basis_template.copy()  # (2, 3, 4); z row constant
        basis[:, :2, :] = (heading @ self._basis_xy).transpose(1, 0, 2)  # x and y rows of the pyramid edges
        # Arms to every corner, from the CoM (centroidal moments) and from the sole centre (foot wrench).
        arms = self._arms_buf  # (16, 3): 8 corners from the CoM, then 8 from their sole centre
        arms[:8] = (corners - snap.com_m[None, :, None]).transpose(0, 2, 1).reshape(8, 3)
        arms[8:] = corner_rel.transpose(0, 2, 1).reshape(8, 3)
        edges = self._edges_buf  # (16, 3, 4): each corner's pyramid edges (twice: CoM arms, foot arms)
        edges.reshape(2, len(SIDES), N_CORNERS, 3, N_BASIS)[:] = basis[None, :, None]
        moments = (self._skew_stack(arms) @ edges).transpose(1, 0, 2).reshape(3, 2, -1)  # (3, 2 × 32)
        g_rho = np.empty((6, self.n_rho))
        g_rho[:3] = edges[:8].transpose(1, 0, 2).reshape(3, -1)
        g_rho[3:] = moments[:, 0]
        # τ̄ map: −Σ_feet J_footᵀ [f; m_foot] per unit ρ (all nv rows; rows 6: are τ̄)
        wrench = self._wrench_buf  # (2, 6, 16)
        wrench[:, :3] = g_rho[:3].reshape(3, 2, -1).transpose(1, 0, 2)
        wrench[:, 3:] = moments[:, 1].reshape(3, 2, -1).transpose(1, 0, 2)
        tau_map = -(snap.frame_jacobian.transpose(0, 2, 1) @ wrench).transpose(1, 0, 2).reshape(nv, -1)
        tj = tau_map[6:]
        r_rr = g.lambda_tau * (tj.T @ tj)  # λ_τ̄ ‖τ̄‖²
        r_rr.flat[::self.n_rho + 1] += g.lambda_rho

        return p_qq, c_q, r_rr, g_rho, tau_map, basis, corners

    def _skew_stack(self, arms: FloatArray) -> FloatArray:
        """The cross-product matrices [a]× of the (16, 3) arms, in a (16, 3, 3) buffer."""
        s = self._skew
        s[:, 0, 1] = -arms[:, 2]
        s[:, 0, 2] = arms[:, 1]
        s[:, 1, 0] = arms[:, 2]
        s[:, 1, 2] = -arms[:, 0]
        s[:, 2, 0] = -arms[:, 1]
        s[:, 2, 1] = arms[:, 0]
        return s
