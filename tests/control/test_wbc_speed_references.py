"""The whole-body tick's speed-ups compute the same numbers as the code they replaced (issue 12, speed6).

The kernels before the speed-up are kept here as the references (verbatim, compiled without the disk cache):
``assemble_qp`` (the task rows' normal equations over every column, now over each row's non-zero columns) and
``torques`` (its two matrix-vector products row by row, now two rows side by side), the active set's
``_cholesky_block`` and ``_forward`` (row by row, now two rows side by side) and ``solve_centroidal_qp`` (the Gram products and the primal point over every column, now over the columns of
L⁻¹aᵢ that can be non-zero; the working set's Cholesky factor recomputed whole each iteration, now from its
first changed row). The tests assert bit-equal results (signed zeros included) on recorded whole-body QPs of
G1 and TALOS walks, cold and warm started, and on perturbed ones. The one-call tick
(``TaskSpaceInverseDynamics._compute_one_call``) is compared with the step-by-step path it replaces.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from engine.control.wbc.active_set import (
    DUAL_TOL,
    PRIMAL_TOL,
    QP_ITERATION_LIMIT,
    QP_NOT_CONVEX,
    QP_OPTIMAL,
    QP_SINGULAR,
    SINGULAR_TOL,
    _backward,
    _gram_solve,
    _row,
)


@njit(cache=False, nogil=True)
def assemble_qp_reference(jac, w, rhs, lambda_qdd, rot, pos, offsets_t, com, basis_xy, basis_z, frame_jac,
                lambda_tau, lambda_rho, p_qq, c_q, r_rr, g_rho, tau_map, corners, basis):  # noqa: ANN001, ANN201
    """Fill ``p_qq`` (nv, nv), ``c_q`` (nv,), ``r_rr`` (32, 32), ``g_rho`` (6, 32), ``tau_map`` (nv, 32),
    ``corners`` (2, 3, 4) and ``basis`` (2, 3, 4) in place (see the module docstring)."""
    n_rows, nv = jac.shape
    # ---- tasks: P = Jᵀ W J + λ I (upper triangle, mirrored), c = −Jᵀ W r; zero entries skipped
    for i in range(nv):
        c_q[i] = 0.0
        for j in range(nv):
            p_qq[i, j] = 0.0
    for r in range(n_rows):
        wr = w[r]
        if wr == 0.0:
            continue
        wrr = wr * rhs[r]
        for i in range(nv):
            a = jac[r, i]
            if a == 0.0:
                continue
            wa = wr * a
            c_q[i] -= a * wrr
            for j in range(i, nv):
                b = jac[r, j]
                if b != 0.0:
                    p_qq[i, j] += wa * b
    for i in range(nv):
        p_qq[i, i] += lambda_qdd
        for j in range(i + 1, nv):
            p_qq[j, i] = p_qq[i, j]
    # ---- contact model: corners and pyramid edges per sole (world z normal, foot-yaw tangents)
    n_sides = rot.shape[0]
    n_corners = offsets_t.shape[2]
    n_basis = basis_xy.shape[2]
    per_side = n_corners * n_basis
    corner_rel = np.empty((n_sides, 3, n_corners))
    for s in range(n_sides):
        for r in range(3):
            for c in range(n_corners):
                acc = 0.0
                for k in range(3):
                    acc += rot[s, r, k] * offsets_t[s, k, c]
                corner_rel[s, r, c] = acc
                corners[s, r, c] = pos[s, r] + acc
        hx, hy = rot[s, 0, 0], rot[s, 1, 0]
        norm = max(math.sqrt(hx * hx + hy * hy), 1e-9)
        hx /= norm
        hy /= norm
        for r in range(2):
            for k in range(n_basis):
                basis[s, r, k] = hx * basis_xy[r, 0, k] + hy * basis_xy[r, 1, k]
        for k in range(n_basis):
            basis[s, 2, k] = basis_z
    # ---- G ρ (force rows, then moments about the CoM) and the feet's wrenches per unit ρ
    wrench = np.empty((6, per_side))
    for s in range(n_sides):
        for c in range(n_corners):
            ax, ay, az = corners[s, 0, c] - com[0], corners[s, 1, c] - com[1], corners[s, 2, c] - com[2]
            fx, fy, fz = corner_rel[s, 0, c], corner_rel[s, 1, c], corner_rel[s, 2, c]
            for k in range(n_basis):
                ex, ey, ez = basis[s, 0, k], basis[s, 1, k], basis[s, 2, k]
                col = s * per_side + c * n_basis + k
                g_rho[0, col] = ex
                g_rho[1, col] = ey
                g_rho[2, col] = ez
                g_rho[3, col] = ay * ez - az * ey
                g_rho[4, col] = az * ex - ax * ez
                g_rho[5, col] = ax * ey - ay * ex
                m = c * n_basis + k
                wrench[0, m] = ex
                wrench[1, m] = ey
                wrench[2, m] = ez
                wrench[3, m] = fy * ez - fz * ey
                wrench[4, m] = fz * ex - fx * ez
                wrench[5, m] = fx * ey - fy * ex
        # τ̄ map of this side: −J_sᵀ wrench (nv, 16); the foot's Jacobian is zero outside its leg and the base
        for i in range(nv):
            nonzero = False
            for r in range(6):
                if frame_jac[s, r, i] != 0.0:
                    nonzero = True
            for m in range(per_side):
                acc = 0.0
                if nonzero:
                    for r in range(6):
                        acc += frame_jac[s, r, i] * wrench[r, m]
                tau_map[i, s * per_side + m] = -acc
    # ---- R = λ_τ̄ T_jᵀ T_j + λ_ρ I over the joint rows (6:) of the τ̄ map
    # (row by row over the non-zero entries: each joint row of T touches one foot's columns at most)
    n_rho = tau_map.shape[1]
    for a in range(n_rho):
        for b in range(n_rho):
            r_rr[a, b] = 0.0
    nz = np.empty(n_rho, dtype=np.int64)
    for i in range(6, nv):
        k = 0
        for a in range(n_rho):
            if tau_map[i, a] != 0.0:
                nz[k] = a
                k += 1
        for ia in range(k):
            a = nz[ia]
            ta = tau_map[i, a]
            for ib in range(ia, k):
                r_rr[a, nz[ib]] += ta * tau_map[i, nz[ib]]
    for a in range(n_rho):
        for b in range(a, n_rho):
            r_rr[a, b] = lambda_tau * r_rr[a, b]
            r_rr[b, a] = r_rr[a, b]
        r_rr[a, a] += lambda_rho


@njit(cache=False, nogil=True)
def torques_reference(mass_matrix, nle, tau_map, rho, qdd, damping):  # noqa: ANN001, ANN201
    """Eq. 15: the base rows solved for q̈_base (6×6 Cholesky of M's base block), written into
    ``qdd[:6]``; returns (τ, base rows' right-hand side, −Σ J_cᵀ f_c) with τ = M_j q̈ + h_j − Σ J_c,jᵀ f_c
    + ``damping`` (the model's viscous joint torque, already multiplied by q̇_j; zeros when the model
    has none). τ is empty when the base block is not positive definite: the caller solves it (LU)."""
    nv = mass_matrix.shape[0]
    n_rho = rho.shape[0]
    gen = np.empty(nv)  # −Σ J_cᵀ f_c
    for i in range(nv):
        acc = 0.0
        for k in range(n_rho):
            acc += tau_map[i, k] * rho[k]
        gen[i] = acc
    rhs = np.empty(6)
    for r in range(6):
        acc = 0.0
        for j in range(6, nv):
            acc += mass_matrix[r, j] * qdd[j]
        rhs[r] = -acc - nle[r] - gen[r]
    low = np.zeros((6, 6))  # Cholesky factor of M[:6, :6]
    ok = True
    for i in range(6):
        for j in range(i + 1):
            acc = mass_matrix[i, j]
            for k in range(j):
                acc -= low[i, k] * low[j, k]
            if i == j:
                if acc <= 0.0:
                    ok = False
                    break
                low[i, i] = math.sqrt(acc)
            else:
                low[i, j] = acc / low[j, j]
        if not ok:
            break
    if ok:
        y = np.empty(6)
        for i in range(6):
            acc = rhs[i]
            for k in range(i):
                acc -= low[i, k] * y[k]
            y[i] = acc / low[i, i]
        for i in range(5, -1, -1):
            acc = y[i]
            for k in range(i + 1, 6):
                acc -= low[k, i] * qdd[k]
            qdd[i] = acc / low[i, i]
    else:  # the caller solves with LU (numba's LAPACK binding would triple this kernel's compile time)
        return np.empty(0), rhs, gen
    tau = np.empty(nv - 6)
    for i in range(nv - 6):
        acc = 0.0
        for j in range(nv):
            acc += mass_matrix[6 + i, j] * qdd[j]
        tau[i] = acc + nle[6 + i] + gen[6 + i] + damping[i]
    return tau, rhs, gen


@njit(cache=False, nogil=True)
def _cholesky_block_reference(h, lo, hi, low):  # noqa: ANN001, ANN202
    """Lower Cholesky factor of ``h[lo:hi, lo:hi]`` into ``low[lo:hi, lo:hi]``; False unless positive definite."""
    for i in range(lo, hi):
        for j in range(lo, i + 1):
            acc = h[i, j]
            for k in range(lo, j):
                acc -= low[i, k] * low[j, k]
            if i == j:
                if not acc > 0.0:
                    return False
                low[i, i] = math.sqrt(acc)
            else:
                low[i, j] = acc / low[j, j]
    return True


@njit(cache=False, nogil=True)
def _forward_reference(low, rhs, out, lo, hi, start):  # noqa: ANN001, ANN202
    """``out[lo:hi] = L[lo:hi, lo:hi]⁻¹ rhs[lo:hi]`` with ``rhs`` zero before ``start`` (out is 0 there)."""
    for i in range(lo, start):
        out[i] = 0.0
    for i in range(start, hi):
        acc = rhs[i]
        for k in range(start, i):
            acc -= low[i, k] * out[k]
        out[i] = acc / low[i, i]


@njit(cache=False, nogil=True)
def _map_row_reference(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, low, row, out):  # noqa: ANN001, ANN202
    """m = L⁻¹ aᵢ into ``out`` (block by block); returns ‖m‖."""
    start = _row(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, row)
    _forward_reference(low, row, out, 0, nv, min(start, nv))
    _forward_reference(low, row, out, nv, n, max(start, nv))
    acc = 0.0
    for j in range(n):
        acc += out[j] * out[j]
    return math.sqrt(acc)


@njit(cache=False, nogil=True)
def solve_centroidal_qp_reference(p_qq, c_q, r_rr, a_h, g_rho, b, qdd_lo, qdd_up, rho_up, tau_qdd, tau_rho, tau_bias, tau_lo,
                        tau_up, rho_idx, ws_index, ws_upper, n_warm, max_iter, x, qdd, rho):  # noqa: ANN001, ANN201, PLR0912, PLR0915
    """Solve the QP over x = [q̈; ρ[rho_idx]] into ``x`` (n = nv + len(rho_idx)); see the module docstring.
    On success also q̈ into ``qdd`` (nv) and every corner's ρ into ``rho`` (32: 0 off contact, the others
    clipped into their bounds, as :class:`engine.control.wbc.qp.DaqpQpSolver` returns them).

    Constraints are numbered as in DAQP's form (:func:`engine.control.wbc.kernels.fill_daqp`): the n simple
    bounds (the base's six are free), the six centroidal equalities, the torque rows. ``ws_index[:n_warm]``
    / ``ws_upper[:n_warm]``: the warm working set's inequality constraints and their sides (upper bound when
    True), overwritten with the final one. Returns (outcome, iterations, size of the final working set)."""
    nv = p_qq.shape[0]
    n_r = rho_idx.shape[0]
    n = nv + n_r
    n_tau = tau_qdd.shape[0]
    n_con = n + 6 + n_tau
    # ---- H = L Lᵀ block by block; v = L⁻¹ f (f = [c; 0])
    low = np.zeros((n, n))
    h_r = np.empty((n, n))  # only its R block is read
    for i in range(n_r):
        for j in range(n_r):
            h_r[nv + i, nv + j] = r_rr[rho_idx[i], rho_idx[j]]
    if not (_cholesky_block_reference(p_qq, 0, nv, low) and _cholesky_block_reference(h_r, nv, n, low)):
        return QP_NOT_CONVEX, 0, n_warm
    f = np.zeros(n)
    for j in range(nv):
        f[j] = c_q[j]
    v = np.zeros(n)
    _forward_reference(low, f, v, 0, nv, 0)
    # ---- bounds of every constraint and their normalisation (1/‖L⁻¹aᵢ‖, computed when needed)
    lower = np.empty(n_con)
    upper = np.empty(n_con)
    for j in range(6):
        lower[j], upper[j] = -1e20, 1e20
    for j in range(nv - 6):
        lower[6 + j], upper[6 + j] = qdd_lo[j], qdd_up[j]
    for j in range(n_r):
        lower[nv + j], upper[nv + j] = 0.0, rho_up[rho_idx[j]]
    for r in range(6):
        lower[n + r] = upper[n + r] = b[r]
    for r in range(n_tau):
        lower[n + 6 + r] = tau_lo[r] - tau_bias[r]
        upper[n + 6 + r] = tau_up[r] - tau_bias[r]
    norm = np.full(n_con, -1.0)
    # ---- the working set: normalised rows m̂, their right-hand sides d̂, Gram matrix, multipliers
    k_max = n + 1
    w_idx = np.empty(k_max, dtype=np.int64)
    w_up = np.empty(k_max, dtype=np.bool_)
    m_hat = np.empty((k_max, n))
    d_hat = np.empty(k_max)
    gram = np.empty((k_max, k_max))
    chol = np.empty((k_max, k_max))
    lam = np.zeros(k_max)
    lam_star = np.empty(k_max)
    in_ws = np.zeros(n_con, dtype=np.bool_)
    row = np.empty(n)
    m_vec = np.empty(n)
    k = 0
    # Warm rows first, then the equalities (in constraint order, as DAQP activates them).
    start_up = np.zeros(n_con, dtype=np.int8)  # 0: not in the start set, 1: lower side, 2: upper side
    for p in range(n_warm):
        i = ws_index[p]
        if 6 <= i < n_con and not (n <= i < n + 6):
            start_up[i] = 2 if ws_upper[p] else 1
    for i in range(n, n + 6):
        start_up[i] = 2
    for i in range(n_con):
        if start_up[i] == 0:
            continue
        if k >= k_max:
            return QP_SINGULAR, 0, 0
        nrm = _map_row_reference(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, low, row, m_vec)
        if not nrm > 0.0:
            return QP_SINGULAR, 0, 0
        norm[i] = nrm
        side_up = start_up[i] == 2
        bound = upper[i] if side_up else lower[i]
        mv = 0.0
        for j in range(n):
            m_hat[k, j] = m_vec[j] / nrm
            mv += m_vec[j] * v[j]
        d_hat[k] = (bound + mv) / nrm
        for p in range(k):
            acc = 0.0
            for j in range(n):
                acc += m_hat[p, j] * m_hat[k, j]
            gram[p, k] = gram[k, p] = acc
        acc = 0.0
        for j in range(n):
            acc += m_hat[k, j] * m_hat[k, j]
        gram[k, k] = acc
        w_idx[k], w_up[k], lam[k] = i, side_up, 0.0
        in_ws[i] = True
        k += 1
    u = np.empty(n)
    diff = np.empty(n)
    outcome = QP_ITERATION_LIMIT
    it = 0
    while it < max_iter:
        it += 1
        # ---- λ* on the working set: Cholesky of the Gram matrix, G λ* = −d̂
        for i in range(k):
            for j in range(i + 1):
                acc = gram[i, j]
                for p in range(j):
                    acc -= chol[i, p] * chol[j, p]
                if i == j:
                    if not acc > SINGULAR_TOL:
                        outcome = QP_SINGULAR
                        break
                    chol[i, i] = math.sqrt(acc)
                else:
                    chol[i, j] = acc / chol[j, j]
            if outcome == QP_SINGULAR:
                break
        if outcome == QP_SINGULAR:
            break
        for i in range(k):
            lam_star[i] = -d_hat[i]
        _gram_solve(chol, lam_star, k)
        # ---- a multiplier of the wrong sign: step towards λ* until the first reaches zero, drop that row
        alpha, block = math.inf, -1
        for p in range(k):
            i = w_idx[p]
            if n <= i < n + 6:
                continue  # equalities: any sign
            if w_up[p]:
                if lam_star[p] > -DUAL_TOL:
                    continue
            elif lam_star[p] < DUAL_TOL:
                continue
            cand = -lam[p] / (lam_star[p] - lam[p])
            if cand < alpha:
                alpha, block = cand, p
        if block >= 0:
            for p in range(k):
                lam[p] += alpha * (lam_star[p] - lam[p])
            in_ws[w_idx[block]] = False
            for p in range(block, k - 1):
                w_idx[p], w_up[p], lam[p], d_hat[p] = w_idx[p + 1], w_up[p + 1], lam[p + 1], d_hat[p + 1]
                for j in range(n):
                    m_hat[p, j] = m_hat[p + 1, j]
            for p in range(block, k - 1):
                for q in range(k):
                    gram[p, q] = gram[p + 1, q]
            for q in range(block, k - 1):
                for p in range(k - 1):
                    gram[p, q] = gram[p, q + 1]
            k -= 1
            continue
        # ---- dual feasible: λ = λ*, the primal point, the most violated constraint outside the set
        for p in range(k):
            lam[p] = lam_star[p]
        for j in range(n):
            u[j] = 0.0
        for p in range(k):
            lp = lam[p]
            for j in range(n):
                u[j] -= m_hat[p, j] * lp
        for j in range(n):
            diff[j] = u[j] - v[j]
        _backward(low, diff, x, 0, nv)
        _backward(low, diff, x, nv, n)
        worst, worst_i, worst_up = PRIMAL_TOL, -1, False
        for i in range(6, n_con):
            if in_ws[i] or (n <= i < n + 6):
                continue
            if i < n:
                value = x[i]
            else:
                r = i - n - 6
                value = 0.0
                for j in range(nv):
                    value += tau_qdd[r, j] * x[j]
                for j in range(n_r):
                    value += tau_rho[r, rho_idx[j]] * x[nv + j]
            over_up = value - upper[i]
            over_lo = lower[i] - value
            if over_up <= 0.0 and over_lo <= 0.0:
                continue
            if norm[i] < 0.0:
                norm[i] = _map_row_reference(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, low, row, m_vec)
            if over_up / norm[i] > worst:
                worst, worst_i, worst_up = over_up / norm[i], i, True
            elif over_lo / norm[i] > worst:
                worst, worst_i, worst_up = over_lo / norm[i], i, False
        if worst_i < 0:
            # One step of iterative refinement: the working set's rows hold to rounding (M̂_W u = d̂_W)
            # however ill-conditioned its Gram matrix (a tight torque row next to the dynamics).
            for p in range(k):
                acc = d_hat[p]
                for j in range(n):
                    acc -= m_hat[p, j] * u[j]
                lam_star[p] = acc  # the residual r
            for i in range(k):  # G δ = −r
                lam_star[i] = -lam_star[i]
            _gram_solve(chol, lam_star, k)
            for p in range(k):
                dp = lam_star[p]
                for j in range(n):
                    u[j] -= m_hat[p, j] * dp
            for j in range(n):
                diff[j] = u[j] - v[j]
            _backward(low, diff, x, 0, nv)
            _backward(low, diff, x, nv, n)
            outcome = QP_OPTIMAL
            break
        if k >= k_max:
            outcome = QP_SINGULAR
            break
        nrm = _map_row_reference(worst_i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, low, row, m_vec)
        bound = upper[worst_i] if worst_up else lower[worst_i]
        mv = 0.0
        for j in range(n):
            m_hat[k, j] = m_vec[j] / nrm
            mv += m_vec[j] * v[j]
        d_hat[k] = (bound + mv) / nrm
        for p in range(k + 1):
            acc = 0.0
            for j in range(n):
                acc += m_hat[p, j] * m_hat[k, j]
            gram[p, k] = gram[k, p] = acc
        w_idx[k], w_up[k], lam[k] = worst_i, worst_up, 0.0
        in_ws[worst_i] = True
        k += 1
    # ---- the working set's inequalities for the next solve
    n_out = 0
    if outcome == QP_OPTIMAL:
        total = 0.0
        for j in range(n):
            total += x[j]
        if not math.isfinite(total):
            return QP_NOT_CONVEX, it, 0
        for j in range(nv):
            qdd[j] = x[j]
        for j in range(rho.shape[0]):
            rho[j] = 0.0
        for j in range(n_r):
            rho[rho_idx[j]] = min(max(x[nv + j], 0.0), rho_up[rho_idx[j]])
        for p in range(k):
            i = w_idx[p]
            if n <= i < n + 6:
                continue
            ws_index[n_out], ws_upper[n_out] = i, w_up[p]
            n_out += 1
    return outcome, it, n_out



# ----------------------------------------------------------------------------- recorded whole-body ticks

from dataclasses import replace  # noqa: E402

from engine.control.controller import RobotState  # noqa: E402
from engine.control.wbc import TaskSpaceInverseDynamics, WbcGains, WbcReference  # noqa: E402
from engine.control.wbc import kernels  # noqa: E402
from engine.control.wbc.active_set import solve_centroidal_qp  # noqa: E402
from engine.gait.style import StyleContext  # noqa: E402
from engine.robot.model import load_robot  # noqa: E402
from tests.control.test_wbc_active_set import _golden_ticks, _perturbed_ticks  # noqa: E402


def _bits(a: np.ndarray) -> np.ndarray:
    """An array's bit patterns (signed zeros and NaN payloads count)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and bool(np.array_equal(_bits(a), _bits(b)))


def _controllers(name: str, tight: bool) -> tuple[TaskSpaceInverseDynamics, list[tuple[RobotState, WbcReference]]]:
    robot = load_robot(name)
    gains = WbcGains.for_robot(robot)
    if tight:  # torque rows in the working set: more iterations, rows added and dropped
        gains = replace(gains, torque_limit_fraction=0.2)
    wbc = TaskSpaceInverseDynamics(robot, gains, upper_body_joints=StyleContext.for_robot(name).upper_joints)
    ticks = _golden_ticks() if name == "g1" and not tight else _perturbed_ticks(wbc, 24)
    return wbc, ticks


CASES = [("g1", False), ("g1", True), ("talos", True)]


@pytest.mark.parametrize(("name", "tight"), CASES)
def test_assemble_qp_equals_its_reference(name: str, tight: bool) -> None:
    wbc, ticks = _controllers(name, tight)
    wbc.reset(ticks[0][0])
    checked = 0
    for state, ref in ticks:
        wbc.compute(state, ref)
        if wbc.qp is None or not wbc.diagnostics.ok:
            continue
        snap = wbc._snapshot.compute(np.asarray(state.q, float), np.asarray(state.v, float))  # this tick's again
        p = wbc._build_params
        nv, n_rho = wbc.nv, wbc.n_rho
        out = [np.empty((nv, nv)), np.empty(nv), np.empty((n_rho, n_rho)), np.empty((6, n_rho)),
               np.empty((nv, n_rho)), np.empty((2, 3, 4)), np.empty((2, 3, 4))]
        ref_out = [np.empty_like(a) for a in out]
        args = (wbc._jac, wbc._w, wbc._rhs, p[0], snap.frame_rotation, snap.frame_position_m, wbc._corner_offsets_t,
                snap.com_m, wbc._basis_xy, p[1], snap.frame_jacobian, p[2], p[3])
        kernels.assemble_qp(*args, *out)
        assemble_qp_reference(*args, *ref_out)
        for a, b in zip(out, ref_out):
            assert _same(a, b)
        assert _same(out[0], wbc.qp.p_qq) and _same(out[2], wbc.qp.r_rr)  # and the controller's QP
        checked += 1
    assert checked >= 10


@pytest.mark.parametrize(("name", "tight"), CASES)
def test_active_set_equals_its_reference(name: str, tight: bool) -> None:
    """Cold, warm from the previous tick's working set, and warm from another tick's (rows to drop)."""
    wbc, ticks = _controllers(name, tight)
    wbc.reset(ticks[0][0])
    qps = []
    for state, ref in ticks:
        wbc.compute(state, ref)
        if wbc.qp is not None and wbc.diagnostics.status != "fallback_no_contact":
            qps.append(wbc.qp)
    size = wbc.nv + wbc.n_rho + 6 + wbc.n_joints
    warm: dict[int, tuple[np.ndarray, np.ndarray, int]] = {}
    changed = iterated = 0
    for k, qp in enumerate(qps):
        rho_idx = np.flatnonzero(qp.rho_up > 0.0).astype(np.int64)
        previous = warm.get(rho_idx.size, (np.zeros(size, np.int64), np.zeros(size, np.bool_), 0))
        other = warm.get(int(np.flatnonzero(qps[k // 2].rho_up > 0.0).size), previous)  # possibly a stale set
        for start in ((np.zeros(size, np.int64), np.zeros(size, np.bool_), 0), previous, other):
            results = []
            for solve in (solve_centroidal_qp, solve_centroidal_qp_reference):
                index, upper = start[0].copy(), start[1].copy()
                n = wbc.nv + rho_idx.size
                x, qdd, rho = np.full(n, 7.0), np.full(wbc.nv, 7.0), np.full(wbc.n_rho, 7.0)
                outcome, iterations, n_out = solve(
                    qp.p_qq, qp.c_q, qp.r_rr, qp.a_h, qp.g_rho, qp.b, qp.qdd_joint_lo, qp.qdd_joint_up, qp.rho_up,
                    qp.tau_qdd, qp.tau_rho, qp.tau_bias, qp.tau_lo, qp.tau_up, rho_idx, index, upper, start[2],
                    500, x, qdd, rho)
                results.append((outcome, iterations, n_out, index[:n_out], upper[:n_out], x, qdd, rho))
            new, old = results
            assert new[:3] == old[:3]
            assert np.array_equal(new[3], old[3]) and np.array_equal(new[4], old[4])
            for a, b in zip(new[5:], old[5:]):
                assert _same(a, b)
            changed += new[2] != start[2]
            iterated += new[1] > 1
            if start is previous and new[0] == QP_OPTIMAL:
                warm[rho_idx.size] = (np.pad(new[3], (0, size - new[2])), np.pad(new[4], (0, size - new[2])), new[2])
    assert changed > 0 and iterated > 0  # working sets that grew or shrank, solves of several iterations


@pytest.mark.parametrize(("name", "tight"), CASES)
def test_one_call_tick_equals_the_step_by_step_path(name: str, tight: bool) -> None:
    one, ticks = _controllers(name, tight)
    steps, _ = _controllers(name, tight)
    steps.one_call = False
    one.reset(ticks[0][0])
    steps.reset(ticks[0][0])
    for state, ref in ticks:
        a, b = one.compute(state, ref), steps.compute(state, ref)
        for field in ("q_des", "qd_des", "tau_ff", "kp", "kd"):
            assert _same(getattr(a, field), getattr(b, field)), field
        da, db = one.diagnostics, steps.diagnostics
        assert (da.status, da.message, da.backend, da.qp_iterations) == (db.status, db.message, db.backend,
                                                                          db.qp_iterations)
        for field in ("qdd", "rho", "tau_nm", "basis", "corners_m", "horizontal_force_n"):
            x, y = getattr(da, field), getattr(db, field)
            assert (x is None) == (y is None) and (x is None or _same(x, y)), field
        if da.qp is not None:
            for field in ("p_qq", "c_q", "r_rr", "g_rho", "b", "qdd_joint_lo", "qdd_joint_up", "rho_up",
                          "tau_bias"):
                assert _same(getattr(da.qp, field), getattr(db.qp, field)), field


def test_factor_and_forward_substitution_equal_their_references() -> None:
    """Two rows at a time, the same numbers: random SPD blocks of odd and even sizes at offsets, and the
    substitution from every start (the zeros before it), and a block that is not positive definite."""
    from engine.control.wbc.active_set import _cholesky_block, _forward

    rng = np.random.default_rng(7)
    for trial in range(300):
        n = int(rng.integers(1, 70))
        lo = int(rng.integers(0, min(n, 5)))
        a = rng.normal(size=(n, n))
        h = a @ a.T + rng.random() * np.eye(n)
        if trial % 10 == 0:  # not positive definite: both stop, at the same row
            h[n - 1, n - 1] = -1.0
        low, low_ref = np.zeros((n, n)), np.zeros((n, n))
        ok = _cholesky_block(h, lo, n, low)
        assert ok == _cholesky_block_reference(h, lo, n, low_ref)
        if not ok:
            continue
        assert _same(low, low_ref)
        rhs = rng.normal(size=n)
        for start in range(lo, n + 1):
            rhs_s = rhs.copy()
            rhs_s[:start] = 0.0
            out, out_ref = np.full(n, 3.0), np.full(n, 3.0)
            _forward(low, rhs_s, out, lo, n, start)
            _forward_reference(low, rhs_s, out_ref, lo, n, start)
            assert _same(out, out_ref)


@pytest.mark.parametrize(("name", "tight"), CASES)
def test_torques_equal_their_reference(name: str, tight: bool) -> None:
    """Eq. 15's torques of recorded solutions (and of random accelerations, odd and even row counts)."""
    wbc, ticks = _controllers(name, tight)
    wbc.reset(ticks[0][0])
    rng = np.random.default_rng(1)
    checked = 0
    for state, ref in ticks:
        wbc.compute(state, ref)
        d = wbc.diagnostics
        if not d.ok:
            continue
        snap = wbc._snapshot.compute(np.asarray(state.q, float), np.asarray(state.v, float))
        damping = rng.normal(size=wbc.n_joints)
        for qdd in (d.qdd, rng.normal(size=wbc.nv)):
            a, b = qdd.copy(), qdd.copy()
            new = kernels.torques(snap.mass_matrix, snap.nonlinear_effects, wbc._tau_map, d.rho, a, damping)
            old = torques_reference(snap.mass_matrix, snap.nonlinear_effects, wbc._tau_map, d.rho, b, damping)
            assert _same(a, b) and all(_same(x, y) for x, y in zip(new, old))
        checked += 1
    assert checked >= 10
    for rows in (7, 8):  # odd and even joint rows
        m = rng.normal(size=(rows, rows))
        m = m @ m.T + np.eye(rows)
        tau_map, rho, qdd, damping = (rng.normal(size=(rows, 5)), rng.normal(size=5), rng.normal(size=rows),
                                      rng.normal(size=rows - 6))
        a, b = qdd.copy(), qdd.copy()
        new = kernels.torques(m, np.ones(rows), tau_map, rho, a, damping)
        old = torques_reference(m, np.ones(rows), tau_map, rho, b, damping)
        assert _same(a, b) and all(_same(x, y) for x, y in zip(new, old))


def test_numpy_sum_is_numpys_sum() -> None:
    """The compiled finiteness checks sum as numpy does (its pairwise summation), bit for bit: any length (the
    eight running sums from 8 terms, the halves above 128), magnitudes over six decades, signed zeros."""
    rng = np.random.default_rng(11)
    for n in list(range(0, 140)) + [200, 257, 300]:
        for _ in range(5):
            a = rng.normal(size=n) * 10.0 ** rng.uniform(-3, 3, size=n)
            assert _same(np.array([kernels.numpy_sum(a)]), np.array([a.sum()]))
            b = rng.normal(size=n + 1)
            assert _same(np.array([kernels.state_sum(a, b)]), np.array([a.sum() + b.sum()]))
    for n in (0, 1, 7, 8, 9, 16, 130, 300):
        for zeros in (np.full(n, -0.0), np.zeros(n)):
            assert _same(np.array([kernels.numpy_sum(zeros)]), np.array([zeros.sum()]))
    assert not math.isfinite(kernels.numpy_sum(np.array([1e308] * 9)))  # overflows as numpy's does
