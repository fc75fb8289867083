"""Task-space inverse dynamics whole-body controller (paper Sec. 7.1 and Appendix "ID").

One quadratic program per 500 Hz control tick (Eqs. 20–25)::

    min_{q̈, ρ}  Σ_t ‖√W_t (J_t q̈ + J̇_t q̇ − a*_t)‖² + λ_q̈ ‖q̈‖² + λ_ρ ‖ρ‖² + λ_τ̄ ‖τ̄‖²
    s.t.  A_h q̈ + Ȧ_h q̇ = Σ_c [I; (p_c − c)×] B_c ρ_c + [m g; 0] + w_ext        (21)
          k_l (q_min − q) − b_l q̇ ≤ q̈_j ≤ k_l (q_max − q) − b_l q̇, |q̈_j| ≤ q̈_max (22, 23)
          0 ≤ ρ ≤ ρ_max on active sole corners, ρ = 0 on inactive ones            (24, 25)

with ``τ̄ = −Σ_c J_c,jᵀ f_c`` (actuated rows) and ``f_c = B_c ρ_c`` (Eq. 17): four unit
basis vectors per sole corner spanning a pyramid inscribed in the friction cone of
coefficient ``μ``. Tasks (:mod:`engine.control.wbc.tasks`): both feet (6-D pose; damping only
when flat on the ground), pelvis height and orientation, horizontal CoM (PD on the CoM MPC's
reference plus its acceleration), upper-body joints, angular-momentum damping.

Solvers for the same QP, selected by ``qp_backend``. The default is :class:`ActiveSetQpSolver`
(``"active_set"``): DAQP's dual active-set steps and tolerances, compiled, on the QP's block structure
(:mod:`engine.control.wbc.active_set`; the same active set as DAQP, and closer to the exact optimum);
it falls back to DAQP (:class:`DaqpQpSolver`, ``"daqp"``, a dense dual active set in C on preallocated
arrays), then OSQP. :class:`DenseQpSolver` is the hand-written exact alternative
(``"dense"``): q̈ is eliminated in closed form, leaving a ≤32-variable box QP in ρ solved by a
warm-started primal active set. :class:`OsqpQpSolver` keeps a fixed sparsity pattern and only
updates values each tick (``Px, Ax, q, l, u``, warm start); it is the fallback of both and the
``"osqp"`` option. ``"proxsuite"`` and ``"quadprog"`` go through
:mod:`engine.control.qp_backends` (measured slower). The floating-base
acceleration is then made exactly consistent with the rigid-body dynamics (6×6 solve of
the base rows of Eq. 15), torques follow from Eq. 15 (plus the model's viscous joint
damping), and joint position/velocity set-points come from integrating q̈, clipped to a
maximum error from the measured state (paper Sec. 7.1). A failed solve (non-finite input,
no active contact, solver failure, NaN) never raises: the command falls back to a stiff PD
hold with the last good torques decaying, and the diagnostics say why.

This module composes the tick; its parts live in their own modules: the compiled build, solve and finish
(:mod:`engine.control.wbc.kernels`), the numpy assembly they replace (:mod:`engine.control.wbc.assembly_numpy`),
the solvers' order and fallbacks (:mod:`engine.control.wbc.solver_chain`), Eq. 15's torques in numpy
(:mod:`engine.control.wbc.torques`), the set-points and the fallback hold (:mod:`engine.control.wbc.setpoints`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from engine.control.controller import JointCommand, RobotState
from engine.constants import CONTROL_PERIOD_S, GRAVITY_MPS2, SIDES
from engine.control import qp_backends
from engine.control.wbc.assembly_numpy import NumpyQpAssembly
from engine.control.wbc.tasks import (
    AngularMomentumTask,
    ComTask,
    DynamicsSnapshot,
    FramePoseTask,
    JointTask,
    PelvisTask,
)
from engine.robot.model import RobotModel
from engine.control.wbc.priority import LexicographicSolve
from engine.control.wbc.qp import ActiveSetQpSolver, CentroidalQp, DaqpQpSolver, DenseQpSolver, OsqpQpSolver
from engine.control.wbc.reference import N_BASIS, N_CORNERS, WbcDiagnostics, WbcGains, WbcReference
from engine.control.wbc.setpoints import fallback_hold, integrate_setpoints
from engine.control.wbc.snapshot import SnapshotReader
from engine.control.wbc.solver_chain import QpSolverChain, SolveResult, solve_status
from engine.control.wbc.torques import joint_torques, joint_torques_lu
from engine.control.wbc import kernels as _kernels

#: How the QP is assembled: compiled (numba, the default) or the numpy reference it replaces.
KERNELS = ("numba", "numpy")

FloatArray = NDArray[np.float64]
_FLOAT64 = np.dtype(np.float64)  # the dtype object of float64 arrays (snapshot() compares identity)
_BOOL = np.dtype(np.bool_)
_CONTACT_SHAPE = (len(SIDES), N_CORNERS)


# ----------------------------------------------------------------------------- the controller


class TaskSpaceInverseDynamics:
    """The paper's whole-body QP (Eqs. 15–25) for a biped with two rectangular soles.

    ``qp_backend``: ``"active_set"`` (default: the compiled dual active set, DAQP then OSQP when it fails),
    ``"daqp"``, ``"dense"`` (the
    hand-written exact active set), ``"osqp"`` (fixed sparsity pattern, warm started; the others'
    fallback) or ``"proxsuite"`` / ``"quadprog"`` (:mod:`engine.control.qp_backends`).

    ``kernels``: ``"numba"`` (default) computes the task rows, the QP's assembly, DAQP's form and the
    torques in the compiled kernels of :mod:`engine.control.wbc.kernels`; ``"numpy"`` keeps the
    task objects and numpy code they replace (the tests' reference: the same numbers to rounding).
    """

    name = "task-space-id"

    def __init__(self, robot: RobotModel, gains: WbcGains | None = None,
                 upper_body_joints: Sequence[str] | None = None, dt_s: float = CONTROL_PERIOD_S,
                 qp_backend: str = "active_set", kernels: str = "numba"):
        if set(robot.config.soles) != set(SIDES):
            raise ValueError(f"{robot.name}: the inverse dynamics needs left and right soles")
        choices = ("active_set", "dense", "osqp", *(b for b in qp_backends.BACKENDS if b != "osqp"))
        if qp_backend not in choices:
            raise ValueError(f"qp_backend: expected one of {', '.join(choices)}, got {qp_backend!r}")
        if kernels not in KERNELS:
            raise ValueError(f"kernels: expected one of {', '.join(KERNELS)}, got {kernels!r}")
        self.robot = robot
        self.kernels = kernels
        self.gains = gains or WbcGains.for_robot(robot)
        self.dt_s = dt_s
        self.qp_backend = qp_backend
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.nv = self.model.nv
        # (nq,) and (nv,): the state's shapes, compared each tick (pinocchio's model.nq is a binding's property)
        self._q_shape, self._v_shape = (self.model.nq,), (self.nv,)
        self.n_joints = robot.n_joints
        self.n_rho = len(SIDES) * N_CORNERS * N_BASIS
        self.mass_kg = robot.mass_kg
        self.foot_frame_ids = [self.model.getFrameId(f"{s}_foot") for s in SIDES]
        self._snapshot = SnapshotReader(self.model, self.data, self.foot_frame_ids)  # the compiled tick's
        # see snapshot(): (q, v, q.sum() + v.sum() when prepared, the pass)
        self._prepared: tuple[FloatArray, FloatArray, float, DynamicsSnapshot] | None = None
        self._state_total = math.nan  # _compute's q.sum() + v.sum() of the tick being computed
        # Corner offsets in the foot frame (sole centre, sole plane): (2, 4, 3).
        self.corner_offsets_m = np.array([[np.subtract(c, robot.config.soles[s].center)
                                           for c in robot.config.soles[s].corners()] for s in SIDES])
        names = list(robot.config.upper_body_joints if upper_body_joints is None else upper_body_joints)
        self.upper_body_joints = names
        self.upper_v_indices = np.array([6 + robot.joint_names.index(j) for j in names], dtype=np.int64)

        g = self.gains
        s2 = g.priority_level2_scale  # the style's tasks' weights (engine/control/wbc/priority.py)
        self._swing_weights = (g.swing_foot_weight, s2 * g.swing_foot_rotation_weight)
        self.foot_tasks = [FramePoseTask(i) for i in range(len(SIDES))]
        self.pelvis_task = PelvisTask(kp=[g.pelvis_height_kp] + [g.pelvis_rot_kp] * 3,
                                      kd=[g.pelvis_height_kd] + [g.pelvis_rot_kd] * 3,
                                      weight=[g.pelvis_height_weight] + [s2 * g.pelvis_rot_weight] * 3)
        self.com_task = ComTask(kp=g.com_kp, kd=g.com_kd, weight=[g.com_weight, g.com_weight, g.com_z_weight])
        self.upper_task = JointTask(self.upper_v_indices, self.nv, g.upper_body_kp, g.upper_body_kd,
                                    s2 * g.upper_body_weight)
        self.angular_momentum_task = AngularMomentumTask(kd=g.angular_momentum_kd, weight=s2 * g.angular_momentum_weight)
        self.tasks = [*self.foot_tasks, self.pelvis_task, self.com_task, self.upper_task, self.angular_momentum_task]
        self.n_rows = sum(t.dim for t in self.tasks)
        self._jac = np.zeros((self.n_rows, self.nv))
        self._jac_filled = False
        self._rhs = np.zeros(self.n_rows)
        self._w = np.zeros(self.n_rows)
        # Every task's weights are views of the stacked ``_w`` (the numpy path writes them through the tasks).
        n_feet = len(SIDES)
        r = 0
        for task in self.tasks:
            self._w[r:r + task.dim] = task.weight
            task.weight = self._w[r:r + task.dim]
            r += task.dim
        # The compiled rows' gains (kernels.task_rows) and zero feed-forward.
        self._task_gains = np.array([g.swing_foot_kp, g.swing_foot_kd, self._swing_weights[0], g.contact_foot_kd,
                                     g.contact_foot_weight, g.pelvis_height_kp, g.pelvis_height_kd, g.pelvis_rot_kp,
                                     g.pelvis_rot_kd, g.com_kp, g.com_kd, g.com_z_weight, g.upper_body_kp,
                                     g.upper_body_kd, g.angular_momentum_kd, self._swing_weights[1]], dtype=float)
        self._zeros_2x3 = np.zeros((n_feet, 3))
        self._corner_offsets_t = self.corner_offsets_m.transpose(0, 2, 1).copy()
        mu_n = g.friction_mu / math.sqrt(1.0 + g.friction_mu**2)
        # Pyramid edges (n ± μ t1, n ± μ t2)/√(1+μ²), t1 = heading, t2 = z × heading (see friction_basis):
        # their x and y rows are linear in the heading (hx, hy).
        self._basis_xy = mu_n * np.array([[[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 1.0]],
                                          [[0.0, 0.0, 1.0, -1.0], [1.0, -1.0, 0.0, 0.0]]])  # (x|y row, hx|hy, 4)
        self._rho_up_cache: tuple[bytes, FloatArray] = (b"", np.zeros(self.n_rho))
        self._rho_idx_cache: tuple[FloatArray | None, NDArray[np.int64]] = (None, np.zeros(0, dtype=np.int64))

        damping = np.asarray(self.model.damping[6:], dtype=float).copy()
        self._joint_damping = damping if np.any(damping > 0.0) else None
        self._no_damping = np.zeros(self.n_joints)
        self._joint_lower = robot.joint_lower.copy()
        self._joint_upper = robot.joint_upper.copy()
        effort = np.asarray(robot.effort_limits, dtype=float)
        self._torque_limit = np.where(effort > 0.0, g.torque_limit_fraction * effort, 1e6)
        self._neg_torque_limit = -self._torque_limit
        self._zeros_6 = np.zeros(6)
        # kernels.build_qp's scalar parameters (λ_q̈, pyramid z, λ_τ̄, λ_ρ, m g, k_l, b_l, q̈_max)
        self._build_params = np.array([g.lambda_qdd, 1.0 / math.sqrt(1.0 + g.friction_mu**2), g.lambda_tau,
                                       g.lambda_rho, self.mass_kg * GRAVITY_MPS2, g.joint_limit_kl,
                                       g.joint_limit_bl, g.max_joint_acc_radps2], dtype=float)
        self._servo_kp = g.servo_kp_scale * robot.kp
        self._servo_kd = g.servo_kd_scale * robot.kd
        self.dense_solver = DenseQpSolver(self.nv, self.n_rho)
        self.osqp_solver = OsqpQpSolver(self.nv, self.n_rho)
        self.daqp_solver = DaqpQpSolver(self.nv, self.n_rho, self.n_joints, compiled=kernels == "numba")
        self.active_set_solver = ActiveSetQpSolver(self.nv, self.n_rho, self.n_joints)
        # Balance before style: two solves per tick when the slack is finite (engine/control/wbc/priority.py).
        self.priority = (LexicographicSolve(self.nv, self.n_rho, self.n_joints, self.n_rows, g.priority_slack_mps2)
                         if math.isfinite(g.priority_slack_mps2) else None)
        self._solvers = QpSolverChain(qp_backend, self.active_set_solver, self.daqp_solver, self.dense_solver,
                                      self.osqp_solver, self.priority)
        # kernels="numpy": the task objects' path (engine/control/wbc/assembly_numpy.py)
        self._numpy = NumpyQpAssembly(g, self._swing_weights, self.tasks, self.foot_tasks, self.pelvis_task,
                                      self.com_task, self.upper_task, self._jac, self._rhs, self._w,
                                      self._corner_offsets_t, self._basis_xy, self.mass_kg, self._joint_lower,
                                      self._joint_upper, self._joint_damping, self._torque_limit)
        # build, solve and finish in one compiled call with the default solver and no task priority (False: the
        # step-by-step calls it replaces, the tests' reference: the same numbers)
        self.one_call = True
        self.q_des: FloatArray | None = None
        self.qd_des: FloatArray | None = None
        self.last_tau = np.zeros(self.n_joints)
        self.diagnostics = WbcDiagnostics(status="not_run")
        self.qp: CentroidalQp | None = None

    # ------------------------------------------------------------------ public API
    def reset(self, state: RobotState) -> None:
        """Start the set-point integrators at the measured joint state."""
        self.q_des = np.array(state.q[7:], dtype=float)
        self.qd_des = np.array(state.v[6:], dtype=float)
        self.last_tau = np.zeros(self.n_joints)

    def snapshot(self, q: FloatArray, v: FloatArray) -> DynamicsSnapshot | None:
        """The dynamics pass of the tick about to be computed for ``(q, v)``, computed now: a caller that needs this
        state's CoM or momentum (the walking controller) reads it here, and the next :meth:`compute` with the same
        ``q`` and ``v`` arrays (unchanged in between) reuses it instead of a second pass. Its arrays are views of
        this controller's buffers, valid until that tick. None where the compiled tick does not run (numpy kernels,
        a model with mimic joints) or the state is not a finite ``(q, v)`` (the tick then falls back as before)."""
        self._prepared = None
        if self.kernels != "numba" or not self._snapshot.exact:
            return None
        # (float64 arrays: numpy's dtype singleton, what every float array the simulation hands out has; any other
        # dtype object, equal or not, returns None and compute() makes its own pass: the same numbers)
        if q.shape != self._q_shape or v.shape != self._v_shape or q.dtype is not _FLOAT64 or v.dtype is not _FLOAT64:
            return None
        total = self._state_sum(q, v)
        if not math.isfinite(total):
            return None
        try:  # (compute() never raises: a failed pass here leaves the tick to compute its own, and fall back there)
            snap = self._snapshot.compute(q, v)
        except Exception:  # noqa: BLE001
            return None
        self._prepared = (q, v, total, snap)
        return snap

    def hold_reference(self, q: FloatArray) -> WbcReference:
        """A standing reference that holds configuration ``q``: both feet flat and in contact."""
        self._prepared = None  # (the pass below overwrites the buffers a prepared snapshot views)
        snap = DynamicsSnapshot.compute(self.model, self.data, q, np.zeros(self.nv), self.foot_frame_ids)
        return WbcReference(
            com_xy_m=snap.com_m[:2].copy(), com_xy_vel_mps=np.zeros(2), com_xy_acc_mps2=np.zeros(2),
            pelvis_height_m=float(q[2]), pelvis_height_rate_mps=0.0, pelvis_rotation=snap.base_rotation.copy(),
            pelvis_ang_vel_radps=np.zeros(3), foot_pos_m=snap.frame_position_m.copy(),
            foot_rotation=snap.frame_rotation.copy(), foot_lin_vel_mps=np.zeros((2, 3)),
            foot_ang_vel_radps=np.zeros((2, 3)), contact=np.ones((2, N_CORNERS), dtype=bool),
            upper_body_q_rad=q[1 + self.upper_v_indices].copy(), upper_body_qd_radps=np.zeros(self.upper_v_indices.size),
            com_z_m=float(snap.com_m[2]),
        )

    def compute(self, state: RobotState, ref: WbcReference) -> JointCommand:
        """One control tick. Never raises; ``self.diagnostics`` describes the result."""
        t0 = time.perf_counter()
        try:
            return self._compute(state, ref, t0)
        except Exception as exc:  # noqa: BLE001 - a controller must not take the simulation down
            return self._fallback(state, "fallback_exception", f"{type(exc).__name__}: {exc}", t0)

    # ------------------------------------------------------------------ one tick
    def _state_sum(self, q: FloatArray, v: FloatArray) -> float:
        """``q.sum() + v.sum()`` (finite for a finite state), compiled with the compiled kernels (numpy's
        summation, the same number: :func:`engine.control.wbc.kernels.state_sum`)."""
        if self.kernels == "numba":
            return float(_kernels.state_sum(q, v))
        return float(q.sum() + v.sum())

    def _compute(self, state: RobotState, ref: WbcReference, t0: float) -> JointCommand:
        q, v = state.q, state.v
        if type(q) is not np.ndarray or q.dtype is not _FLOAT64:  # (np.asarray returns a float64 ndarray itself)
            q = np.asarray(q, dtype=float)
        if type(v) is not np.ndarray or v.dtype is not _FLOAT64:
            v = np.asarray(v, dtype=float)
        self._state_total = self._state_sum(q, v) if q.shape == self._q_shape and v.shape == self._v_shape else math.nan
        if not math.isfinite(self._state_total):
            return self._fallback(state, "fallback_invalid_state", "state is not a finite (q, v)", t0)
        if self.q_des is None:
            self.reset(state)
        if self.kernels == "numba":
            return self._compute_compiled(state, q, v, ref, t0)
        if not ref.is_finite():
            return self._fallback(state, "fallback_invalid_reference", "reference has non-finite values", t0)
        contact = np.asarray(ref.contact, dtype=bool).reshape(len(SIDES), N_CORNERS)
        if not contact.any():
            return self._fallback(state, "fallback_no_contact", "no active contact corner: nothing to stand on", t0)

        snap = DynamicsSnapshot.compute(self.model, self.data, q, v, self.foot_frame_ids)
        t1 = time.perf_counter()
        qp, self._basis, self._corners_m, self._tau_map = self._numpy.build(
            snap, ref, contact, self._rho_upper(contact), self._jac_filled)
        self._jac_filled = True
        self.qp = qp
        t2 = time.perf_counter()
        solution, backend, iterations, message = self._solve_prioritized(qp, contact, ref)
        t3 = time.perf_counter()
        if solution is None:
            return self._fallback(state, "fallback_solver", message or "qp failed", t0, iterations)
        qdd, rho = solution
        tau = joint_torques(snap, self._tau_map, qdd, rho, self._joint_damping)
        if not math.isfinite(tau.sum()):
            return self._fallback(state, "fallback_solver", "non-finite torques", t0, iterations)
        cmd = self._setpoints(state, qdd, tau)
        self.last_tau = tau
        self.diagnostics = WbcDiagnostics(
            status=solve_status(backend, message), message=message, backend=backend, qdd=qdd, rho=rho, tau_nm=tau,
            qp_iterations=iterations, pinocchio_s=t1 - t0, build_s=t2 - t1, qp_s=t3 - t2,
            total_s=time.perf_counter() - t0, basis=self._basis, corners_m=self._corners_m, qp=qp)
        return cmd

    def _solve_prioritized(self, qp: CentroidalQp, contact: NDArray[np.bool_], ref: WbcReference) -> SolveResult:
        """The QP by the solver chain (:mod:`engine.control.wbc.solver_chain`), with the task priority's two
        solves when there is one (the stacked rows of this tick, the CoM height in level 1 when tracked)."""
        return self._solvers.solve_prioritized(qp, self._jac, self._rhs, self._w, contact,
                                               ref.com_z_m is not None and self.gains.com_z_weight > 0.0)

    def _compute_compiled(self, state: RobotState, q: FloatArray, v: FloatArray, ref: WbcReference,
                          t0: float) -> JointCommand:
        """:meth:`_compute` with the compiled kernels: the reference's finiteness, the task rows, the QP's
        assembly and bounds in one call (:func:`engine.control.wbc.kernels.build_qp`), the torques and
        set-points in another (:func:`engine.control.wbc.kernels.finish_tick`): the same numbers. With the
        default solver and no task priority, build, solve and finish are one call (:meth:`_compute_one_call`)."""
        contact = ref.contact  # (2, 4) bool (read only), as np.asarray(…, dtype=bool).reshape(2, 4) makes it
        if type(contact) is not np.ndarray or contact.dtype is not _BOOL or contact.shape != _CONTACT_SHAPE:
            contact = np.asarray(contact, dtype=bool).reshape(len(SIDES), N_CORNERS)
        prepared, self._prepared = self._prepared, None
        if prepared is not None and prepared[0] is q and prepared[1] is v and prepared[2] == self._state_total:
            snap = prepared[3]  # computed by snapshot() for this state (the same arrays, unchanged: the same pass)
        else:
            snap = self._snapshot.compute(q, v)
        t1 = time.perf_counter()
        if self.one_call and self.priority is None and self.qp_backend == "active_set":
            return self._compute_one_call(state, snap, ref, contact, t0, t1)
        qp = self._build_qp_compiled(snap, ref, contact)
        if qp is None:
            return self._fallback(state, "fallback_invalid_reference", "reference has non-finite values", t0)
        if not contact.any():
            return self._fallback(state, "fallback_no_contact", "no active contact corner: nothing to stand on", t0)
        self.qp = qp
        t2 = time.perf_counter()
        solution, backend, iterations, message = self._solve_prioritized(qp, contact, ref)
        t3 = time.perf_counter()
        return self._finish_compiled(state, snap, qp, solution, backend, iterations, message, (t0, t1, t2, t3))

    def _finish_compiled(self, state: RobotState, snap: DynamicsSnapshot, qp: CentroidalQp,
                         solution: tuple[FloatArray, FloatArray] | None, backend: str, iterations: int, message: str,
                         times: tuple[float, float, float, float]) -> JointCommand:
        """Torques and set-points of a solved QP (:func:`engine.control.wbc.kernels.finish_tick`), the diagnostics."""
        t0, t1, t2, t3 = times
        if solution is None:
            return self._fallback(state, "fallback_solver", message or "qp failed", t0, iterations)
        qdd, rho = solution
        g = self.gains
        damping = self._joint_damping
        assert self.q_des is not None and self.qd_des is not None, "_compute resets the integrators first"
        tau, rhs, gen, q_des, qd_des, force = _kernels.finish_tick(
            snap.mass_matrix, snap.nonlinear_effects, self._tau_map, rho, qdd,
            self._no_damping if damping is None else damping, damping is not None, snap.v, snap.q, self.q_des,
            self.qd_des, float(self.dt_s), float(g.max_position_error_rad), float(g.max_velocity_error_radps),
            self._basis)
        if not tau.size:  # the base block is not positive definite: LU (engine/control/wbc/torques.py)
            tau = joint_torques_lu(snap, qdd, rhs, gen, damping)
            if not math.isfinite(tau.sum()):
                return self._fallback(state, "fallback_solver", "non-finite torques", t0, iterations)
            cmd = self._setpoints(state, qdd, tau)
        else:
            if not math.isfinite(tau.sum()):
                return self._fallback(state, "fallback_solver", "non-finite torques", t0, iterations)
            self.q_des, self.qd_des = q_des, qd_des
            cmd = JointCommand(q_des.copy(), qd_des.copy(), tau.copy(), self._servo_kp, self._servo_kd)
        self.last_tau = tau
        self.diagnostics = WbcDiagnostics(
            status=solve_status(backend, message), message=message, backend=backend, qdd=qdd, rho=rho, tau_nm=tau,
            qp_iterations=iterations, pinocchio_s=t1 - t0, build_s=t2 - t1, qp_s=t3 - t2,
            total_s=time.perf_counter() - t0, basis=self._basis, corners_m=self._corners_m, qp=qp,
            horizontal_force_n=force)
        return cmd

    def _build_args(self, snap: DynamicsSnapshot, ref: WbcReference, contact: NDArray[np.bool_]) -> tuple:
        """The arguments both compiled builds start with (:func:`engine.control.wbc.kernels.build_qp` and
        :func:`engine.control.wbc.kernels.solve_tick`): the task buffers, the snapshot, the reference and the
        robot's constants, in the kernels' order."""
        zeros = self._zeros_2x3
        ext, com_z, damping = ref.external_wrench, ref.com_z_m, self._joint_damping
        return (
            self._jac, self._rhs, self._w, self._task_gains, not self._jac_filled, snap.frame_position_m,
            snap.frame_rotation, snap.frame_jacobian, snap.frame_velocity, snap.frame_drift, contact,
            ref.foot_pos_m, ref.foot_rotation, ref.foot_lin_vel_mps, ref.foot_ang_vel_radps,
            zeros if ref.foot_lin_acc_mps2 is None else ref.foot_lin_acc_mps2,
            zeros if ref.foot_ang_acc_radps2 is None else ref.foot_ang_acc_radps2, snap.base_rotation, snap.q, snap.v,
            float(ref.pelvis_height_m), float(ref.pelvis_height_rate_mps), ref.pelvis_rotation, ref.pelvis_ang_vel_radps,
            snap.centroidal_map, snap.centroidal_drift, snap.momentum, snap.com_m, float(snap.mass_kg), ref.com_xy_m,
            ref.com_xy_vel_mps, ref.com_xy_acc_mps2, math.nan if com_z is None else float(com_z), com_z is not None,
            self.upper_v_indices, ref.upper_body_q_rad, ref.upper_body_qd_radps,
            self._zeros_6 if ext is None else np.asarray(ext, dtype=float), ext is not None, self._build_params,
            self._corner_offsets_t, self._basis_xy, self._joint_lower, self._joint_upper, snap.nonlinear_effects,
            self._no_damping if damping is None else damping, damping is not None,
        )

    def _compute_one_call(self, state: RobotState, snap: DynamicsSnapshot, ref: WbcReference,
                          contact: NDArray[np.bool_], t0: float, t1: float) -> JointCommand:
        """Build, solve (the compiled active set) and finish in one compiled call
        (:func:`engine.control.wbc.kernels.solve_tick`: the kernels of the step-by-step path in their order, so
        the same numbers); when the active set gives no solution, the QP it built goes on to DAQP, then OSQP,
        as in :meth:`QpSolverChain.solve`. ``build_s`` is the one call's time (``qp_s`` 0, unless DAQP or OSQP ran)."""
        nv, n_rho = self.nv, self.n_rho
        p_qq, c_q, r_rr = np.empty((nv, nv)), np.empty(nv), np.empty((n_rho, n_rho))
        g_rho, tau_map = np.empty((6, n_rho)), np.empty((nv, n_rho))
        corners, basis = np.empty((len(SIDES), 3, N_CORNERS)), np.empty((len(SIDES), 3, N_BASIS))
        rho_up = self._rho_upper(contact)
        if self._rho_idx_cache[0] is not rho_up:  # the ρ in the QP (ActiveSetQpSolver.workspace), per bounds array
            self._rho_idx_cache = (rho_up, np.flatnonzero(rho_up > 0.0).astype(np.int64))
        rho_idx = self._rho_idx_cache[1]
        solver = self.active_set_solver
        index, upper, count = solver.warm_set(rho_idx.size)
        x, qdd, rho = np.empty(nv + rho_idx.size), np.empty(nv), np.empty(n_rho)
        nj = self.n_joints
        b, lo, up, bias, tau, q_des, qd_des = (np.empty(6), np.empty(nj), np.empty(nj), np.empty(nj), np.empty(nj),
                                               np.empty(nj), np.empty(nj))
        force = np.empty(2)
        g = self.gains
        assert self.q_des is not None and self.qd_des is not None, "_compute resets the integrators first"
        tick, outcome, iterations, n_out = _kernels.solve_tick(*(
            *self._build_args(snap, ref, contact),
            p_qq, c_q, r_rr, g_rho, tau_map, corners, basis, snap.mass_matrix, rho_up, self._neg_torque_limit,
            self._torque_limit, rho_idx, index, upper, count[0], solver.max_iter, x, qdd, rho, self.q_des, self.qd_des,
            float(self.dt_s), float(g.max_position_error_rad), float(g.max_velocity_error_radps), b, lo, up, bias, tau,
            q_des, qd_des, force))
        t2 = time.perf_counter()
        if tick == _kernels.TICK_INVALID_REFERENCE:
            return self._fallback(state, "fallback_invalid_reference", "reference has non-finite values", t0)
        self._jac_filled = True
        self._basis, self._corners_m, self._tau_map = basis, corners, tau_map
        if tick == _kernels.TICK_NO_CONTACT:
            return self._fallback(state, "fallback_no_contact", "no active contact corner: nothing to stand on", t0)
        # (positional arguments: CentroidalQp's field order; a call with keywords costs more at 500 Hz)
        qp = CentroidalQp(p_qq, c_q, r_rr, snap.centroidal_map, g_rho, b, lo, up, rho_up, snap.mass_matrix[6:],
                          tau_map[6:], bias, self._neg_torque_limit, self._torque_limit)
        self.qp = qp
        solved = solver.record(outcome, iterations, n_out, count)
        if tick in (_kernels.TICK_NOT_SOLVED, _kernels.TICK_BASE_NOT_PD):  # DAQP, then OSQP (the solver chain); or
            # the base block's LU (_finish_compiled)
            solution: tuple[FloatArray, FloatArray] | None = (qdd, rho)
            backend, message = "active_set", solver.status
            if not solved:
                solution, backend, iterations, message = self._solvers.after_active_set(qp, iterations)
            return self._finish_compiled(state, snap, qp, solution, backend, iterations, message,
                                         (t0, t1, t2, time.perf_counter()))
        if tick == _kernels.TICK_NONFINITE_TORQUES:
            return self._fallback(state, "fallback_solver", "non-finite torques", t0, iterations)
        self.q_des, self.qd_des = q_des, qd_des
        cmd = JointCommand(q_des.copy(), qd_des.copy(), tau.copy(), self._servo_kp, self._servo_kd)
        self.last_tau = tau
        self.diagnostics = WbcDiagnostics(  # (status, message, backend, qdd, rho, tau_nm, qp_iterations, pinocchio_s,
            # build_s, qp_s, total_s, basis, corners_m, qp, horizontal_force_n: positional, as above)
            "solved", solver.status, "active_set", qdd, rho, tau, iterations, t1 - t0, t2 - t1, 0.0,
            time.perf_counter() - t0, basis, corners, qp, force)
        return cmd

    def _build_qp_compiled(self, snap: DynamicsSnapshot, ref: WbcReference,
                           contact: NDArray[np.bool_]) -> CentroidalQp | None:
        """The QP of :meth:`NumpyQpAssembly.build` in one compiled call (:func:`engine.control.wbc.kernels.build_qp`);
        None when the reference has a non-finite number (nothing is written then)."""
        nv, n_rho = self.nv, self.n_rho
        p_qq, c_q, r_rr = np.empty((nv, nv)), np.empty(nv), np.empty((n_rho, n_rho))
        g_rho, tau_map = np.empty((6, n_rho)), np.empty((nv, n_rho))
        corners, basis = np.empty((len(SIDES), 3, N_CORNERS)), np.empty((len(SIDES), 3, N_BASIS))
        finite, b, lo, up, bias = _kernels.build_qp(
            *(*self._build_args(snap, ref, contact), p_qq, c_q, r_rr, g_rho, tau_map, corners, basis))
        if not finite:
            return None
        self._jac_filled = True
        self._basis, self._corners_m, self._tau_map = basis, corners, tau_map
        return CentroidalQp(p_qq, c_q, r_rr, snap.centroidal_map, g_rho, b, lo, up, self._rho_upper(contact),
                            tau_qdd=snap.mass_matrix[6:], tau_rho=tau_map[6:], tau_bias=bias,
                            tau_lo=self._neg_torque_limit, tau_up=self._torque_limit)

    def _rho_upper(self, contact: NDArray[np.bool_]) -> FloatArray:
        """ρ's upper bounds (Eqs. 24, 25): ``max_corner_force_weights`` m g on the active corners' edges, 0 on the
        others; one array per contact pattern, kept until the pattern changes."""
        key = contact.tobytes()
        if key != self._rho_up_cache[0]:
            rho_max = self.gains.max_corner_force_weights * self.mass_kg * GRAVITY_MPS2
            self._rho_up_cache = (key, np.repeat(np.where(contact.ravel(), rho_max, 0.0), N_BASIS))
        return self._rho_up_cache[1]

    def _setpoints(self, state: RobotState, qdd: FloatArray, tau: FloatArray) -> JointCommand:
        assert self.q_des is not None and self.qd_des is not None, "_compute resets the integrators first"
        self.q_des, self.qd_des = integrate_setpoints(self.q_des, self.qd_des, qdd[6:], state, self.gains, self.dt_s)
        return JointCommand(self.q_des.copy(), self.qd_des.copy(), tau.copy(), self._servo_kp, self._servo_kd)

    def _fallback(self, state: RobotState, status: str, message: str, t0: float, iterations: int = 0) -> JointCommand:
        cmd = fallback_hold(self.robot, state, self.q_des, self.last_tau, self.dt_s, self.gains.fallback_decay_s)
        self.q_des, self.qd_des, self.last_tau = cmd.q_des.copy(), cmd.qd_des.copy(), cmd.tau_ff.copy()
        self.diagnostics = WbcDiagnostics(status=status, message=message, tau_nm=self.last_tau.copy(),
                                          qp_iterations=iterations, total_s=time.perf_counter() - t0)
        return cmd
