"""Compiled (numba) kernels of the whole-body QP's assembly: the same numbers as the numpy code in
:meth:`engine.control.wbc.assembly_numpy.NumpyQpAssembly.build` (equal to rounding,
``tests/control/test_wbc_kernels.py``), in one call instead of ~40 small numpy operations per 500 Hz tick.

* :func:`assemble_qp` — the stacked tasks' normal equations (P = Jᵀ W J + λ I, c = −Jᵀ W r), the contact
  model (sole corners, friction-pyramid edges, Eq. 17), the centroidal map of ρ (Eq. 21), the
  τ̄ map −Σ J_footᵀ [f; m] per unit ρ and its regulariser R = λ_τ̄ T_jᵀ T_j + λ_ρ I.
* :func:`fill_daqp` — the QP in DAQP's dense form (Hessian, cost, rows, bounds) written into the
  solver's preallocated arrays.

* :func:`foot_frames` — the snapshot's feet (placements, Jacobians, classical accelerations) from pinocchio's
  joint-level results (:mod:`engine.control.wbc.snapshot`).
* :func:`solve_tick` — the default tick in one call: :func:`build_qp`, the compiled active set, :func:`finish_tick`.

Compiled on first use and cached on disk (``cache=True``: a fresh process loads the machine code
instead of compiling it again). numba keys a cached kernel on its own file only: after editing
:mod:`engine.control.wbc.active_set`, delete ``__pycache__/kernels.solve_tick*.nb[ic]`` (the one-call tick
inlines its solver).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.control.wbc.active_set import QP_OPTIMAL, solve_centroidal_qp

#: Outcomes of :func:`solve_tick`: solved (torques and set-points computed), a non-finite reference (nothing
#: written), no contact corner (the QP built, not solved), the compiled active set without a solution (the QP
#: built: the caller runs DAQP), solved but the base block of M not positive definite (the caller's LU), solved
#: with torques whose sum is not finite.
TICK_SOLVED, TICK_INVALID_REFERENCE, TICK_NO_CONTACT, TICK_NOT_SOLVED, TICK_BASE_NOT_PD, TICK_NONFINITE_TORQUES = (
    0, 1, 2, 3, 4, 5)


@njit(cache=True, nogil=True)
def _block_sum(a, lo, n):  # noqa: ANN001, ANN202
    """numpy's sum of at most 128 terms ``a[lo:lo + n]``: below 8 in order from 0.0, else eight running sums
    combined as ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7)), then the rest in order."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - (n % 8):
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True, nogil=True)
def _pairwise_sum(a, lo, n):  # noqa: ANN001, ANN202
    """numpy's sum of ``a[lo:lo + n]`` (its pairwise summation), the same number bit for bit: :func:`_block_sum`
    up to 128 terms, above that the sum of the two halves split at a multiple of 8 (numpy's recursion, walked
    with an explicit stack: numba's disk cache does not keep recursive functions)."""
    if n <= 128:
        return _block_sum(a, lo, n)
    starts, lengths = np.empty(64, dtype=np.int64), np.empty(64, dtype=np.int64)
    stage, left = np.zeros(64, dtype=np.int64), np.empty(64)
    top = 0
    starts[0], lengths[0] = lo, n
    ret = 0.0
    while top >= 0:
        m = lengths[top]
        half = m // 2
        half -= half % 8
        if stage[top] == 0:
            if m <= 128:  # a leaf: its sum goes to the parent
                ret = _block_sum(a, starts[top], m)
                top -= 1
                continue
            stage[top] = 1
            top += 1
            starts[top], lengths[top], stage[top] = starts[top - 1], half, 0
        elif stage[top] == 1:  # the left half's sum is in: the right half next
            left[top] = ret
            stage[top] = 2
            top += 1
            starts[top], lengths[top], stage[top] = starts[top - 1] + half, m - half, 0
        else:
            ret = left[top] + ret
            top -= 1
    return ret


@njit(cache=True, nogil=True)
def numpy_sum(a):  # noqa: ANN001, ANN201
    """``a.sum()`` of a 1-D float array, as numpy computes it: its reduction starts from 0.0 and adds the
    pairwise sum (:func:`_pairwise_sum`; the start matters for a sum of −0.0 only)."""
    return 0.0 + _pairwise_sum(a, 0, a.shape[0])


@njit(cache=True, nogil=True)
def state_sum(q, v):  # noqa: ANN001, ANN201
    """``q.sum() + v.sum()`` as numpy computes it (the controller's finiteness check of a state)."""
    return (0.0 + _pairwise_sum(q, 0, q.shape[0])) + (0.0 + _pairwise_sum(v, 0, v.shape[0]))


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
    nz = np.empty(nv, dtype=np.int64)  # the row's non-zero columns, in order (the same terms, in the same order)
    for r in range(n_rows):
        wr = w[r]
        if wr == 0.0:
            continue
        wrr = wr * rhs[r]
        k = 0
        for i in range(nv):
            if jac[r, i] != 0.0:
                nz[k] = i
                k += 1
        for ii in range(k):
            i = nz[ii]
            a = jac[r, i]
            wa = wr * a
            c_q[i] -= a * wrr
            for jj in range(ii, k):
                j = nz[jj]
                p_qq[i, j] += wa * jac[r, j]
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


@njit(cache=True, nogil=True)
def fill_daqp(p_qq, c_q, r_rr, a_h, g_rho, b, qdd_lo, qdd_up, rho_up, tau_qdd, tau_rho, tau_bias, tau_lo,
              tau_up, rho_idx, h, f, a, lo, up):  # noqa: ANN001, ANN201
    """The QP in DAQP's form, in place, over x = [q̈; ρ[rho_idx]] (the corners in contact: the others'
    weights are 0 and leave the problem): H = diag(P, R), f = [c; 0], rows [A_h −G; M_j T] and bounds
    [free base; q̈ joint limits; 0 ≤ ρ ≤ ρ_max; b = b; τ_lo − h_j ≤ · ≤ τ_up − h_j]."""
    nv = p_qq.shape[0]
    n_rho = rho_idx.shape[0]
    n = nv + n_rho
    n_tau = tau_qdd.shape[0]
    for i in range(nv):
        for j in range(nv):
            h[i, j] = p_qq[i, j]
        for j in range(n_rho):
            h[i, nv + j] = 0.0
            h[nv + j, i] = 0.0
        f[i] = c_q[i]
    for i in range(n_rho):
        for j in range(n_rho):
            h[nv + i, nv + j] = r_rr[rho_idx[i], rho_idx[j]]
        f[nv + i] = 0.0
    for r in range(6):
        for j in range(nv):
            a[r, j] = a_h[r, j]
        for j in range(n_rho):
            a[r, nv + j] = -g_rho[r, rho_idx[j]]
        lo[n + r] = b[r]
        up[n + r] = b[r]
    for r in range(n_tau):
        for j in range(nv):
            a[6 + r, j] = tau_qdd[r, j]
        for j in range(n_rho):
            a[6 + r, nv + j] = tau_rho[r, rho_idx[j]]
        lo[n + 6 + r] = tau_lo[r] - tau_bias[r]
        up[n + 6 + r] = tau_up[r] - tau_bias[r]
    for j in range(6):
        lo[j] = -1e20
        up[j] = 1e20
    for j in range(nv - 6):
        lo[6 + j] = qdd_lo[j]
        up[6 + j] = qdd_up[j]
    for j in range(n_rho):
        lo[nv + j] = 0.0
        up[nv + j] = rho_up[rho_idx[j]]


_EPS = float(np.finfo(np.float64).eps)
_PREC_2 = _EPS ** (1.0 / 3.0)  # pinocchio's TaylorSeriesExpansion<double>::precision<2>()


@njit(cache=True, nogil=True)
def _theta_axis(i0, val, rn):  # noqa: ANN001, ANN201
    """pinocchio's internal::compute_theta_axis (the θ ≈ π branch of log3)."""
    i1, i2 = (i0 + 1) % 3, (i0 + 2) % 3
    s = math.sqrt(val + _EPS + _EPS * _EPS) * (1.0 if rn[i2, i1] >= rn[i1, i2] else -1.0)
    axis = np.empty(3)
    axis[i0] = s / 2.0
    axis[i1] = 1.0 / (2.0 * s) * (rn[i1, i0] + rn[i0, i1])
    axis[i2] = 1.0 / (2.0 * s) * (rn[i2, i0] + rn[i0, i2])
    w = 1.0 / (2.0 * s) * (rn[i2, i1] - rn[i1, i2])
    norm = math.sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2])
    angle = 2.0 * math.atan2(norm, w)
    return angle, axis / norm


@njit(cache=True, nogil=True)
def log3(rot):  # noqa: ANN001, ANN201
    """pinocchio 3's ``log3`` (the same renormalisation, branches and series): the rotation vector of ``rot``."""
    rn = np.empty((3, 3))
    n0 = math.sqrt(rot[0, 0] ** 2 + rot[1, 0] ** 2 + rot[2, 0] ** 2)
    n1 = math.sqrt(rot[0, 1] ** 2 + rot[1, 1] ** 2 + rot[2, 1] ** 2)
    c0 = rot[:, 0] / n0
    c1 = rot[:, 1] / n1
    c2 = np.array([c0[1] * c1[2] - c0[2] * c1[1], c0[2] * c1[0] - c0[0] * c1[2], c0[0] * c1[1] - c0[1] * c1[0]])
    c0 = np.array([c1[1] * c2[2] - c1[2] * c2[1], c1[2] * c2[0] - c1[0] * c2[2], c1[0] * c2[1] - c1[1] * c2[0]])
    for i in range(3):
        rn[i, 0], rn[i, 1], rn[i, 2] = c0[i], c1[i], c2[i]
    tr = rn[0, 0] + rn[1, 1] + rn[2, 2]
    cos_value = (tr - 1.0) / 2.0
    prec = _PREC_2
    out = np.empty(3)
    if cos_value < -1.0 + prec:  # θ ≈ π
        v0, v1, v2 = 2.0 * rn[0, 0] - tr + 1.0, 2.0 * rn[1, 1] - tr + 1.0, 2.0 * rn[2, 2] - tr + 1.0
        if v0 >= v1:
            i0, val = (0, v0) if v0 >= v2 else (2, v2)
        else:
            i0, val = (1, v1) if v1 >= v2 else (2, v2)
        theta, axis = _theta_axis(i0, val, rn)
        for k in range(3):
            out[k] = theta * axis[k]
        return out
    acos_expansion = math.sqrt(2.0 * (1.0 - cos_value) + _EPS * _EPS)
    if tr <= 3.0 - prec:
        theta = math.acos(cos_value) if tr >= -1.0 + prec else math.pi - acos_expansion
    else:
        theta = acos_expansion
    a0, a1, a2 = 0.5 * (rn[2, 1] - rn[1, 2]), 0.5 * (rn[0, 2] - rn[2, 0]), 0.5 * (rn[1, 0] - rn[0, 1])
    if theta >= prec:
        t = theta / math.sin(theta)
    else:
        n2 = a0 * a0 + a1 * a1 + a2 * a2
        t = 1.0 + n2 / 6.0 + n2 * n2 * 3.0 / 40.0
    out[0], out[1], out[2] = t * a0, t * a1, t * a2
    return out


@njit(cache=True, nogil=True)
def _rotation_error(target, rot):  # noqa: ANN001, ANN201
    """log3(target · rotᵀ)."""
    prod = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            prod[i, j] = target[i, 0] * rot[j, 0] + target[i, 1] * rot[j, 1] + target[i, 2] * rot[j, 2]
    return log3(prod)


@njit(cache=True, nogil=True)
def task_rows(jac, rhs, w, gains, fill_constant, frame_pos, frame_rot, frame_jac, frame_vel, frame_drift, contact,
              foot_pos, foot_rot, foot_lin_vel, foot_ang_vel, foot_lin_acc, foot_ang_acc, base_rot, q, v,
              pelvis_height, pelvis_height_rate, pelvis_rot, pelvis_ang_vel, centroidal_map, centroidal_drift,
              momentum, com, mass, com_xy, com_xy_vel, com_xy_acc, com_z, upper_v_idx, upper_q_ref,
              upper_qd_ref):  # noqa: ANN001, ANN201
    """The stacked tasks' rows (Eq. 18) in place — J into ``jac``, a* − J̇ q̇ into ``rhs``, the per-tick
    weights into ``w`` — as the task objects of :mod:`engine.control.wbc.tasks` write them: feet
    (rows 0–11: damping only when flat on the ground, else PD on the planned pose), pelvis height and
    orientation, CoM, upper-body joints, angular-momentum damping. ``gains``: swing kp, kd, weight,
    contact kd, weight, pelvis height kp, kd, rotation kp, kd, CoM kp, kd, z weight, upper-body kp,
    kd, angular-momentum kd, swing rotation weight. ``com_z``: NaN when the CoM height is not tracked. The constant
    Jacobian rows (upper body) are written only when ``fill_constant``."""
    nv = jac.shape[1]
    swing_kp, swing_kd, swing_w, contact_kd, contact_w = gains[0], gains[1], gains[2], gains[3], gains[4]
    # ---- feet
    for s in range(2):
        flat = True
        touching = False
        for c in range(contact.shape[1]):
            if contact[s, c]:
                touching = True
            else:
                flat = False
        for r in range(6):
            for j in range(nv):
                jac[6 * s + r, j] = frame_jac[s, r, j]
        if flat:
            for r in range(6):
                w[6 * s + r] = contact_w
                rhs[6 * s + r] = (0.0 + contact_kd * (0.0 - frame_vel[s, r])) - frame_drift[s, r]
        else:
            err = _rotation_error(foot_rot[s], frame_rot[s])
            for r in range(6):
                w[6 * s + r] = contact_w if touching else (swing_w if r < 3 else gains[15])
                if r < 3:
                    vel, acc, e = foot_lin_vel[s, r], foot_lin_acc[s, r], foot_pos[s, r] - frame_pos[s, r]
                else:
                    vel, acc, e = foot_ang_vel[s, r - 3], foot_ang_acc[s, r - 3], err[r - 3]
                a = acc + swing_kd * (vel - frame_vel[s, r])
                if swing_kp != 0.0:
                    a += swing_kp * e
                rhs[6 * s + r] = a - frame_drift[s, r]
    # ---- pelvis: rows [z; ωx; ωy; ωz]
    r0 = 12
    for j in range(nv):
        for r in range(4):
            jac[r0 + r, j] = 0.0
    for k in range(3):
        jac[r0, k] = base_rot[2, k]
        for r in range(3):
            jac[r0 + 1 + r, 3 + k] = base_rot[r, k]
    vx, vy, vz, wx, wy, wz = v[0], v[1], v[2], v[3], v[4], v[5]
    rz = base_rot[2]
    height_rate = rz[0] * vx + rz[1] * vy + rz[2] * vz
    drift = rz[0] * (wy * vz - wz * vy) + rz[1] * (wz * vx - wx * vz) + rz[2] * (wx * vy - wy * vx)
    rhs[r0] = (0.0 + gains[5] * (pelvis_height - q[2]) + gains[6] * (pelvis_height_rate - height_rate)) - drift
    err = _rotation_error(pelvis_rot, base_rot)
    for r in range(3):
        omega = base_rot[r, 0] * wx + base_rot[r, 1] * wy + base_rot[r, 2] * wz
        rhs[r0 + 1 + r] = 0.0 + gains[7] * err[r] + gains[8] * (pelvis_ang_vel[r] - omega)
    # ---- CoM: rows [x; y; z]
    r0 = 16
    inv_m = 1.0 / mass
    for r in range(3):
        for j in range(nv):
            jac[r0 + r, j] = centroidal_map[r, j] * inv_m
        target = com_xy[r] if r < 2 else (0.0 if math.isnan(com_z) else com_z)
        target_vel = com_xy_vel[r] if r < 2 else 0.0
        target_acc = com_xy_acc[r] if r < 2 else 0.0
        lin = momentum[r] * inv_m
        rhs[r0 + r] = (target_acc + gains[9] * (target - com[r]) + gains[10] * (target_vel - lin)
                       - centroidal_drift[r] * inv_m)
    w[r0 + 2] = 0.0 if math.isnan(com_z) else gains[11]
    # ---- upper-body joints (J constant: one 1 per row)
    r0 = 19
    n_upper = upper_v_idx.shape[0]
    for r in range(n_upper):
        k = upper_v_idx[r]
        if fill_constant:
            for j in range(nv):
                jac[r0 + r, j] = 0.0
            jac[r0 + r, k] = 1.0
        rhs[r0 + r] = 0.0 + gains[12] * (upper_q_ref[r] - q[k + 1]) + gains[13] * (upper_qd_ref[r] - v[k])
    # ---- angular momentum damping (k* = 0)
    r0 = 19 + n_upper
    for r in range(3):
        for j in range(nv):
            jac[r0 + r, j] = centroidal_map[3 + r, j]
        rhs[r0 + r] = gains[14] * (0.0 - momentum[3 + r]) - centroidal_drift[3 + r]


@njit(cache=True, nogil=True)
def _rows_times(a, first, last, x, out):  # noqa: ANN001, ANN202
    """``out[i − first] = a[i] · x`` for rows first..last−1, each sum from 0.0 in column order; two rows side by
    side (independent chains of additions: the same numbers in about half the time)."""
    n = x.shape[0]
    i = first
    while i + 1 < last:
        acc = 0.0
        acc2 = 0.0
        for k in range(n):
            xk = x[k]
            acc += a[i, k] * xk
            acc2 += a[i + 1, k] * xk
        out[i - first] = acc
        out[i + 1 - first] = acc2
        i += 2
    if i < last:
        acc = 0.0
        for k in range(n):
            acc += a[i, k] * x[k]
        out[i - first] = acc


@njit(cache=True, nogil=True)
def torques(mass_matrix, nle, tau_map, rho, qdd, damping):  # noqa: ANN001, ANN201
    """Eq. 15: the base rows solved for q̈_base (6×6 Cholesky of M's base block), written into
    ``qdd[:6]``; returns (τ, base rows' right-hand side, −Σ J_cᵀ f_c) with τ = M_j q̈ + h_j − Σ J_c,jᵀ f_c
    + ``damping`` (the model's viscous joint torque, already multiplied by q̇_j; zeros when the model
    has none). τ is empty when the base block is not positive definite: the caller solves it (LU)."""
    nv = mass_matrix.shape[0]
    gen = np.empty(nv)  # −Σ J_cᵀ f_c
    _rows_times(tau_map, 0, nv, rho, gen)
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
    _rows_times(mass_matrix, 6, nv, qdd, tau)
    for i in range(nv - 6):
        tau[i] = tau[i] + nle[6 + i] + gen[6 + i] + damping[i]
    return tau, rhs, gen



@njit(cache=True, nogil=True)
def qp_bounds(centroidal_drift, weight_n, external_wrench, has_external, q, v, joint_lower, joint_upper, kl, bl,
              amax, nle, damping, has_damping):  # noqa: ANN001, ANN201
    """The centroidal equality's right-hand side b = −Ȧ_h q̇ − [0 0 m g 0 0 0] (+ w_ext), the soft joint
    limits' q̈ bounds (Eqs. 22, 23, within ±q̈_max) and the torque rows' bias h_j (+ joint damping)."""
    b = np.empty(6)
    for r in range(6):
        b[r] = -centroidal_drift[r]
    b[2] -= weight_n
    if has_external:
        for r in range(6):
            b[r] = b[r] + external_wrench[r]
    n = joint_lower.shape[0]
    lo, up, bias = np.empty(n), np.empty(n), np.empty(n)
    for j in range(n):
        lo[j] = min(max(kl * (joint_lower[j] - q[7 + j]) - bl * v[6 + j], -amax), amax)
        up[j] = max(min(kl * (joint_upper[j] - q[7 + j]) - bl * v[6 + j], amax), lo[j])
        bias[j] = nle[6 + j] + damping[j] * v[6 + j] if has_damping else nle[6 + j]
    return b, lo, up, bias


@njit(cache=True, nogil=True)
def _all_finite(a):  # noqa: ANN001, ANN201
    """Every entry of ``a`` (any shape) finite."""
    for x in a.flat:
        if not math.isfinite(x):
            return False
    return True


@njit(cache=True, nogil=True)
def build_qp(jac, rhs, w, gains, fill_constant, frame_pos, frame_rot, frame_jac, frame_vel, frame_drift, contact,
             foot_pos, foot_rot, foot_lin_vel, foot_ang_vel, foot_lin_acc, foot_ang_acc, base_rot, q, v,
             pelvis_height, pelvis_height_rate, pelvis_rot, pelvis_ang_vel, centroidal_map, centroidal_drift,
             momentum, com, mass, com_xy, com_xy_vel, com_xy_acc, com_z, com_z_given, upper_v_idx, upper_q_ref,
             upper_qd_ref, external_wrench, has_external, params, offsets_t, basis_xy, joint_lower, joint_upper, nle,
             damping, has_damping, p_qq, c_q, r_rr, g_rho, tau_map, corners, basis):  # noqa: ANN001, ANN201
    """One tick's QP in one call: the reference's finiteness, then :func:`task_rows`, :func:`assemble_qp` and
    :func:`qp_bounds` (the same code, so the same numbers). ``params``: λ_q̈, the pyramid edges' z,
    λ_τ̄, λ_ρ, the robot's weight m g, the soft joint limits' k_l, b_l and q̈_max. ``com_z``: the tracked
    CoM height when ``com_z_given`` (else NaN). Returns (finite, b, lo, up, bias); when the reference
    has a non-finite number nothing is written and the arrays are empty."""
    finite = (math.isfinite(pelvis_height) and math.isfinite(pelvis_height_rate)
              and (math.isfinite(com_z) or not com_z_given)
              and _all_finite(foot_pos) and _all_finite(foot_rot) and _all_finite(foot_lin_vel)
              and _all_finite(foot_ang_vel) and _all_finite(foot_lin_acc) and _all_finite(foot_ang_acc)
              and _all_finite(pelvis_rot) and _all_finite(pelvis_ang_vel) and _all_finite(com_xy)
              and _all_finite(com_xy_vel) and _all_finite(com_xy_acc) and _all_finite(upper_q_ref)
              and _all_finite(upper_qd_ref) and (_all_finite(external_wrench) or not has_external))
    empty = np.empty(0)
    if not finite:
        return False, empty, empty, empty, empty
    tracked_com_z = com_z if com_z_given else math.nan
    task_rows(jac, rhs, w, gains, fill_constant, frame_pos, frame_rot, frame_jac, frame_vel, frame_drift, contact,
              foot_pos, foot_rot, foot_lin_vel, foot_ang_vel, foot_lin_acc, foot_ang_acc, base_rot, q, v,
              pelvis_height, pelvis_height_rate, pelvis_rot, pelvis_ang_vel, centroidal_map, centroidal_drift,
              momentum, com, mass, com_xy, com_xy_vel, com_xy_acc, tracked_com_z, upper_v_idx,
              upper_q_ref, upper_qd_ref)
    assemble_qp(jac, w, rhs, params[0], frame_rot, frame_pos, offsets_t, com, basis_xy, params[1], frame_jac,
                params[2], params[3], p_qq, c_q, r_rr, g_rho, tau_map, corners, basis)
    b, lo, up, bias = qp_bounds(centroidal_drift, params[4], external_wrench, has_external, q, v, joint_lower,
                                joint_upper, params[5], params[6], params[7], nle, damping, has_damping)
    return True, b, lo, up, bias


@njit(cache=True, nogil=True)
def horizontal_force(rho, basis):  # noqa: ANN001, ANN201
    """Σ of the horizontal contact forces Σ_c B_c ρ_c (2 sides, 4 corners, 4 edges), summed as numpy sums
    ``rho.reshape(2, 4, 4).sum(axis=1)`` and einsums it with the edges here: corner after corner, each
    foot's edges as ((e0 + e2) + (e1 + e3)), then foot + foot (the walking controller's push observer)."""
    out = np.empty(2)
    terms = np.empty((2, 2))
    w = np.empty(4)
    for f in range(2):
        for j in range(4):
            w[j] = ((rho[f * 16 + j] + rho[f * 16 + 4 + j]) + rho[f * 16 + 8 + j]) + rho[f * 16 + 12 + j]
        for k in range(2):
            terms[f, k] = ((basis[f, k, 0] * w[0] + basis[f, k, 2] * w[2])
                           + (basis[f, k, 1] * w[1] + basis[f, k, 3] * w[3]))
    for k in range(2):
        out[k] = terms[0, k] + terms[1, k]
    return out


@njit(cache=True, nogil=True)
def finish_tick(mass_matrix, nle, tau_map, rho, qdd, joint_damping, has_damping, v, q, q_des, qd_des, dt,
                max_position_error, max_velocity_error, basis):  # noqa: ANN001, ANN201
    """:func:`torques` (the model's viscous joint damping ``joint_damping ⊙ q̇_j`` when ``has_damping``), the
    set-points of :func:`engine.control.wbc.setpoints.integrate_setpoints` and the :func:`horizontal_force` of
    the solution in one call: (τ, base rows' right-hand side, −Σ J_cᵀ f_c, q*, q̇*, horizontal force); τ is
    empty when the base block is not positive definite (the caller solves it and integrates the set-points)."""
    n = nle.shape[0] - 6
    damping = np.zeros(n)
    if has_damping:
        for j in range(n):
            damping[j] = joint_damping[j] * v[6 + j]
    tau, rhs, gen = torques(mass_matrix, nle, tau_map, rho, qdd, damping)
    force = horizontal_force(rho, basis)
    if tau.size == 0:
        return tau, rhs, gen, tau, tau, force
    qd_new, q_new = np.empty(n), np.empty(n)
    for j in range(n):  # np.minimum(np.maximum(·, lo), hi) on finite numbers
        vj, qj = v[6 + j], q[7 + j]
        x = qd_des[j] + qdd[6 + j] * dt
        lo, hi = vj - max_velocity_error, vj + max_velocity_error
        x = x if x > lo else lo
        qd_new[j] = x if x < hi else hi
        y = q_des[j] + qd_new[j] * dt
        lo, hi = qj - max_position_error, qj + max_position_error
        y = y if y > lo else lo
        q_new[j] = y if y < hi else hi
    return tau, rhs, gen, q_new, qd_new, force


@njit(cache=True, nogil=True)
def _rotate3(rot, x, out, offset):  # noqa: ANN001, ANN202
    """``out[offset:offset + 3] = rot @ x`` in the order pinocchio's Eigen evaluates a 3 × 3 product: rows 0 and 1
    as one SSE2 packet, ((r₀x₀ + r₁x₁) + r₂x₂), row 2 by the scalar reduction, r₀x₀ + (r₁x₁ + r₂x₂)."""
    for i in range(2):
        out[offset + i] = (rot[i, 0] * x[0] + rot[i, 1] * x[1]) + rot[i, 2] * x[2]
    out[offset + 2] = rot[2, 0] * x[0] + (rot[2, 1] * x[1] + rot[2, 2] * x[2])


@njit(cache=True, nogil=True)
def _frame_motion(parent_rot, motion, t):  # noqa: ANN001, ANN202
    """A joint's spatial motion [linear; angular] (local axes) at a point ``t`` of the joint's frame, in world
    axes: [R (v + ω × t); R ω] (pinocchio's getFrameVelocity / getFrameAcceleration, LOCAL_WORLD_ALIGNED)."""
    lx, ly, lz, ax, ay, az = motion[0], motion[1], motion[2], motion[3], motion[4], motion[5]
    moved = np.empty(3)
    moved[0] = lx + (ay * t[2] - az * t[1])
    moved[1] = ly + (az * t[0] - ax * t[2])
    moved[2] = lz + (ax * t[1] - ay * t[0])
    out = np.empty(6)
    _rotate3(parent_rot, moved, out, 0)
    moved[0], moved[1], moved[2] = ax, ay, az
    _rotate3(parent_rot, moved, out, 3)
    return out


@njit(cache=True, nogil=True)
def _foot_frame(s, joint_jac, parent_rot, parent_pos, parent_vel, parent_acc, frame_rot, frame_pos, support, pos,
                rot, jac, drift):  # noqa: ANN001, ANN202
    """Frame ``s`` of :func:`foot_frames`."""
    nv = joint_jac.shape[1]
    col, tmp = np.empty(3), np.empty(3)
    # oMf = oMi · jMf (pinocchio.updateFramePlacement)
    for j in range(3):
        for i in range(3):
            col[i] = frame_rot[s, i, j]
        _rotate3(parent_rot, col, tmp, 0)
        for i in range(3):
            rot[s, i, j] = tmp[i]
    _rotate3(parent_rot, frame_pos[s], tmp, 0)
    for i in range(3):
        pos[s, i] = tmp[i] + parent_pos[i]
    # LOCAL_WORLD_ALIGNED Jacobian: the joint Jacobians' columns on the frame's support, their linear part
    # moved to the frame's origin: v − p × ω (pinocchio's translateJointJacobian); zero elsewhere
    px, py, pz = pos[s, 0], pos[s, 1], pos[s, 2]
    for j in range(nv):
        if support[s, j]:
            wx, wy, wz = joint_jac[3, j], joint_jac[4, j], joint_jac[5, j]
            jac[s, 0, j] = joint_jac[0, j] - (py * wz - pz * wy)
            jac[s, 1, j] = joint_jac[1, j] - (pz * wx - px * wz)
            jac[s, 2, j] = joint_jac[2, j] - (px * wy - py * wx)
            jac[s, 3, j], jac[s, 4, j], jac[s, 5, j] = wx, wy, wz
        else:
            for r in range(6):
                jac[s, r, j] = 0.0
    # classical acceleration of the frame origin, world axes (pinocchio.getFrameClassicalAcceleration,
    # LOCAL_WORLD_ALIGNED): R (a + α × t), R α, plus ω × v of the frame's velocity R (v + ω × t), R ω
    vel = _frame_motion(parent_rot, parent_vel, frame_pos[s])
    acc = _frame_motion(parent_rot, parent_acc, frame_pos[s])
    drift[s, 0] = acc[0] + (vel[4] * vel[2] - vel[5] * vel[1])
    drift[s, 1] = acc[1] + (vel[5] * vel[0] - vel[3] * vel[2])
    drift[s, 2] = acc[2] + (vel[3] * vel[1] - vel[4] * vel[0])
    for r in range(3, 6):
        drift[s, r] = acc[r]


@njit(cache=True, nogil=True)
def foot_frames(joint_jac, left_rot, left_pos, left_vel, left_acc, right_rot, right_pos, right_vel, right_acc,
                frame_rot, frame_pos, support, pos, rot, jac, drift, base_rot_view, base_rot):  # noqa: ANN001, ANN201
    """Both feet's frame quantities from pinocchio's joint-level results (read in place: ``data.J``, and the
    parent joints' ``data.oMi`` rotation and translation, ``data.v`` and ``data.a`` vectors), written into
    ``pos`` (2, 3), ``rot`` (2, 3, 3), ``jac`` (2, 6, nv) and ``drift`` (2, 6): the numbers of
    ``updateFramePlacement``, ``getFrameJacobian`` and ``getFrameClassicalAcceleration`` (LOCAL_WORLD_ALIGNED)
    bit for bit (the same operations in the same order; ``tests/control/test_wbc_snapshot.py``).
    ``frame_rot``/``frame_pos``: the frames' placements in their parent joints; ``support`` (2, nv): the
    velocity columns of each frame's kinematic chain. ``base_rot_view`` (pinocchio's column-major
    ``data.oMi[1].rotation``) is copied into ``base_rot``."""
    _foot_frame(0, joint_jac, left_rot, left_pos, left_vel, left_acc, frame_rot, frame_pos, support, pos, rot, jac,
                drift)
    _foot_frame(1, joint_jac, right_rot, right_pos, right_vel, right_acc, frame_rot, frame_pos, support, pos, rot,
                jac, drift)
    for i in range(3):
        for j in range(3):
            base_rot[i, j] = base_rot_view[i, j]


@njit(cache=True, nogil=True)
def solve_tick(jac, rhs, w, gains, fill_constant, frame_pos, frame_rot, frame_jac, frame_vel, frame_drift, contact,
               foot_pos, foot_rot, foot_lin_vel, foot_ang_vel, foot_lin_acc, foot_ang_acc, base_rot, q, v,
               pelvis_height, pelvis_height_rate, pelvis_rot, pelvis_ang_vel, centroidal_map, centroidal_drift,
               momentum, com, mass, com_xy, com_xy_vel, com_xy_acc, com_z, com_z_given, upper_v_idx, upper_q_ref,
               upper_qd_ref, external_wrench, has_external, params, offsets_t, basis_xy, joint_lower, joint_upper, nle,
               damping, has_damping, p_qq, c_q, r_rr, g_rho, tau_map, corners, basis, mass_matrix, rho_up, tau_lo,
               tau_up, rho_idx, ws_index, ws_upper, n_warm, max_iter, x, qdd, rho, q_des, qd_des, dt,
               max_position_error, max_velocity_error, b, lo, up, bias, tau, q_new, qd_new,
               force):  # noqa: ANN001, ANN201
    """One whole-body tick in one call, the default path's kernels in their order: :func:`build_qp`, the compiled
    active set (:func:`engine.control.wbc.active_set.solve_centroidal_qp`, warm, then cold when the warm
    working set fails, as :meth:`engine.control.wbc.qp.ActiveSetQpSolver.solve`) and :func:`finish_tick`. The
    arguments are theirs (``mass_matrix``: M, whose joint rows are the torque rows; ``tau_map``'s joint rows
    the torque rows' ρ map). Writes the QP's b (6), q̈ bounds ``lo``/``up`` and torque-row bias (n_joints) once
    built, τ, q*, q̇* (n_joints) and the horizontal ground force (2) once solved (arrays returned by the kernels
    they call, copied: a preallocated output costs less than an array handed back to Python). Returns (tick
    outcome, solver outcome, iterations, final working-set size)."""
    finite, b_, lo_, up_, bias_ = build_qp(
        jac, rhs, w, gains, fill_constant, frame_pos, frame_rot, frame_jac, frame_vel, frame_drift, contact,
        foot_pos, foot_rot, foot_lin_vel, foot_ang_vel, foot_lin_acc, foot_ang_acc, base_rot, q, v,
        pelvis_height, pelvis_height_rate, pelvis_rot, pelvis_ang_vel, centroidal_map, centroidal_drift,
        momentum, com, mass, com_xy, com_xy_vel, com_xy_acc, com_z, com_z_given, upper_v_idx, upper_q_ref,
        upper_qd_ref, external_wrench, has_external, params, offsets_t, basis_xy, joint_lower, joint_upper, nle,
        damping, has_damping, p_qq, c_q, r_rr, g_rho, tau_map, corners, basis)
    if not finite:
        return TICK_INVALID_REFERENCE, QP_OPTIMAL, 0, n_warm
    b[:] = b_
    lo[:] = lo_
    up[:] = up_
    bias[:] = bias_
    touching = False
    for c in contact.flat:
        if c:
            touching = True
    if not touching:
        return TICK_NO_CONTACT, QP_OPTIMAL, 0, n_warm
    tau_qdd, tau_rho = mass_matrix[6:], tau_map[6:]
    outcome, iterations, n_out = solve_centroidal_qp(
        p_qq, c_q, r_rr, centroidal_map, g_rho, b, lo, up, rho_up, tau_qdd, tau_rho, bias, tau_lo, tau_up, rho_idx,
        ws_index, ws_upper, n_warm, max_iter, x, qdd, rho)
    if outcome != QP_OPTIMAL and n_warm > 0:  # the warm working set did not work: once more, cold
        outcome, more, n_out = solve_centroidal_qp(
            p_qq, c_q, r_rr, centroidal_map, g_rho, b, lo, up, rho_up, tau_qdd, tau_rho, bias, tau_lo, tau_up,
            rho_idx, ws_index, ws_upper, 0, max_iter, x, qdd, rho)
        iterations += more
    if outcome != QP_OPTIMAL:
        return TICK_NOT_SOLVED, outcome, iterations, n_out
    tau_, _, _, q_new_, qd_new_, force_ = finish_tick(mass_matrix, nle, tau_map, rho, qdd, damping, has_damping, v,
                                                      q, q_des, qd_des, dt, max_position_error, max_velocity_error,
                                                      basis)
    if tau_.size == 0:
        return TICK_BASE_NOT_PD, outcome, iterations, n_out
    if not math.isfinite(numpy_sum(tau_)):  # math.isfinite(tau.sum())
        return TICK_NONFINITE_TORQUES, outcome, iterations, n_out
    tau[:] = tau_
    q_new[:] = q_new_
    qd_new[:] = qd_new_
    force[:] = force_
    return TICK_SOLVED, outcome, iterations, n_out
