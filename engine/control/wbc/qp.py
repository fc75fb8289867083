"""The whole-body QP (Eqs. 20–25) in dense form and its solvers: DAQP on preallocated arrays (default),
the hand-written dense active set, OSQP with a fixed sparsity pattern."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray
from scipy.linalg.lapack import dposv as _dposv

from engine.control.qp_backends import QpProblem
from engine.control.wbc.active_set import QP_OPTIMAL, solve_centroidal_qp
from engine.control.wbc.kernels import fill_daqp

FloatArray = NDArray[np.float64]


class TorqueRows(NamedTuple):
    """The joint-torque rows τ = M_j q̈ + T ρ + h_j and their limits τ_lo ≤ τ ≤ τ_up."""

    qdd: FloatArray  # (n_joints, nv) M_j
    rho: FloatArray  # (n_joints, 32) T
    bias: FloatArray  # (n_joints,) h_j
    lo: FloatArray  # (n_joints,)
    up: FloatArray  # (n_joints,)


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

    def torque_rows(self) -> TorqueRows | None:
        """The five tau_* fields together, or None when the QP has no torque rows."""
        if self.tau_qdd is None:
            return None
        assert (self.tau_rho is not None and self.tau_bias is not None and self.tau_lo is not None
                and self.tau_up is not None), "the tau_* fields are set together"
        return TorqueRows(self.tau_qdd, self.tau_rho, self.tau_bias, self.tau_lo, self.tau_up)

    def torques(self, qdd: FloatArray, rho: FloatArray) -> FloatArray | None:
        torque = self.torque_rows()
        if torque is None:
            return None
        return torque.qdd @ qdd + torque.rho @ rho + torque.bias

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
        torque = self.torque_rows()
        if torque is not None:
            problem.c = np.hstack([torque.qdd, torque.rho])
            problem.c_lo, problem.c_up = torque.lo - torque.bias, torque.up - torque.bias
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
        torque = qp.torque_rows()
        has_tau = torque is not None
        if torque is not None:
            n_tau = torque.qdd.shape[0]
            if self.tau_fixed_lo.size != n_tau:
                self.tau_fixed_lo = np.zeros(n_tau, dtype=bool)
                self.tau_fixed_up = np.zeros(n_tau, dtype=bool)
            tau_rho_act = torque.rho if active.all() else torque.rho[:, active]
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
                assert torque is not None, "torque rows enter the working set only when the QP has them"
                lim = np.where(tau_up[tau_rows], torque.up[tau_rows], torque.lo[tau_rows])
                a_full = np.vstack([qp.a_h, torque.qdd[tau_rows]])
                g_full = np.vstack([g_act, -tau_rho_act[tau_rows]])
                b_full = np.concatenate([qp.b, lim - torque.bias[tau_rows]])
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
            if torque is not None:
                tau = torque.qdd @ qdd + tau_rho_act @ rho_act + torque.bias
                t_viol_lo = ~(tau_lo | tau_up) & (tau < torque.lo - 1e-6)
                t_viol_up = ~(tau_lo | tau_up) & (tau > torque.up + 1e-6)
                lam = np.zeros(tau_lo.size)
                lam[tau_rows] = mult[6:]
                # An upper limit holds with λ ≤ 0, a lower one with λ ≥ 0 (∇f = Aᵀλ).
                t_release = (tau_up & (lam > 1e-12)) | (tau_lo & (lam < -1e-12))
                if t_viol_lo.any() or t_viol_up.any() or t_release.any():
                    tau_changed = True
                    # Add the worst violation only (each changes the others); releases all at once.
                    over = np.maximum(torque.lo - tau, tau - torque.up)
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
        torque = qp.torque_rows()
        if torque is not None:
            self._a_vals[:nv, 6:nd] = torque.qdd.T
            self._a_vals[nv:, 6:nd] = torque.rho.T
            self._lo[6:nd] = torque.lo - torque.bias
            self._up[6:nd] = torque.up - torque.bias
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
    rows are written in place each tick. Bounds first (DAQP's simple bounds), then the rows. One
    ``daqp.Model`` workspace per problem size is kept: each tick updates its data and starts from
    the previous solve's active set (equal to a cold ``daqp.solve`` to ~1e-11, ≈ 15 % less time).

    ``compiled``: the form is written by :func:`engine.control.wbc.kernels.fill_daqp` over the ρ of the
    corners in contact only (the others are fixed at 0: in single support the QP has 16 variables
    fewer, and DAQP's factorisations scale with the cube); otherwise by numpy over every ρ (the
    reference)."""

    def __init__(self, nv: int, n_rho: int, n_tau: int, compiled: bool = False):
        import daqp

        self._daqp = daqp
        self.compiled = compiled
        self.nv, self.n_rho, self.n_tau = nv, n_rho, n_tau
        self._workspaces: dict[int, _DaqpWorkspace] = {}
        self._rho_idx_cache: tuple[bytes, NDArray[np.int64]] = (b"", np.arange(n_rho))
        ws = self._workspace(n_rho)
        self._h, self._f, self._a, self._lo, self._up, self._sense = ws.h, ws.f, ws.a, ws.lo, ws.up, ws.sense
        self.status = ""
        self.iterations = 0

    def _workspace(self, n_rho: int) -> _DaqpWorkspace:
        ws = self._workspaces.get(n_rho)
        if ws is None:
            ws = self._workspaces[n_rho] = _DaqpWorkspace(self._daqp.Model(), self.nv, n_rho, self.n_tau)
        return ws

    def solve(self, qp: CentroidalQp) -> tuple[FloatArray, FloatArray] | None:
        torque = qp.torque_rows()
        if self.compiled and torque is not None:
            key = (qp.rho_up > 0.0).tobytes()
            if key != self._rho_idx_cache[0]:
                self._rho_idx_cache = (key, np.flatnonzero(qp.rho_up > 0.0).astype(np.int64))
            rho_idx = self._rho_idx_cache[1]
            ws = self._workspace(rho_idx.size)
            fill_daqp(qp.p_qq, qp.c_q, qp.r_rr, qp.a_h, qp.g_rho, qp.b, qp.qdd_joint_lo, qp.qdd_joint_up, qp.rho_up,
                      torque.qdd, torque.rho, torque.bias, torque.lo, torque.up, rho_idx, ws.h, ws.f, ws.a, ws.lo, ws.up)
            x = self._run(ws)
            if x is None:
                return None
            rho = np.zeros(self.n_rho)
            rho[rho_idx] = np.minimum(np.maximum(x[self.nv:], 0.0), ws.up[self.nv:self.nv + rho_idx.size])
            return x[:self.nv].copy(), rho
        self._fill_numpy(qp)
        ws = self._workspace(self.n_rho)
        x = self._run(ws)
        if x is None:
            return None
        return x[:self.nv].copy(), np.minimum(np.maximum(x[self.nv:], 0.0), ws.up[self.nv:self.nv + self.n_rho])

    def _fill_numpy(self, qp: CentroidalQp) -> None:
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
        torque = qp.torque_rows()
        if torque is not None:
            a[6:, :nv] = torque.qdd
            a[6:, nv:] = torque.rho
            np.subtract(torque.lo, torque.bias, out=lo[n + 6:])
            np.subtract(torque.up, torque.bias, out=up[n + 6:])
        else:
            a[6:] = 0.0
            lo[n + 6:], up[n + 6:] = -1e20, 1e20

    def _run(self, ws: _DaqpWorkspace) -> FloatArray | None:
        if ws.set_up:
            ws.model.update(H=ws.h, f=ws.f, A=ws.a, bupper=ws.up, blower=ws.lo)
        else:
            ws.model.setup(ws.h, ws.f, ws.a, ws.up, ws.lo, ws.sense)
            ws.set_up = True
        x, _, flag, info = ws.model.solve()
        self.status = f"daqp exitflag {flag}"
        self.iterations = int(info.get("iterations", 0)) if isinstance(info, dict) else 0
        if flag not in (1, 2) or not math.isfinite(float(x.sum())):
            ws.set_up = False  # start the next solve of this size cold
            return None
        return np.asarray(x)


class ActiveSetQpSolver:
    """:class:`CentroidalQp` by the compiled, structure-aware dual active set of
    :mod:`engine.control.wbc.active_set` (DAQP's steps and tolerances without its per-tick refactorisation of
    the whole Hessian), over the ρ of the corners in contact only, warm-started from the previous solve's
    working set of the same size. Returns None when it does not settle (a singular working set, the
    iteration cap): the caller then runs DAQP."""

    def __init__(self, nv: int, n_rho: int, n_tau: int, max_iter: int = 500):
        self.nv, self.n_rho, self.n_tau = nv, n_rho, n_tau
        self.max_iter = max_iter
        self._rho_idx_cache: tuple[bytes, NDArray[np.int64]] = (b"", np.arange(n_rho))
        # one warm working set per number of ρ in the QP: (constraint indices, upper side, count)
        self._warm: dict[int, tuple[NDArray[np.int64], NDArray[np.bool_], list[int]]] = {}
        self.status = ""
        self.iterations = 0

    def solve(self, qp: CentroidalQp) -> tuple[FloatArray, FloatArray] | None:
        # the tau_* fields read directly (no TorqueRows per tick); they are set together
        tau_qdd, tau_rho, tau_bias, tau_lo, tau_up = qp.tau_qdd, qp.tau_rho, qp.tau_bias, qp.tau_lo, qp.tau_up
        if tau_qdd is None or tau_rho is None or tau_bias is None or tau_lo is None or tau_up is None:
            self.status = "active set: the QP has no torque rows"
            return None
        rho_idx, index, upper, count = self.workspace(qp.rho_up)
        x, qdd, rho = np.empty(self.nv + rho_idx.size), np.empty(self.nv), np.empty(self.n_rho)
        outcome, iterations, n_out = solve_centroidal_qp(
            qp.p_qq, qp.c_q, qp.r_rr, qp.a_h, qp.g_rho, qp.b, qp.qdd_joint_lo, qp.qdd_joint_up, qp.rho_up, tau_qdd,
            tau_rho, tau_bias, tau_lo, tau_up, rho_idx, index, upper, count[0], self.max_iter, x, qdd, rho)
        if outcome != QP_OPTIMAL and count[0] > 0:  # the warm working set did not work: once more, cold
            outcome, more, n_out = solve_centroidal_qp(
                qp.p_qq, qp.c_q, qp.r_rr, qp.a_h, qp.g_rho, qp.b, qp.qdd_joint_lo, qp.qdd_joint_up, qp.rho_up,
                tau_qdd, tau_rho, tau_bias, tau_lo, tau_up, rho_idx, index, upper, 0, self.max_iter, x, qdd, rho)
            iterations += more
        if not self.record(outcome, iterations, n_out, count):  # (a non-finite solution counts as not convex)
            return None
        return qdd, rho

    def workspace(self, rho_up: FloatArray) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_], list[int]]:
        """The ρ in the QP (the corners in contact: ``rho_up > 0``) and the warm working set of their number
        (:meth:`warm_set`): what a solve reads and updates."""
        key = (rho_up > 0.0).tobytes()
        if key != self._rho_idx_cache[0]:
            self._rho_idx_cache = (key, np.flatnonzero(rho_up > 0.0).astype(np.int64))
        rho_idx = self._rho_idx_cache[1]
        index, upper, count = self.warm_set(rho_idx.size)
        return rho_idx, index, upper, count

    def warm_set(self, n_rho: int) -> tuple[NDArray[np.int64], NDArray[np.bool_], list[int]]:
        """The warm working set of QPs with ``n_rho`` ρ: constraint indices, upper sides and a one-element list
        holding its size."""
        warm = self._warm.get(n_rho)
        if warm is None:
            size = self.nv + n_rho + 6 + self.n_tau
            warm = self._warm[n_rho] = (np.zeros(size, dtype=np.int64), np.zeros(size, dtype=np.bool_), [0])
        return warm

    def record(self, outcome: int, iterations: int, n_out: int, count: list[int]) -> bool:
        """Keep a solve's final working-set size, iterations and status; True when it is optimal."""
        count[0] = n_out
        self.iterations = iterations
        if outcome != QP_OPTIMAL:
            self.status = f"active set outcome {outcome}"
            return False
        self.status = "active set optimal"
        return True


class _DaqpWorkspace:
    """One DAQP problem size: its model and preallocated arrays (bounds, then the 6 + n_tau rows)."""

    def __init__(self, model: object, nv: int, n_rho: int, n_tau: int):
        n = nv + n_rho
        self.model: Any = model
        self.set_up = False
        self.h = np.zeros((n, n))
        self.f = np.zeros(n)
        self.a = np.zeros((6 + n_tau, n))
        self.up = np.zeros(n + 6 + n_tau)
        self.lo = np.zeros(n + 6 + n_tau)
        self.up[:6], self.lo[:6] = 1e20, -1e20  # the floating base is free
        self.sense = np.zeros(n + 6 + n_tau, dtype=np.int32)
        self.sense[n:n + 6] = 5
