"""Compiled (numba) kernels of the whole-body QP's assembly: the same numbers as the numpy code in
:meth:`engine.control.wbc.controller.TaskSpaceInverseDynamics._build_qp_numpy` (equal to rounding,
``tests/test_wbc_kernels.py``), in one call instead of ~40 small numpy operations per 500 Hz tick.

* :func:`assemble_qp` — the stacked tasks' normal equations (P = Jᵀ W J + λ I, c = −Jᵀ W r), the contact
  model (sole corners, friction-pyramid edges, Eq. 17), the centroidal map of ρ (Eq. 21), the
  τ̄ map −Σ J_footᵀ [f; m] per unit ρ and its regulariser R = λ_τ̄ T_jᵀ T_j + λ_ρ I.
* :func:`fill_daqp` — the QP in DAQP's dense form (Hessian, cost, rows, bounds) written into the
  solver's preallocated arrays.

Compiled on first use and cached on disk (``cache=True``: a fresh process loads the machine code
instead of compiling it again).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def assemble_qp(jac, w, rhs, lambda_qdd, rot, pos, offsets_t, com, basis_xy, basis_z, frame_jac,
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
        # τ̄ map of this side: −J_sᵀ wrench (nv, 16)
        for i in range(nv):
            for m in range(per_side):
                acc = 0.0
                for r in range(6):
                    acc += frame_jac[s, r, i] * wrench[r, m]
                tau_map[i, s * per_side + m] = -acc
    # ---- R = λ_τ̄ T_jᵀ T_j + λ_ρ I over the joint rows (6:) of the τ̄ map
    n_rho = tau_map.shape[1]
    for a in range(n_rho):
        for b in range(a, n_rho):
            acc = 0.0
            for i in range(6, nv):
                acc += tau_map[i, a] * tau_map[i, b]
            r_rr[a, b] = lambda_tau * acc
            r_rr[b, a] = r_rr[a, b]
        r_rr[a, a] += lambda_rho


@njit(cache=True, nogil=True)
def fill_daqp(p_qq, c_q, r_rr, a_h, g_rho, b, qdd_lo, qdd_up, rho_up, tau_qdd, tau_rho, tau_bias, tau_lo,
              tau_up, h, f, a, lo, up):  # noqa: ANN001, ANN201
    """The QP in DAQP's form, in place: H = diag(P, R), f = [c; 0], rows [A_h −G; M_j T] and bounds
    [free base; q̈ joint limits; 0 ≤ ρ ≤ ρ_max; b = b; τ_lo − h_j ≤ · ≤ τ_up − h_j]."""
    nv = p_qq.shape[0]
    n_rho = r_rr.shape[0]
    n = nv + n_rho
    n_tau = tau_qdd.shape[0]
    for i in range(nv):
        for j in range(nv):
            h[i, j] = p_qq[i, j]
        f[i] = c_q[i]
    for i in range(n_rho):
        for j in range(n_rho):
            h[nv + i, nv + j] = r_rr[i, j]
    for r in range(6):
        for j in range(nv):
            a[r, j] = a_h[r, j]
        for j in range(n_rho):
            a[r, nv + j] = -g_rho[r, j]
        lo[n + r] = b[r]
        up[n + r] = b[r]
    for r in range(n_tau):
        for j in range(nv):
            a[6 + r, j] = tau_qdd[r, j]
        for j in range(n_rho):
            a[6 + r, nv + j] = tau_rho[r, j]
        lo[n + 6 + r] = tau_lo[r] - tau_bias[r]
        up[n + 6 + r] = tau_up[r] - tau_bias[r]
    for j in range(nv - 6):
        lo[6 + j] = qdd_lo[j]
        up[6 + j] = qdd_up[j]
    for j in range(n_rho):
        lo[nv + j] = 0.0
        up[nv + j] = rho_up[j]
