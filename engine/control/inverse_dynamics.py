"""Task-space inverse dynamics whole-body controller (paper Sec. 7.1 and Appendix "ID").

One quadratic program per 500 Hz control tick (Eqs. 20–25)::

    min_{q̈, ρ}  Σ_t ‖√W_t (J_t q̈ + J̇_t q̇ − a*_t)‖² + λ_q̈ ‖q̈‖² + λ_ρ ‖ρ‖² + λ_τ̄ ‖τ̄‖²
    s.t.  A_h q̈ + Ȧ_h q̇ = Σ_c [I; (p_c − c)×] B_c ρ_c + [m g; 0] + w_ext        (21)
          k_l (q_min − q) − b_l q̇ ≤ q̈_j ≤ k_l (q_max − q) − b_l q̇, |q̈_j| ≤ q̈_max (22, 23)
          0 ≤ ρ ≤ ρ_max on active sole corners, ρ = 0 on inactive ones            (24, 25)

with ``τ̄ = −Σ_c J_c,jᵀ f_c`` (actuated rows) and ``f_c = B_c ρ_c`` (Eq. 17): four unit
basis vectors per sole corner spanning a pyramid inscribed in the friction cone of
coefficient ``μ``. Tasks (:mod:`engine.control.tasks`): both feet (6-D pose; damping only
when flat on the ground), pelvis height and orientation, horizontal CoM (PD on the CoM MPC's
reference plus its acceleration), upper-body joints, angular-momentum damping.

Solvers for the same QP, selected by ``qp_backend``. The default is DAQP (:class:`DaqpQpSolver`,
a dense dual active set in C on preallocated arrays: fastest and equal to rounding in
``studio bench qp``). :class:`DenseQpSolver` is the hand-written exact alternative
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
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.linalg.lapack import dposv as _dposv

from engine.control.controller import JointCommand, RobotState
from engine.control import qp_backends
from engine.control.qp_backends import QpProblem
from engine.control.tasks import (
    AngularMomentumTask,
    ComTask,
    DynamicsSnapshot,
    FramePoseTask,
    JointTask,
    PelvisTask,
)
from engine.robot.model import RobotModel

FloatArray = NDArray[np.float64]
GRAVITY_MPS2 = 9.81
CONTROL_PERIOD_S = 0.002
SIDES = ("left", "right")
N_CORNERS = 4  # per sole
N_BASIS = 4  # friction-pyramid edges per corner

__all__ = [
    "TaskSpaceInverseDynamics",
    "TrackingController",
    "WbcDiagnostics",
    "WbcGains",
    "WbcReference",
    "friction_basis",
]


# ----------------------------------------------------------------------------- parameters


@dataclass
class WbcGains:
    """Feedback gains (1/s², 1/s), task weights and QP parameters of the whole-body controller."""

    # Horizontal CoM (x, y) PD on the MPC reference; vertical CoM is left to the pelvis task.
    com_kp: float = 40.0
    com_kd: float = 12.0
    com_weight: float = 100.0
    com_z_weight: float = 0.0
    # Pelvis height and orientation.
    pelvis_height_kp: float = 100.0
    pelvis_height_kd: float = 20.0
    pelvis_height_weight: float = 100.0
    pelvis_rot_kp: float = 150.0
    pelvis_rot_kd: float = 25.0
    pelvis_rot_weight: float = 10.0
    # Feet: swing tracking (PD on the planner's pose) and contact (hold still, damping only).
    swing_foot_kp: float = 400.0
    swing_foot_kd: float = 40.0
    swing_foot_weight: float = 50.0
    contact_foot_kd: float = 20.0
    contact_foot_weight: float = 1000.0
    # Upper-body joints.
    upper_body_kp: float = 150.0
    upper_body_kd: float = 25.0
    upper_body_weight: float = 1.0
    # Centroidal angular momentum damping.
    angular_momentum_kd: float = 5.0
    angular_momentum_weight: float = 0.3
    # Regularisation (Eq. 20).
    lambda_qdd: float = 1e-4
    lambda_rho: float = 1e-5
    lambda_tau: float = 1e-6
    # Contact model (Eqs. 17, 24, 25).
    friction_mu: float = 0.7
    max_corner_force_weights: float = 2.0  # ρ ≤ this × m g per basis weight
    # Soft joint limits (Eqs. 22, 23) and acceleration limits.
    joint_limit_kl: float = 400.0
    joint_limit_bl: float = 40.0
    max_joint_acc_radps2: float = 400.0
    # Actuator torque limits (the URDF's efforts), kept with headroom for the servo's PD terms.
    torque_limit_fraction: float = 0.9
    # Joint set-points: integrated q̈, clipped to a max error from the measured state.
    servo_kp_scale: float = 0.25
    servo_kd_scale: float = 0.5
    max_position_error_rad: float = 0.01
    max_velocity_error_radps: float = 0.2
    # Fallback: stiff PD hold; the last good feed-forward decays with this time constant.
    fallback_decay_s: float = 0.2

    @classmethod
    def for_robot(cls, robot: RobotModel) -> WbcGains:
        """Per-robot defaults (tuned in closed loop in MuJoCo)."""
        if robot.name == "talos":
            # Stiffer servos (kp 1000-1500) need a smaller share to keep the set-point PD from
            # fighting the feed-forward torques.
            return cls(servo_kp_scale=0.05, servo_kd_scale=0.2, swing_foot_kp=300.0, swing_foot_kd=35.0)
        return cls()


@dataclass
class WbcReference:
    """What the whole-body controller tracks at one tick. World frame, SI units.

    Feet are ordered (left, right); contact corners in each foot's order front-left,
    front-right, back-right, back-left. Upper-body joints follow the order given to
    :class:`TaskSpaceInverseDynamics`.
    """

    com_xy_m: FloatArray  # (2,) from the CoM MPC
    com_xy_vel_mps: FloatArray  # (2,)
    com_xy_acc_mps2: FloatArray  # (2,)
    pelvis_height_m: float
    pelvis_height_rate_mps: float
    pelvis_rotation: FloatArray  # (3, 3) world ← pelvis
    pelvis_ang_vel_radps: FloatArray  # (3,)
    foot_pos_m: FloatArray  # (2, 3) sole centres
    foot_rotation: FloatArray  # (2, 3, 3)
    foot_lin_vel_mps: FloatArray  # (2, 3)
    foot_ang_vel_radps: FloatArray  # (2, 3)
    contact: NDArray[np.bool_]  # (2, 4) active sole corners
    upper_body_q_rad: FloatArray  # (n_upper,)
    upper_body_qd_radps: FloatArray  # (n_upper,)
    external_wrench: FloatArray | None = None  # (6,) [force N; torque N·m about the CoM] estimate
    foot_lin_acc_mps2: FloatArray | None = None  # (2, 3) swing feed-forward
    foot_ang_acc_radps2: FloatArray | None = None  # (2, 3)
    com_z_m: float | None = None  # tracked only when gains.com_z_weight > 0

    def is_finite(self) -> bool:
        """Every number finite (a sum propagates NaN/inf); malformed values count as not finite."""
        arrays = (self.com_xy_m, self.com_xy_vel_mps, self.com_xy_acc_mps2, self.pelvis_rotation,
                  self.pelvis_ang_vel_radps, self.foot_pos_m, self.foot_rotation, self.foot_lin_vel_mps,
                  self.foot_ang_vel_radps, self.upper_body_q_rad, self.upper_body_qd_radps, self.pelvis_height_m,
                  self.pelvis_height_rate_mps, self.external_wrench, self.foot_lin_acc_mps2, self.foot_ang_acc_radps2,
                  self.com_z_m)
        try:
            flat = np.concatenate([a for a in arrays if a is not None], axis=None, dtype=float)
            return math.isfinite(float(flat.sum()))
        except (TypeError, ValueError):
            return False


@dataclass
class WbcDiagnostics:
    """The solution of one tick and how it was obtained (contact forces, CoP and the QP residual
    are derived on first access, so the control loop does not pay for them)."""

    status: str  # "solved", "solved_inaccurate" or "fallback_<reason>"
    message: str = ""
    backend: str = ""  # "dense", "osqp" or "placo"
    qdd: FloatArray | None = None  # (nv,)
    rho: FloatArray | None = None  # (32,) friction-basis weights
    tau_nm: FloatArray | None = None  # (n_joints,) Eq. 15
    qp_iterations: int = 0
    pinocchio_s: float = 0.0
    build_s: float = 0.0
    qp_s: float = 0.0
    total_s: float = 0.0
    basis: FloatArray | None = field(default=None, repr=False)  # (2, 3, 4) pyramid edges per foot
    corners_m: FloatArray | None = field(default=None, repr=False)  # (2, 3, 4) corner positions
    qp: CentroidalQp | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        return self.status.startswith("solved")

    @cached_property
    def contact_forces_n(self) -> FloatArray | None:
        """(2, 4, 3) world force at each sole corner, f_c = B_c ρ_c (Eq. 17)."""
        if self.rho is None or self.basis is None:
            return None
        return np.einsum("fkb,fcb->fck", self.basis, self.rho.reshape(len(SIDES), N_CORNERS, N_BASIS))

    @cached_property
    def cop_m(self) -> FloatArray | None:
        """(2,) centre of pressure of the solution's contact forces (NaN without normal force)."""
        forces = self.contact_forces_n
        if forces is None or self.corners_m is None:
            return None
        fz = forces[..., 2]
        total = float(fz.sum())
        if total <= 1e-6:
            return np.full(2, np.nan)
        return (self.corners_m[:, :2] * fz[:, None, :]).sum(axis=(0, 2)) / total

    @cached_property
    def centroidal_residual(self) -> float:
        """max |Eq. 21| of the solution (after the exact base-acceleration projection)."""
        if self.qp is None or self.qdd is None or self.rho is None:
            return math.nan
        return self.qp.equality_residual(self.qdd, self.rho)


def friction_basis(normal: FloatArray, tangent: FloatArray, mu: float) -> FloatArray:
    """(3, 4) unit edges ``(n ± μ t1, n ± μ t2)/√(1+μ²)`` of a pyramid inside the friction cone (Eq. 17)."""
    n = normal / np.linalg.norm(normal)
    t1 = tangent - (tangent @ n) * n
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    edges = np.stack([n + mu * t1, n - mu * t1, n + mu * t2, n - mu * t2], axis=1)
    return edges / math.sqrt(1.0 + mu * mu)


# ----------------------------------------------------------------------------- the solver


@dataclass
class CentroidalQp:
    """The QP of Eqs. 20–25 in dense form, x = [q̈ (nv); ρ (32)]::

        min ½ q̈ᵀ P q̈ + cᵀ q̈ + ½ ρᵀ R ρ   s.t.  A q̈ − G ρ = b,  lo ≤ q̈_j ≤ up,  0 ≤ ρ ≤ ρ_max,
                                             τ_lo ≤ M_j q̈ + T ρ + h_j ≤ τ_up

    The last row keeps the joint torques inside the actuators' limits (G1's ankles give 35 N·m:
    a CoP the QP plans beyond what they can hold is not where the robot's CoP ends up).
    """

    p_qq: FloatArray  # (nv, nv)
    c_q: FloatArray  # (nv,)
    r_rr: FloatArray  # (32, 32)
    a_h: FloatArray  # (6, nv)
    g_rho: FloatArray  # (6, 32)
    b: FloatArray  # (6,)
    qdd_joint_lo: FloatArray  # (nv - 6,)
    qdd_joint_up: FloatArray  # (nv - 6,)
    rho_up: FloatArray  # (32,) 0 on inactive corners
    # Joint torques τ = M_j q̈ + T ρ + h_j (Eq. 15, actuated rows) within the actuators' limits.
    tau_qdd: FloatArray | None = None  # (n_joints, nv) M_j
    tau_rho: FloatArray | None = None  # (n_joints, 32) T = −Σ J_c,jᵀ B_c
    tau_bias: FloatArray | None = None  # (n_joints,) h_j (+ viscous damping)
    tau_lo: FloatArray | None = None  # (n_joints,)
    tau_up: FloatArray | None = None  # (n_joints,)

    def torques(self, qdd: FloatArray, rho: FloatArray) -> FloatArray | None:
        if self.tau_qdd is None:
            return None
        return self.tau_qdd @ qdd + self.tau_rho @ rho + self.tau_bias

    def objective(self, qdd: FloatArray, rho: FloatArray) -> float:
        """½ q̈ᵀPq̈ + cᵀq̈ + ½ ρᵀRρ (Eq. 20 up to a constant)."""
        return float(0.5 * qdd @ self.p_qq @ qdd + self.c_q @ qdd + 0.5 * rho @ self.r_rr @ rho)

    def equality_residual(self, qdd: FloatArray, rho: FloatArray) -> float:
        return float(np.max(np.abs(self.a_h @ qdd - self.g_rho @ rho - self.b)))

    def standard_form(self) -> QpProblem:
        """The same QP over x = [q̈; ρ] for the maintained backends (:mod:`engine.control.qp_backends`)."""
        nv, n_rho = self.p_qq.shape[0], self.r_rr.shape[0]
        h = np.zeros((nv + n_rho, nv + n_rho))
        h[:nv, :nv] = self.p_qq
        h[nv:, nv:] = self.r_rr
        lb = np.concatenate([np.full(6, -np.inf), self.qdd_joint_lo, np.zeros(n_rho)])
        ub = np.concatenate([np.full(6, np.inf), self.qdd_joint_up, self.rho_up])
        problem = QpProblem(h, np.concatenate([self.c_q, np.zeros(n_rho)]), lb, ub,
                            np.hstack([self.a_h, -self.g_rho]), self.b.copy())
        if self.tau_qdd is not None:
            problem.c = np.hstack([self.tau_qdd, self.tau_rho])
            problem.c_lo, problem.c_up = self.tau_lo - self.tau_bias, self.tau_up - self.tau_bias
        return problem


class DenseQpSolver:
    """Exact active-set solution of :class:`CentroidalQp` (no iteration tolerance).

    For a fixed set of joint accelerations held at their bounds, q̈ is eliminated in closed
    form: with q̈₀ = −P⁻¹c, Y = P⁻¹Aᵀ, S = A Y, the constrained optimum for a given ρ is
    q̈ = q̈₀ + Y S⁻¹ (b + Gρ − A q̈₀) and the cost left in ρ is ½ρᵀ(R + GᵀS⁻¹G)ρ +
    ρᵀGᵀS⁻¹(b − A q̈₀): a ≤32-variable box QP, solved by a primal active-set method
    warm-started from the previous tick. Violated joint-acceleration bounds are added to
    the fixed set, and violated torque limits to the equality rows (A gains the row M_j,
    G the row −T_j), both released by their multiplier's sign, in an outer loop. Returns None
    when either loop does not settle; the caller then uses OSQP.
    """

    def __init__(self, nv: int, n_rho: int, max_outer: int = 12, max_box: int = 200):
        self.nv, self.n_rho = nv, n_rho
        self.max_outer, self.max_box = max_outer, max_box
        self.rho_at_zero = np.ones(n_rho, dtype=bool)
        self.rho_at_up = np.zeros(n_rho, dtype=bool)
        self.fixed_lo = np.zeros(nv, dtype=bool)
        self.fixed_up = np.zeros(nv, dtype=bool)
        self.tau_fixed_lo = np.zeros(0, dtype=bool)  # torque limits in the working set
        self.tau_fixed_up = np.zeros(0, dtype=bool)
        self._lo = np.full(nv, -np.inf)
        self._up = np.full(nv, np.inf)
        self.iterations = 0

    def solve(self, qp: CentroidalQp) -> tuple[FloatArray, FloatArray] | None:
        lo, up = self._lo, self._up  # base rows stay ±inf
        lo[6:] = qp.qdd_joint_lo
        up[6:] = qp.qdd_joint_up
        active = qp.rho_up > 0.0
        if active.all():
            g_act, r_act, u_act = qp.g_rho, qp.r_rr, qp.rho_up
        else:
            g_act, r_act, u_act = qp.g_rho[:, active], qp.r_rr[np.ix_(active, active)], qp.rho_up[active]
        has_tau = qp.tau_qdd is not None
        if has_tau:
            n_tau = qp.tau_qdd.shape[0]
            if self.tau_fixed_lo.size != n_tau:
                self.tau_fixed_lo = np.zeros(n_tau, dtype=bool)
                self.tau_fixed_up = np.zeros(n_tau, dtype=bool)
            tau_rho_act = qp.tau_rho if active.all() else qp.tau_rho[:, active]
            tau_lo, tau_up = self.tau_fixed_lo.copy(), self.tau_fixed_up.copy()
        else:
            tau_lo = tau_up = np.zeros(0, dtype=bool)
        fixed_lo, fixed_up = self.fixed_lo, self.fixed_up
        self.iterations = 0
        for _ in range(self.max_outer):
            fixed = fixed_lo | fixed_up
            any_fixed = bool(fixed.any())
            # Equality rows: the centroidal dynamics, then the torque limits in the working set
            # (M_j q̈ + T_j ρ = τ_lim − h_j, i.e. rows of A q̈ − G ρ = b with G_j = −T_j).
            tau_rows = np.flatnonzero(tau_lo | tau_up)
            if tau_rows.size:
                lim = np.where(tau_up[tau_rows], qp.tau_up[tau_rows], qp.tau_lo[tau_rows])
                a_full = np.vstack([qp.a_h, qp.tau_qdd[tau_rows]])
                g_full = np.vstack([g_act, -tau_rho_act[tau_rows]])
                b_full = np.concatenate([qp.b, lim - qp.tau_bias[tau_rows]])
            else:
                a_full, g_full, b_full = qp.a_h, g_act, qp.b
            n_eq = a_full.shape[0]
            qdd = np.zeros(self.nv)
            if any_fixed:
                free = ~fixed
                qdd[fixed_lo] = lo[fixed_lo]
                qdd[fixed_up] = up[fixed_up]
                p_ff = qp.p_qq[np.ix_(free, free)]
                c_f = qp.c_q[free] + qp.p_qq[np.ix_(free, fixed)] @ qdd[fixed]
                a_f = a_full[:, free]
                b_f = b_full - a_full[:, fixed] @ qdd[fixed]
            else:
                p_ff, c_f, a_f, b_f = qp.p_qq, qp.c_q, a_full, b_full
            rhs_f = np.empty((c_f.size, n_eq + 1))
            rhs_f[:, 0] = -c_f
            rhs_f[:, 1:] = a_f.T
            _, sol, info = _dposv(p_ff, rhs_f)
            if info != 0:
                return None
            qdd0, y_mat = sol[:, 0], sol[:, 1:]
            resid0 = b_f - a_f @ qdd0
            rhs_s = np.empty((n_eq, g_full.shape[1] + 1))
            rhs_s[:, 0] = resid0
            rhs_s[:, 1:] = g_full
            _, s_sol, info = _dposv(a_f @ y_mat, rhs_s)  # S⁻¹ [r₀, G]
            if info != 0:
                return None
            s_r, s_g = s_sol[:, 0], s_sol[:, 1:]
            rho_act = self._box_qp(r_act + g_full.T @ s_g, g_full.T @ s_r, u_act, active)
            if rho_act is None:
                return None
            mult = s_r + s_g @ rho_act  # the equalities' multipliers
            step = qdd0 + y_mat @ mult
            if any_fixed:
                qdd[free] = step
            else:
                qdd = step
            # Outer active set on the joint-acceleration bounds and the torque limits.
            self.iterations += 1
            viol_lo = qdd < lo - 1e-9
            viol_up = qdd > up + 1e-9
            if any_fixed:
                grad = qp.p_qq @ qdd + qp.c_q - a_full.T @ mult
                release = (fixed_lo & (grad < 0.0)) | (fixed_up & (grad > 0.0))
                viol_lo &= free
                viol_up &= free
            else:
                release = fixed
            tau_changed = False
            if has_tau:
                tau = qp.tau_qdd @ qdd + tau_rho_act @ rho_act + qp.tau_bias
                t_viol_lo = ~(tau_lo | tau_up) & (tau < qp.tau_lo - 1e-6)
                t_viol_up = ~(tau_lo | tau_up) & (tau > qp.tau_up + 1e-6)
                lam = np.zeros(tau_lo.size)
                lam[tau_rows] = mult[6:]
                # An upper limit holds with λ ≤ 0, a lower one with λ ≥ 0 (∇f = Aᵀλ).
                t_release = (tau_up & (lam > 1e-12)) | (tau_lo & (lam < -1e-12))
                if t_viol_lo.any() or t_viol_up.any() or t_release.any():
                    tau_changed = True
                    # Add the worst violation only (each changes the others); releases all at once.
                    over = np.maximum(qp.tau_lo - tau, tau - qp.tau_up)
                    over[~(t_viol_lo | t_viol_up)] = -np.inf
                    tau_lo, tau_up = tau_lo & ~t_release, tau_up & ~t_release
                    if np.isfinite(over.max()):
                        worst = int(np.argmax(over))
                        tau_lo[worst] = bool(t_viol_lo[worst])
                        tau_up[worst] = bool(t_viol_up[worst])
            if not (viol_lo.any() or viol_up.any() or release.any() or tau_changed):
                self.fixed_lo, self.fixed_up = fixed_lo, fixed_up
                if has_tau:
                    self.tau_fixed_lo, self.tau_fixed_up = tau_lo, tau_up
                if u_act is qp.rho_up:
                    return qdd, rho_act
                rho = np.zeros(self.n_rho)
                rho[active] = rho_act
                return qdd, rho
            fixed_lo = (fixed_lo & ~release) | viol_lo
            fixed_up = (fixed_up & ~release) | viol_up
        self.fixed_lo = np.zeros(self.nv, dtype=bool)
        self.fixed_up = np.zeros(self.nv, dtype=bool)
        if has_tau:
            self.tau_fixed_lo = np.zeros_like(self.tau_fixed_lo)
            self.tau_fixed_up = np.zeros_like(self.tau_fixed_up)
        return None

    def _box_qp(self, h: FloatArray, f: FloatArray, upper: FloatArray, active: NDArray[np.bool_]) -> FloatArray | None:
        """min ½ρᵀHρ + fᵀρ, 0 ≤ ρ ≤ upper (H ≻ 0): primal active set (finite, exact), warm-started
        with the previous tick's bounds. Usually one linear solve."""
        at_zero = self.rho_at_zero[active]  # fancy indexing: copies
        at_up = self.rho_at_up[active]
        x = np.where(at_up, upper, 0.0)  # feasible start
        for _ in range(self.max_box):
            self.iterations += 1
            free = ~(at_zero | at_up)
            target = x.copy()
            if free.any():
                rhs = -f[free]
                if at_up.any():
                    rhs = rhs - h[np.ix_(free, at_up)] @ upper[at_up]
                h_ff = h if free.all() else h[np.ix_(free, free)]
                _, x_free, info = _dposv(h_ff, rhs)
                if info != 0:
                    return None
                target[free] = x_free
            if (target >= 0.0).all() and (target <= upper).all():
                x = target
                # Optimal on this working set: release the bound with the most negative multiplier, if any.
                grad = h @ x + f
                mult = np.where(at_zero, grad, 0.0) - np.where(at_up, grad, 0.0)
                worst = int(np.argmin(mult))
                if mult[worst] >= -1e-12:
                    self._store_rho_bounds(active, at_zero, at_up)
                    return x
                at_zero[worst] = at_up[worst] = False
                continue
            # Largest feasible step towards the target; the first bound hit joins the working set.
            step = target - x
            alpha, block, block_up = 1.0, -1, False
            down = free & (step < 0.0)
            if down.any():
                idx = np.flatnonzero(down)
                ratios = -x[idx] / step[idx]
                j = int(np.argmin(ratios))
                alpha, block = float(ratios[j]), int(idx[j])
            up = free & (step > 0.0)
            if up.any():
                idx = np.flatnonzero(up)
                ratios = (upper[idx] - x[idx]) / step[idx]
                j = int(np.argmin(ratios))
                if ratios[j] < alpha:
                    alpha, block, block_up = float(ratios[j]), int(idx[j]), True
            x = np.minimum(np.maximum(x + min(alpha, 1.0) * step, 0.0), upper)
            if block >= 0:
                if block_up:
                    x[block] = upper[block]
                    at_up[block] = True
                else:
                    x[block] = 0.0
                    at_zero[block] = True
        self._store_rho_bounds(active, np.ones(active.sum(), dtype=bool), np.zeros(active.sum(), dtype=bool))
        return None

    def _store_rho_bounds(self, active: NDArray[np.bool_], at_zero: NDArray[np.bool_], at_up: NDArray[np.bool_]) -> None:
        """Remember the box QP's working set (inactive corners count as 'at zero') for the next tick."""
        if active.all():
            self.rho_at_zero, self.rho_at_up = at_zero, at_up
        else:
            self.rho_at_zero = np.ones(self.n_rho, dtype=bool)
            self.rho_at_up = np.zeros(self.n_rho, dtype=bool)
            self.rho_at_zero[active] = at_zero
            self.rho_at_up[active] = at_up


class OsqpQpSolver:
    """:class:`CentroidalQp` in OSQP with a fixed sparsity pattern: values updated each tick, warm started.

    P: the full upper triangles of the q̈ and ρ blocks; A: six dense centroidal rows over
    every variable, one dense torque row per joint (τ_lo − h ≤ M_j q̈ + T ρ ≤ τ_up − h), then
    the identity for the bounds (inactive corners: 0 ≤ ρ ≤ 0).
    """

    def __init__(self, nv: int, n_rho: int, eps: float = 1e-5, max_iter: int = 4000):
        self.nv, self.n_rho = nv, n_rho
        self.n_tau = nv - 6
        n = nv + n_rho
        self.n_x = n
        iu_q = np.triu_indices(nv)
        iu_r = np.triu_indices(n_rho)
        oq = np.lexsort((iu_q[0], iu_q[1]))  # CSC order: by column, then row
        orr = np.lexsort((iu_r[0], iu_r[1]))
        self._p_idx_q = iu_q[0][oq] * nv + iu_q[1][oq]
        self._p_idx_r = iu_r[0][orr] * n_rho + iu_r[1][orr]
        rows = np.concatenate([iu_q[0][oq], nv + iu_r[0][orr]])
        cols = np.concatenate([iu_q[1][oq], nv + iu_r[1][orr]])
        p_mat = sp.csc_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
        if not np.array_equal(p_mat.indices, rows):
            raise AssertionError("P pattern order")
        n_dense = 6 + self.n_tau  # dense rows: centroidal, then torques
        self._n_dense = n_dense
        a_rows = np.concatenate([np.tile(np.arange(n_dense), n), n_dense + np.arange(n)])
        a_cols = np.concatenate([np.repeat(np.arange(n), n_dense), np.arange(n)])
        a_mat = sp.csc_matrix((np.ones(a_rows.size), (a_rows, a_cols)), shape=(n_dense + n, n))
        self._a_vals = np.ones((n, n_dense + 1))  # per column: the dense entries, then the bound's 1
        self._lo = np.zeros(n_dense + n)
        self._up = np.zeros(n_dense + n)
        self._lo[6:n_dense] = -1e9
        self._up[6:n_dense] = 1e9
        self._lo[n_dense:n_dense + 6] = -np.inf
        self._up[n_dense:n_dense + 6] = np.inf
        self._q = np.zeros(n)
        self._solver = osqp.OSQP()
        self._solver.setup(p_mat, self._q, a_mat, self._lo, self._up, verbose=False, eps_abs=eps, eps_rel=eps,
                           max_iter=max_iter, polishing=False, warm_starting=True, adaptive_rho=True,
                           check_termination=10)
        self.status = ""
        self.iterations = 0

    def solve(self, qp: CentroidalQp) -> tuple[FloatArray, FloatArray] | None:
        nv, nd = self.nv, self._n_dense
        px = np.concatenate([qp.p_qq.ravel()[self._p_idx_q], qp.r_rr.ravel()[self._p_idx_r]])
        self._a_vals[:nv, :6] = qp.a_h.T
        self._a_vals[nv:, :6] = -qp.g_rho.T
        if qp.tau_qdd is not None:
            self._a_vals[:nv, 6:nd] = qp.tau_qdd.T
            self._a_vals[nv:, 6:nd] = qp.tau_rho.T
            self._lo[6:nd] = qp.tau_lo - qp.tau_bias
            self._up[6:nd] = qp.tau_up - qp.tau_bias
        else:
            self._a_vals[:, 6:nd] = 0.0
        self._q[:nv] = qp.c_q
        self._lo[:6] = qp.b
        self._up[:6] = qp.b
        self._lo[nd + 6:nd + nv] = qp.qdd_joint_lo
        self._up[nd + 6:nd + nv] = qp.qdd_joint_up
        self._lo[nd + nv:] = 0.0
        self._up[nd + nv:] = qp.rho_up
        self._solver.update(Px=px, Ax=self._a_vals.ravel(), q=self._q, l=self._lo, u=self._up)
        result = self._solver.solve(raise_error=False)
        self.status = str(result.info.status)
        self.iterations = int(result.info.iter)
        x = result.x
        ok = result.info.status_val in (osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE)
        if not ok or x is None or not np.all(np.isfinite(x)):
            self._solver.warm_start(x=np.zeros(self.n_x), y=np.zeros(nd + self.n_x))
            return None
        return x[:nv].copy(), np.clip(x[nv:], 0.0, qp.rho_up)


class DaqpQpSolver:
    """:class:`CentroidalQp` in DAQP (dense dual active set, C), its arrays preallocated: the
    Hessian's two blocks, the centroidal equalities (sense 5: immutable equality) and the torque
    rows are written in place each tick. Bounds first (DAQP's simple bounds), then the rows."""

    def __init__(self, nv: int, n_rho: int, n_tau: int):
        import daqp

        self._solve = daqp.solve
        self.nv, self.n_rho, self.n_tau = nv, n_rho, n_tau
        n = nv + n_rho
        self._h = np.zeros((n, n))
        self._f = np.zeros(n)
        self._a = np.zeros((6 + n_tau, n))
        self._up = np.zeros(n + 6 + n_tau)
        self._lo = np.zeros(n + 6 + n_tau)
        self._up[:6], self._lo[:6] = 1e20, -1e20  # the floating base is free
        self._sense = np.zeros(n + 6 + n_tau, dtype=np.int32)
        self._sense[n:n + 6] = 5
        self.status = ""
        self.iterations = 0

    def solve(self, qp: CentroidalQp) -> tuple[FloatArray, FloatArray] | None:
        nv, n = self.nv, self.nv + self.n_rho
        h, a, lo, up = self._h, self._a, self._lo, self._up
        h[:nv, :nv] = qp.p_qq
        h[nv:, nv:] = qp.r_rr
        self._f[:nv] = qp.c_q
        a[:6, :nv] = qp.a_h
        np.negative(qp.g_rho, out=a[:6, nv:])
        lo[6:nv], up[6:nv] = qp.qdd_joint_lo, qp.qdd_joint_up
        lo[nv:n], up[nv:n] = 0.0, qp.rho_up
        lo[n:n + 6] = up[n:n + 6] = qp.b
        if qp.tau_qdd is not None:
            a[6:, :nv] = qp.tau_qdd
            a[6:, nv:] = qp.tau_rho
            np.subtract(qp.tau_lo, qp.tau_bias, out=lo[n + 6:])
            np.subtract(qp.tau_up, qp.tau_bias, out=up[n + 6:])
        else:
            a[6:] = 0.0
            lo[n + 6:], up[n + 6:] = -1e20, 1e20
        x, _, flag, info = self._solve(h, self._f, a, up, lo, self._sense)
        self.status = f"daqp exitflag {flag}"
        self.iterations = int(info.get("iterations", 0)) if isinstance(info, dict) else 0
        if flag not in (1, 2) or not math.isfinite(float(np.sum(x))):
            return None
        x = np.asarray(x)
        return x[:nv].copy(), np.minimum(np.maximum(x[nv:], 0.0), qp.rho_up)


# ----------------------------------------------------------------------------- the controller


class TaskSpaceInverseDynamics:
    """The paper's whole-body QP (Eqs. 15–25) for a biped with two rectangular soles.

    ``qp_backend``: ``"daqp"`` (default: fastest in ``studio bench qp``), ``"dense"`` (the
    hand-written exact active set), ``"osqp"`` (fixed sparsity pattern, warm started; the others'
    fallback) or ``"proxsuite"`` / ``"quadprog"`` (:mod:`engine.control.qp_backends`).
    """

    name = "task-space-id"

    def __init__(self, robot: RobotModel, gains: WbcGains | None = None,
                 upper_body_joints: Sequence[str] | None = None, dt_s: float = CONTROL_PERIOD_S,
                 qp_backend: str = "daqp"):
        if set(robot.config.soles) != set(SIDES):
            raise ValueError(f"{robot.name}: the inverse dynamics needs left and right soles")
        choices = ("dense", "osqp", *(b for b in qp_backends.BACKENDS if b != "osqp"))
        if qp_backend not in choices:
            raise ValueError(f"qp_backend: expected one of {', '.join(choices)}, got {qp_backend!r}")
        self.robot = robot
        self.gains = gains or WbcGains.for_robot(robot)
        self.dt_s = dt_s
        self.qp_backend = qp_backend
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.nv = self.model.nv
        self.n_joints = robot.n_joints
        self.n_rho = len(SIDES) * N_CORNERS * N_BASIS
        self.mass_kg = robot.mass_kg
        self.foot_frame_ids = [self.model.getFrameId(f"{s}_foot") for s in SIDES]
        # Corner offsets in the foot frame (sole centre, sole plane): (2, 4, 3).
        self.corner_offsets_m = np.array([[np.subtract(c, robot.config.soles[s].center)
                                           for c in robot.config.soles[s].corners()] for s in SIDES])
        names = list(robot.config.upper_body_joints if upper_body_joints is None else upper_body_joints)
        self.upper_body_joints = names
        self.upper_v_indices = np.array([6 + robot.joint_names.index(j) for j in names], dtype=np.int64)

        g = self.gains
        self.foot_tasks = [FramePoseTask(i) for i in range(len(SIDES))]
        self.pelvis_task = PelvisTask(kp=[g.pelvis_height_kp] + [g.pelvis_rot_kp] * 3,
                                      kd=[g.pelvis_height_kd] + [g.pelvis_rot_kd] * 3,
                                      weight=[g.pelvis_height_weight] + [g.pelvis_rot_weight] * 3)
        self.com_task = ComTask(kp=g.com_kp, kd=g.com_kd, weight=[g.com_weight, g.com_weight, g.com_z_weight])
        self.upper_task = JointTask(self.upper_v_indices, self.nv, g.upper_body_kp, g.upper_body_kd, g.upper_body_weight)
        self.angular_momentum_task = AngularMomentumTask(kd=g.angular_momentum_kd, weight=g.angular_momentum_weight)
        self.tasks = [*self.foot_tasks, self.pelvis_task, self.com_task, self.upper_task, self.angular_momentum_task]
        self.n_rows = sum(t.dim for t in self.tasks)
        self._jac = np.zeros((self.n_rows, self.nv))
        self._jac_filled = False
        self._rhs = np.zeros(self.n_rows)
        self._w = np.zeros(self.n_rows)
        self._skew = np.zeros((2 * len(SIDES) * N_CORNERS, 3, 3))
        self._corner_offsets_t = self.corner_offsets_m.transpose(0, 2, 1).copy()
        mu_n = g.friction_mu / math.sqrt(1.0 + g.friction_mu**2)
        # Pyramid edges (n ± μ t1, n ± μ t2)/√(1+μ²), t1 = heading, t2 = z × heading (see friction_basis):
        # their x and y rows are linear in the heading (hx, hy).
        self._basis_xy = mu_n * np.array([[[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 1.0]],
                                          [[0.0, 0.0, 1.0, -1.0], [1.0, -1.0, 0.0, 0.0]]])  # (x|y row, hx|hy, 4)
        self._basis_template = np.zeros((len(SIDES), 3, N_BASIS))
        self._basis_template[:, 2, :] = 1.0 / math.sqrt(1.0 + g.friction_mu**2)
        self._arms_buf = np.zeros((2 * len(SIDES) * N_CORNERS, 3))
        self._edges_buf = np.zeros((2 * len(SIDES) * N_CORNERS, 3, N_BASIS))
        self._rho_up_cache: tuple[bytes, FloatArray] = (b"", np.zeros(self.n_rho))
        self._wrench_buf = np.zeros((len(SIDES), 6, N_CORNERS * N_BASIS))

        damping = np.asarray(self.model.damping[6:], dtype=float).copy()
        self._joint_damping = damping if np.any(damping > 0.0) else None
        self._joint_lower = robot.joint_lower.copy()
        self._joint_upper = robot.joint_upper.copy()
        effort = np.asarray(robot.effort_limits, dtype=float)
        self._torque_limit = np.where(effort > 0.0, g.torque_limit_fraction * effort, 1e6)
        self._servo_kp = g.servo_kp_scale * robot.kp
        self._servo_kd = g.servo_kd_scale * robot.kd
        self.dense_solver = DenseQpSolver(self.nv, self.n_rho)
        self.osqp_solver = OsqpQpSolver(self.nv, self.n_rho)
        self.daqp_solver = DaqpQpSolver(self.nv, self.n_rho, self.n_joints)
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

    def hold_reference(self, q: FloatArray) -> WbcReference:
        """A standing reference that holds configuration ``q``: both feet flat and in contact."""
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
    def _compute(self, state: RobotState, ref: WbcReference, t0: float) -> JointCommand:
        q = np.asarray(state.q, dtype=float)
        v = np.asarray(state.v, dtype=float)
        if q.shape != (self.model.nq,) or v.shape != (self.nv,) or not math.isfinite(q.sum() + v.sum()):
            return self._fallback(state, "fallback_invalid_state", "state is not a finite (q, v)", t0)
        if self.q_des is None:
            self.reset(state)
        if not ref.is_finite():
            return self._fallback(state, "fallback_invalid_reference", "reference has non-finite values", t0)
        contact = np.asarray(ref.contact, dtype=bool).reshape(len(SIDES), N_CORNERS)
        if not contact.any():
            return self._fallback(state, "fallback_no_contact", "no active contact corner: nothing to stand on", t0)

        snap = DynamicsSnapshot.compute(self.model, self.data, q, v, self.foot_frame_ids)
        t1 = time.perf_counter()
        self._set_targets(ref, contact)
        qp = self._build_qp(snap, ref, contact)
        self.qp = qp
        t2 = time.perf_counter()
        solution, backend, iterations, message = None, self.qp_backend, 0, ""
        if self.qp_backend == "dense":  # (the default, "daqp", is the next branch)
            solution = self.dense_solver.solve(qp)
            iterations = self.dense_solver.iterations
        elif self.qp_backend == "daqp":
            solution = self.daqp_solver.solve(qp)
            iterations, message = self.daqp_solver.iterations, self.daqp_solver.status
        elif self.qp_backend != "osqp":
            result = qp_backends.solve(qp.standard_form(), self.qp_backend)
            message = result.status
            if result.ok:
                solution = (result.x[:self.nv].copy(), np.clip(result.x[self.nv:], 0.0, qp.rho_up))
        if solution is None:
            backend = "osqp"
            solution = self.osqp_solver.solve(qp)
            iterations, message = self.osqp_solver.iterations, f"osqp: {self.osqp_solver.status}"
        t3 = time.perf_counter()
        if solution is None:
            return self._fallback(state, "fallback_solver", message or "qp failed", t0, iterations)
        qdd, rho = solution
        tau = self._torques(snap, qdd, rho)
        if not math.isfinite(tau.sum()):
            return self._fallback(state, "fallback_solver", "non-finite torques", t0, iterations)
        cmd = self._setpoints(state, qdd, tau)
        self.last_tau = tau
        status = "solved" if backend in ("dense", "daqp") or "inaccurate" not in message else "solved_inaccurate"
        self.diagnostics = WbcDiagnostics(
            status=status, message=message, backend=backend, qdd=qdd, rho=rho, tau_nm=tau, qp_iterations=iterations,
            pinocchio_s=t1 - t0, build_s=t2 - t1, qp_s=t3 - t2, total_s=time.perf_counter() - t0,
            basis=self._basis, corners_m=self._corners_m, qp=qp)
        return cmd

    def _set_targets(self, ref: WbcReference, contact: NDArray[np.bool_]) -> None:
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
                task.weight[:] = g.contact_foot_weight if contact[i].any() else g.swing_foot_weight
        self.pelvis_task.set_target(ref.pelvis_height_m, ref.pelvis_rotation, ref.pelvis_height_rate_mps,
                                    ref.pelvis_ang_vel_radps)
        com = self.com_task  # targets written in place (the task owns its 3-vectors)
        com.position_m[:2] = ref.com_xy_m
        com.position_m[2] = 0.0 if ref.com_z_m is None else ref.com_z_m
        com.velocity_mps[:2] = ref.com_xy_vel_mps
        com.acceleration_mps2[:2] = ref.com_xy_acc_mps2
        com.weight[2] = g.com_z_weight if ref.com_z_m is not None else 0.0
        self.upper_task.set_target(ref.upper_body_q_rad, ref.upper_body_qd_radps)

    def _build_qp(self, snap: DynamicsSnapshot, ref: WbcReference, contact: NDArray[np.bool_]) -> CentroidalQp:
        g = self.gains
        nv = self.nv
        # ---- tasks: stacked weighted least squares on q̈ (Eq. 20)
        r = 0
        for task in self.tasks:
            d = task.dim
            if not task.constant_jacobian or not self._jac_filled:
                self._jac[r:r + d] = task.compute_jacobian(snap)
            np.subtract(task.compute_desired_acceleration(snap), task.compute_drift(snap), out=self._rhs[r:r + d])
            self._w[r:r + d] = task.weight
            r += d
        self._jac_filled = True
        wj = self._jac * self._w[:, None]
        p_qq = self._jac.T @ wj
        p_qq.flat[::nv + 1] += g.lambda_qdd
        c_q = -(wj.T @ self._rhs)

        # ---- contact model (Eq. 17): corners, friction pyramids (world z normal, foot-yaw tangents)
        rot = snap.frame_rotation  # (2, 3, 3)
        corner_rel = rot @ self._corner_offsets_t  # (2, 3, 4) world, from the sole centre
        corners = snap.frame_position_m[:, :, None] + corner_rel  # (2, 3, 4)
        heading = rot[:, :2, 0]  # foot x axes, horizontal part (2, 2)
        heading = heading / np.maximum(np.sqrt((heading * heading).sum(axis=1)), 1e-9)[:, None]
        basis = self._basis_template.copy()  # (2, 3, 4); z row constant
        basis[:, :2, :] = (heading @ self._basis_xy).transpose(1, 0, 2)  # x and y rows of the pyramid edges
        self._basis = basis
        self._corners_m = corners
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
        self._tau_map = tau_map
        tj = tau_map[6:]
        r_rr = g.lambda_tau * (tj.T @ tj)  # λ_τ̄ ‖τ̄‖²
        r_rr.flat[::self.n_rho + 1] += g.lambda_rho

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
        key = contact.tobytes()
        if key != self._rho_up_cache[0]:
            rho_max = g.max_corner_force_weights * self.mass_kg * GRAVITY_MPS2
            self._rho_up_cache = (key, np.repeat(np.where(contact.ravel(), rho_max, 0.0), N_BASIS))
        rho_up = self._rho_up_cache[1]
        # ---- actuator torque limits on Eq. 15's joint rows: τ = M_j q̈ + T ρ + h_j
        bias = snap.nonlinear_effects[6:].copy()
        if self._joint_damping is not None:
            bias += self._joint_damping * snap.v[6:]
        return CentroidalQp(p_qq, c_q, r_rr, snap.centroidal_map, g_rho, b, lo, up, rho_up,
                            tau_qdd=snap.mass_matrix[6:], tau_rho=tj, tau_bias=bias,
                            tau_lo=-self._torque_limit, tau_up=self._torque_limit)

    def _skew_stack(self, arms: FloatArray) -> FloatArray:
        s = self._skew
        s[:, 0, 1] = -arms[:, 2]
        s[:, 0, 2] = arms[:, 1]
        s[:, 1, 0] = arms[:, 2]
        s[:, 1, 2] = -arms[:, 0]
        s[:, 2, 0] = -arms[:, 1]
        s[:, 2, 1] = arms[:, 0]
        return s

    def _torques(self, snap: DynamicsSnapshot, qdd: FloatArray, rho: FloatArray) -> FloatArray:
        """Eq. 15: base rows solved exactly for q̈_base (6×6, in place), then τ from the joint rows."""
        m = snap.mass_matrix
        contact_gen = self._tau_map @ rho  # −Σ J_cᵀ f_c
        rhs = -(m[:6, 6:] @ qdd[6:]) - snap.nonlinear_effects[:6] - contact_gen[:6]
        _, base, info = _dposv(m[:6, :6], rhs)  # the base block of M is symmetric positive definite
        qdd[:6] = base if info == 0 else np.linalg.solve(m[:6, :6], rhs)
        tau = m[6:] @ qdd + snap.nonlinear_effects[6:] + contact_gen[6:]
        if self._joint_damping is not None:  # the model's viscous joint damping (MuJoCo applies it too)
            tau += self._joint_damping * snap.v[6:]
        return tau

    def _setpoints(self, state: RobotState, qdd: FloatArray, tau: FloatArray) -> JointCommand:
        self.q_des, self.qd_des = integrate_setpoints(self.q_des, self.qd_des, qdd[6:], state, self.gains, self.dt_s)
        return JointCommand(self.q_des.copy(), self.qd_des.copy(), tau.copy(), self._servo_kp, self._servo_kd)

    def _fallback(self, state: RobotState, status: str, message: str, t0: float, iterations: int = 0) -> JointCommand:
        cmd = fallback_hold(self.robot, state, self.q_des, self.last_tau, self.dt_s, self.gains.fallback_decay_s)
        self.q_des, self.qd_des, self.last_tau = cmd.q_des.copy(), cmd.qd_des.copy(), cmd.tau_ff.copy()
        self.diagnostics = WbcDiagnostics(status=status, message=message, tau_nm=self.last_tau.copy(),
                                          qp_iterations=iterations, total_s=time.perf_counter() - t0)
        return cmd


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


# ----------------------------------------------------------------------------- controller slot


ReferenceSource = Callable[[RobotState], WbcReference]


class TrackingController:
    """Puts a reference-tracking whole-body controller (``compute(state, ref)``) in the
    simulation's controller slot: ``reference(state)`` supplies the reference each tick."""

    def __init__(self, wbc, reference: ReferenceSource):  # noqa: ANN001 - TaskSpaceInverseDynamics or PlacoWbc
        self.wbc = wbc
        self.reference = reference
        self.name = getattr(wbc, "name", "wbc")

    def reset(self, state: RobotState) -> None:
        self.wbc.reset(state)

    def compute(self, state: RobotState) -> JointCommand:
        return self.wbc.compute(state, self.reference(state))
