"""The whole-body QP (:class:`engine.control.wbc.qp.CentroidalQp`) by a compiled dual active set that knows
its structure (numba).

The QP over x = [q̈ (nv); ρ of the corners in contact (n_ρ)] has a block-diagonal Hessian H = diag(P, R),
simple bounds (q̈ joint limits, 0 ≤ ρ ≤ ρ_max), the six centroidal equalities and one two-sided row per
joint torque. DAQP (the reference, :class:`engine.control.wbc.qp.DaqpQpSolver`) solves the same problem
in its least-distance form, u = Lᵀx + L⁻¹f with H = L Lᵀ, min ½‖u‖² s.t. m̂ᵢᵀu ≤ d̂ᵢ, every row
normalised (m̂ᵢ = L⁻¹aᵢ / ‖L⁻¹aᵢ‖), but it factorises the whole (nv + n_ρ)² Hessian, inverts the factor
and maps every row through it each tick (≈ 80 % of its time). Here:

* H's two blocks are factorised apart (P: nv × nv, R: n_ρ × n_ρ), and only the rows that enter the
  working set are mapped through L⁻¹ (a bound: one column of L⁻¹; a row: two triangular solves).
* Rows outside the working set are checked in the primal space, x = L⁻ᵀ(u − v): the violation of
  aᵢᵀx ≤ bᵢ, normalised by ‖L⁻¹aᵢ‖ (computed for the violated rows only), is DAQP's slack.
* The dual active set takes DAQP's steps (Goldfarb–Idnani in the least-distance form): solve the working
  set's equalities for the multipliers λ*; if one has the wrong sign, step the multipliers towards λ*
  until the first reaches zero and drop that row; else add the most violated row (normalised violation
  above ``PRIMAL_TOL``, DAQP's default primal tolerance). The working set's Gram matrix M̂_W M̂_Wᵀ is
  kept and refactorised (Cholesky, ≤ a few dozen rows) after each change.
* The working set starts from the previous solve's (one per n_ρ, as DAQP keeps one workspace per size).

The optimum is unique (H ≻ 0), so the solution equals DAQP's to rounding when both stop on the same
active set (``tests/control/test_wbc_active_set.py``). A singular working set (a row dependent on the
others), a factor that is not positive definite or the iteration cap returns a failure: the caller then
runs DAQP.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: DAQP's default tolerances: normalised primal violation, dual sign, singular working set.
PRIMAL_TOL = 1e-6
DUAL_TOL = 1e-12
SINGULAR_TOL = 1e-10
#: Outcomes of :func:`solve_centroidal_qp`.
QP_OPTIMAL, QP_NOT_CONVEX, QP_SINGULAR, QP_ITERATION_LIMIT = 0, 1, 2, 3


@njit(cache=True, nogil=True)
def _cholesky_block(h, lo, hi, low):  # noqa: ANN001, ANN202
    """Lower Cholesky factor of ``h[lo:hi, lo:hi]`` into ``low[lo:hi, lo:hi]``; False unless positive definite.

    Rows two at a time: each entry's sum runs in the same order as row by row (the same numbers), the two
    rows' sums side by side (a sum is a chain of dependent subtractions: two chains keep the core busy)."""
    i = lo
    while i < hi:
        if i + 1 == hi:  # the last row alone
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
        i2 = i + 1
        for j in range(lo, i + 1):
            acc = h[i, j]
            acc2 = h[i2, j]
            for k in range(lo, j):
                ljk = low[j, k]
                acc -= low[i, k] * ljk
                acc2 -= low[i2, k] * ljk
            if i == j:
                if not acc > 0.0:
                    return False
                low[i, i] = math.sqrt(acc)
            else:
                low[i, j] = acc / low[j, j]
            low[i2, j] = acc2 / low[j, j]
        acc = h[i2, i2]
        for k in range(lo, i2):
            acc -= low[i2, k] * low[i2, k]
        if not acc > 0.0:
            return False
        low[i2, i2] = math.sqrt(acc)
        i += 2
    return True


@njit(cache=True, nogil=True)
def _forward(low, rhs, out, lo, hi, start):  # noqa: ANN001, ANN202
    """``out[lo:hi] = L[lo:hi, lo:hi]⁻¹ rhs[lo:hi]`` with ``rhs`` zero before ``start`` (out is 0 there).
    Rows two at a time (as :func:`_cholesky_block`: each row's sum in its order, two sums side by side)."""
    for i in range(lo, start):
        out[i] = 0.0
    i = start
    while i + 1 < hi:
        i2 = i + 1
        acc = rhs[i]
        acc2 = rhs[i2]
        for k in range(start, i):
            ok = out[k]
            acc -= low[i, k] * ok
            acc2 -= low[i2, k] * ok
        out[i] = acc / low[i, i]
        acc2 -= low[i2, i] * out[i]
        out[i2] = acc2 / low[i2, i2]
        i += 2
    if i < hi:
        acc = rhs[i]
        for k in range(start, i):
            acc -= low[i, k] * out[k]
        out[i] = acc / low[i, i]


@njit(cache=True, nogil=True)
def _backward(low, rhs, out, lo, hi):  # noqa: ANN001, ANN202
    """``out[lo:hi] = L[lo:hi, lo:hi]⁻ᵀ rhs[lo:hi]``."""
    for i in range(hi - 1, lo - 1, -1):
        acc = rhs[i]
        for k in range(i + 1, hi):
            acc -= low[k, i] * out[k]
        out[i] = acc / low[i, i]


@njit(cache=True, nogil=True)
def _gram_solve(chol, x, k):  # noqa: ANN001, ANN202
    """x[:k] ← G⁻¹ x[:k] in place, G = L Lᵀ with L = chol[:k, :k] (forward, then backward substitution)."""
    for i in range(k):
        acc = x[i]
        for p in range(i):
            acc -= chol[i, p] * x[p]
        x[i] = acc / chol[i, i]
    for i in range(k - 1, -1, -1):
        acc = x[i]
        for p in range(i + 1, k):
            acc -= chol[p, i] * x[p]
        x[i] = acc / chol[i, i]


@njit(cache=True, nogil=True)
def _row(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, out):  # noqa: ANN001, ANN202
    """Constraint ``i``'s row aᵢ over x: a unit vector (bounds, i < n), a centroidal row [A_h, −G] (the next
    six) or a torque row [M_j, T] (the rest). Returns the index of its first non-zero entry."""
    if i < n:
        for j in range(n):
            out[j] = 0.0
        out[i] = 1.0
        return i
    r = i - n
    if r < 6:
        for j in range(nv):
            out[j] = a_h[r, j]
        for j in range(n - nv):
            out[nv + j] = -g_rho[r, rho_idx[j]]
    else:
        r -= 6
        for j in range(nv):
            out[j] = tau_qdd[r, j]
        for j in range(n - nv):
            out[nv + j] = tau_rho[r, rho_idx[j]]
    return 0


@njit(cache=True, nogil=True)
def _mapped_range(i, n, nv):  # noqa: ANN001, ANN202
    """The columns of L⁻¹aᵢ that can be non-zero: a bound on q̈ᵢ, [i, nv) (L is block-diagonal; the ρ block
    comes out +0 exactly); a bound on ρ, [i, n); a row, all. Sums over them skip only exact zeros, which leave
    a sum begun at +0 unchanged bit for bit (finite terms)."""
    if i < nv:
        return i, nv
    if i < n:
        return i, n
    return 0, n


@njit(cache=True, nogil=True)
def _map_row(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, low, row, out):  # noqa: ANN001, ANN202
    """m = L⁻¹ aᵢ into ``out`` (block by block); returns ‖m‖."""
    start = _row(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, row)
    _forward(low, row, out, 0, nv, min(start, nv))
    _forward(low, row, out, nv, n, max(start, nv))
    acc = 0.0
    for j in range(n):
        acc += out[j] * out[j]
    return math.sqrt(acc)


@njit(cache=True, nogil=True)
def solve_centroidal_qp(p_qq, c_q, r_rr, a_h, g_rho, b, qdd_lo, qdd_up, rho_up, tau_qdd, tau_rho, tau_bias, tau_lo,
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
    if not (_cholesky_block(p_qq, 0, nv, low) and _cholesky_block(h_r, nv, n, low)):
        return QP_NOT_CONVEX, 0, n_warm
    f = np.zeros(n)
    for j in range(nv):
        f[j] = c_q[j]
    v = np.zeros(n)
    _forward(low, f, v, 0, nv, 0)
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
    m_lo = np.empty(k_max, dtype=np.int64)  # the columns of m̂ that can be non-zero (_mapped_range)
    m_hi = np.empty(k_max, dtype=np.int64)
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
        nrm = _map_row(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, low, row, m_vec)
        if not nrm > 0.0:
            return QP_SINGULAR, 0, 0
        norm[i] = nrm
        side_up = start_up[i] == 2
        bound = upper[i] if side_up else lower[i]
        lo_k, hi_k = _mapped_range(i, n, nv)
        m_lo[k], m_hi[k] = lo_k, hi_k
        mv = 0.0
        for j in range(n):
            m_hat[k, j] = m_vec[j] / nrm
        for j in range(lo_k, hi_k):
            mv += m_vec[j] * v[j]
        d_hat[k] = (bound + mv) / nrm
        for p in range(k + 1):
            acc = 0.0
            for j in range(max(m_lo[p], lo_k), min(m_hi[p], hi_k)):
                acc += m_hat[p, j] * m_hat[k, j]
            gram[p, k] = gram[k, p] = acc
        w_idx[k], w_up[k], lam[k] = i, side_up, 0.0
        in_ws[i] = True
        k += 1
    u = np.empty(n)
    diff = np.empty(n)
    outcome = QP_ITERATION_LIMIT
    it = 0
    n_factored = 0  # leading rows of chol that factor the present Gram matrix (rows are added at the end)
    while it < max_iter:
        it += 1
        # ---- λ* on the working set: Cholesky of the Gram matrix, G λ* = −d̂ (row i of the factor depends on
        # G's rows ≤ i only: the rows still valid are not recomputed, the same numbers)
        for i in range(n_factored, k):
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
        n_factored = k
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
                m_lo[p], m_hi[p] = m_lo[p + 1], m_hi[p + 1]
                for j in range(n):
                    m_hat[p, j] = m_hat[p + 1, j]
            for p in range(block, k - 1):
                for q in range(k):
                    gram[p, q] = gram[p + 1, q]
            for q in range(block, k - 1):
                for p in range(k - 1):
                    gram[p, q] = gram[p, q + 1]
            k -= 1
            n_factored = min(n_factored, block)
            continue
        # ---- dual feasible: λ = λ*, the primal point, the most violated constraint outside the set
        for p in range(k):
            lam[p] = lam_star[p]
        for j in range(n):
            u[j] = 0.0
        for p in range(k):  # (u begins at +0 and is never −0: skipping m̂'s exact zeros leaves it bit for bit)
            lp = lam[p]
            for j in range(m_lo[p], m_hi[p]):
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
                norm[i] = _map_row(i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, low, row, m_vec)
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
                for j in range(m_lo[p], m_hi[p]):
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
        nrm = _map_row(worst_i, n, nv, a_h, g_rho, tau_qdd, tau_rho, rho_idx, low, row, m_vec)
        bound = upper[worst_i] if worst_up else lower[worst_i]
        lo_k, hi_k = _mapped_range(worst_i, n, nv)
        m_lo[k], m_hi[k] = lo_k, hi_k
        mv = 0.0
        for j in range(n):
            m_hat[k, j] = m_vec[j] / nrm
        for j in range(lo_k, hi_k):
            mv += m_vec[j] * v[j]
        d_hat[k] = (bound + mv) / nrm
        for p in range(k + 1):
            acc = 0.0
            for j in range(max(m_lo[p], lo_k), min(m_hi[p], hi_k)):
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
