"""The CoM MPC's compiled (numba) kernels: the support polygons' padded geometry in one call.

:func:`geometry_padded` computes what :func:`engine.control.mpc.regions._geometry_padded` computes with
complex numpy arrays (hull, outward normals, half-plane offsets, centroids, areas, the not-convex
mask), on real and imaginary parts and with numpy's complex products, quotients and row sums
spelled out in the same order: the same numbers (``tests/control/test_stack_speed_references.py``).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core.extending import intrinsic


@intrinsic
def _fma(typingctx, a, b, c):  # noqa: ANN001, ANN202, ARG001
    """a·b + c rounded once (LLVM's fma): numpy's SIMD complex product uses fused multiply-adds."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # noqa: ANN001, ANN202, ARG001
        double = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double, double, double]))
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True, nogil=True, inline="always")
def _cmul(ar, ai, br, bi):  # noqa: ANN001, ANN202
    """numpy's complex product (a_r b_r − a_i b_i, a_r b_i + a_i b_r), each part one fused multiply-add."""
    return _fma(ar, br, -(ai * bi)), _fma(ar, bi, ai * br)


@njit(cache=True, nogil=True)
def _row_sum(values, n):  # noqa: ANN001, ANN201
    """Σ values[:n] in numpy's order (its pairwise sum: one accumulator below 8 terms, else eight)."""
    if n < 8:
        total = 0.0
        for j in range(n):
            total += values[j]
        return total
    acc = values[:8].copy()
    i = 8
    while i + 8 <= n:
        for j in range(8):
            acc[j] += values[i + j]
        i += 8
    total = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
    for j in range(i, n):
        total += values[j]
    return total


@njit(cache=True, nogil=True)
def _complex_row_sum(re, im, n):  # noqa: ANN001, ANN201
    """Σ (re + i im)[:n] in numpy's order (its pairwise sum over the interleaved parts: one accumulator
    per part below 4 terms, else four)."""
    if 2 * n < 8:
        a, b = 0.0, 0.0
        for j in range(n):
            a += re[j]
            b += im[j]
        return a, b
    ar = re[:4].copy()
    ai = im[:4].copy()
    k = 4
    while 2 * (k + 4) <= 2 * n:
        for j in range(4):
            ar[j] += re[k + j]
            ai[j] += im[k + j]
        k += 4
    a, b = (ar[0] + ar[1]) + (ar[2] + ar[3]), (ai[0] + ai[1]) + (ai[2] + ai[3])
    for j in range(k, n):
        a += re[j]
        b += im[j]
    return a, b


@njit(cache=True, nogil=True)
def geometry_padded(points, lens, n_v, edge_length):  # noqa: ANN001, ANN201
    """Padded geometry of the polygons stacked in ``points`` (P, 2), ``lens[k]`` vertices each, ``n_v`` slots.

    Returns ``(hull (S, V, 2), normals (S, V, 2), offsets (S, V), centroids (S, 2), area (S,),
    bad (S,))``; unused slots: vertex 0, zero normal, +inf offset. ``edge_length`` (S, V) is numpy's
    ``abs`` of the padded edges (its SIMD hypot differs from libm's in the last bit)."""
    n_s = lens.shape[0]
    hull = np.empty((n_s, n_v, 2))
    normals = np.zeros((n_s, n_v, 2))
    offsets = np.empty((n_s, n_v))
    centroids = np.empty((n_s, 2))
    area = np.empty(n_s)
    bad = np.zeros(n_s, dtype=np.bool_)
    cross = np.empty(n_v)
    sx = np.empty(n_v)
    sy = np.empty(n_v)
    nx = np.empty(n_v)
    ny = np.empty(n_v)
    length = np.empty(n_v)
    start = 0
    for k in range(n_s):
        n = lens[k]
        x0, y0 = points[start, 0], points[start, 1]
        for j in range(n_v):
            i = j if j < n else 0
            hull[k, j, 0], hull[k, j, 1] = points[start + i, 0], points[start + i, 1]
        for j in range(n_v):
            jn = j + 1 if j + 1 < n else 0
            zx, zy = hull[k, j, 0], hull[k, j, 1]
            znx, zny = points[start + jn, 0], points[start + jn, 1]
            wx, wy = zx - x0, zy - y0
            wnx, wny = znx - x0, zny - y0
            cross[j] = _cmul(wx, -wy, wnx, wny)[1]  # imag(conj(w) wn)
            sx[j], sy[j] = wx + wnx, wy + wny
            ex, ey = znx - zx, zny - zy
            length[j] = edge_length[k, j]
            nx[j], ny[j] = ex, ey
        area2 = _row_sum(cross, n_v)
        orient = -1.0 if area2 < 0.0 else 1.0
        cr, ci = _cmul(-0.0, -1.0, orient, 0.0)  # (-1j) * (orient + 0j)
        for j in range(n_v):
            ex, ey = nx[j], ny[j]
            px, py = _cmul(ex, ey, cr, ci)  # e * (-1j orient)
            d = max(length[j], 1e-300)
            scl = 1.0 / (d + 0.0 * 0.0)  # numpy's complex ÷ (d + 0j)
            nx[j], ny[j] = (px + py * 0.0) * scl, (py - px * 0.0) * scl
        for j in range(n_v):
            jp = j - 1 if j > 0 else n - 1
            # rel = conj(n_prev) n
            rel_re, rel_im = _cmul(nx[jp], -ny[jp], nx[j], ny[j])
            if (length[j] <= 1e-9 and j < n) or rel_im * orient < -1e-9:
                bad[k] = True
            use = length[j] > 1e-9 and rel_re < 1.0 - 1e-12
            if use:
                normals[k, j, 0], normals[k, j, 1] = nx[j], ny[j]
                offsets[k, j] = _cmul(nx[j], -ny[j], hull[k, j, 0], hull[k, j, 1])[0]
            else:
                offsets[k, j] = np.inf
        # centroid: z0 + Σ (w + wn) cross / (3 area2)
        for j in range(n_v):
            sx[j], sy[j] = _cmul(sx[j], sy[j], cross[j], 0.0)
        cx, cy = _complex_row_sum(sx, sy, n_v)
        den = 3.0 * (1.0 if area2 == 0.0 else area2)
        rat = 0.0 / den  # numpy's complex ÷ (den + 0j) (Smith's method, |real| ≥ |imag|)
        scl = 1.0 / (den + 0.0 * rat)
        centroids[k, 0] = x0 + (cx + cy * rat) * scl
        centroids[k, 1] = y0 + (cy - cx * rat) * scl
        area[k] = 0.5 * abs(area2)
        start += n
    return hull, normals, offsets, centroids, area, bad


@njit(cache=True, nogil=True)
def problem_rows(own, n_sup, hull, normals, offsets, centroids, ends, t_now, contain_tol, kind_offset_s):  # noqa: ANN001, ANN201, PLR0913
    """The rows of one call's QP from its supports' padded geometry (``ComMpc._build_problem``'s numpy code
    after the geometry, the same numbers): ``own[i]`` is the support of interval ``i``; its midpoint waypoint
    keeps that support's half-planes, its end waypoint the intersection with the next support's, by
    containment. Returns ``(overlap, normals (m, 2), offsets (m,), row_wp (m,), row_key (m,), times (2n+1,),
    centroids (2n+1, 2))``; ``overlap`` True (and nothing else computed) when an end waypoint needs the
    general intersection of two polygons (the numpy code clips them)."""
    n_int = own.shape[0]
    n_v = offsets.shape[1]
    nxt = np.empty(n_int, dtype=np.int64)
    for i in range(n_int - 1):
        nxt[i] = own[i + 1]
    nxt[n_int - 1] = own[n_int - 1]
    use_a = np.ones(n_int, dtype=np.bool_)
    use_b = np.zeros(n_int, dtype=np.bool_)
    overlap = False
    if n_sup > 1:
        inner_a = np.empty(n_sup - 1)
        inner_b = np.empty(n_sup - 1)
        for k in range(n_sup - 1):
            # max over (half-plane of one polygon, vertex of the other) of the signed distance
            best_b, best_a = -np.inf, -np.inf
            for h in range(n_v):
                for v in range(n_v):
                    d_b = _cmul(normals[k, h, 0], -normals[k, h, 1], hull[k + 1, v, 0], hull[k + 1, v, 1])[0] - offsets[k, h]
                    d_a = _cmul(normals[k + 1, h, 0], -normals[k + 1, h, 1], hull[k, v, 0], hull[k, v, 1])[0] - offsets[k + 1, h]
                    best_b = max(best_b, d_b)
                    best_a = max(best_a, d_a)
            inner_b[k], inner_a[k] = best_b, best_a
        for i in range(n_int):
            pair = min(own[i], n_sup - 2)
            in_a = inner_a[pair] <= contain_tol  # C_k ⊂ C_k+1: the intersection is C_k
            in_b = inner_b[pair] <= contain_tol  # C_k+1 ⊂ C_k: it is C_k+1
            use_b[i] = nxt[i] != own[i] and not in_a
            use_a[i] = not (use_b[i] and in_b)
            if use_a[i] and use_b[i]:
                overlap = True
    m = 0
    for i in range(n_int):
        for j in range(n_v):
            if offsets[own[i], j] < np.inf:
                m += 1 + (1 if use_a[i] else 0)
            if use_b[i] and offsets[nxt[i], j] < np.inf:
                m += 1
    times = np.empty(2 * n_int + 1)
    times[0] = t_now
    for i in range(n_int):
        times[2 * i + 2] = ends[i]
        times[2 * i + 1] = 0.5 * (times[2 * i] + ends[i])
    cent = np.empty((2 * n_int + 1, 2))
    cent[0, 0], cent[0, 1] = centroids[own[0], 0], centroids[own[0], 1]
    for i in range(n_int):
        k_end = own[i] if use_a[i] else nxt[i]
        cent[2 * i + 1, 0], cent[2 * i + 1, 1] = centroids[own[i], 0], centroids[own[i], 1]
        cent[2 * i + 2, 0], cent[2 * i + 2, 1] = centroids[k_end, 0], centroids[k_end, 1]
    out_n = np.empty((m, 2))
    out_o = np.empty(m)
    row_wp = np.empty(m, dtype=np.int64)
    row_key = np.empty(m)
    if overlap:
        return overlap, out_n, out_o, row_wp, row_key, times, cent
    r = 0
    for i in range(n_int):
        for part in range(3):  # midpoint slots (C_k), end slots (C_k), end slots (C_k+1)
            if part == 1 and not use_a[i]:
                continue
            if part == 2 and not use_b[i]:
                continue
            k = nxt[i] if part == 2 else own[i]
            wp = 2 * i + 1 if part == 0 else 2 * i + 2
            for j in range(n_v):
                if offsets[k, j] < np.inf:
                    out_n[r, 0], out_n[r, 1] = normals[k, j, 0], normals[k, j, 1]
                    out_o[r] = offsets[k, j]
                    row_wp[r] = wp
                    row_key[r] = times[wp] + kind_offset_s * (wp & 1)
                    r += 1
    return overlap, out_n, out_o, row_wp, row_key, times, cent


@njit(cache=True, nogil=True, error_model="numpy")
def lip_segments(times, omega):  # noqa: ANN001, ANN201
    """``_Segments.build``'s coefficients ``(h, a, b, grow)`` (the same numbers as its numpy code)."""
    n = times.shape[0] - 1
    h = np.empty(n)
    a = np.empty(n)
    b = np.empty(n)
    grow = np.empty(n + 1)
    for j in range(n):
        h[j] = times[j + 1] - times[j]
        wh = omega * h[j]
        one_minus_e = -math.expm1(-wh)
        r = one_minus_e / max(wh, 1e-9) if wh > 1e-9 else 1.0 - 0.5 * wh  # -> 1 as h -> 0
        a[j] = 1.0 - r
        b[j] = r - (1.0 - one_minus_e)
    for j in range(n + 1):
        grow[j] = math.exp(omega * (times[j] - times[0]))
    return h, a, b, grow


@njit(cache=True, nogil=True, error_model="numpy")
def lip_propagate(omega, a, b, grow, cop, com, vel):  # noqa: ANN001, ANN201
    """``_Segments.propagate``: CoM position and velocity at every waypoint (the same numbers as its numpy
    code: its running sums in numpy's cumsum order)."""
    n1 = cop.shape[0]
    pos = np.empty((n1, 2))
    out_vel = np.empty((n1, 2))
    zeta = np.zeros((n1, 2))
    eta = np.zeros((n1, 2))
    for ax in range(2):
        for j in range(n1 - 1):
            z = (a[j] * cop[j, ax] + b[j] * cop[j + 1, ax]) / grow[j]
            e = (b[j] * cop[j, ax] + a[j] * cop[j + 1, ax]) * grow[j + 1]
            zeta[j + 1, ax] = z if j == 0 else zeta[j, ax] + z
            eta[j + 1, ax] = e if j == 0 else eta[j, ax] + e
        z0 = com[ax] + vel[ax] / omega
        e0 = com[ax] - vel[ax] / omega
        for j in range(n1):
            zj = grow[j] * (z0 - zeta[j, ax])
            ej = (e0 + eta[j, ax]) / grow[j]
            pos[j, ax] = 0.5 * (zj + ej)
            out_vel[j, ax] = (0.5 * omega) * (zj - ej)
    return pos, out_vel


@njit(cache=True, nogil=True)
def match_rows(row_key, normals, key_prev, normals_prev, time_tol, cos_min):  # noqa: ANN001, ANN201
    """``ComMpc._match_warm``: for each remembered active row (in order), the first row of this problem
    with a key within ``time_tol`` and a normal more parallel than ``cos_min`` (rows without one are left
    out); numpy's complex product as fused multiply-adds, as in its code."""
    out = np.empty(key_prev.shape[0], dtype=np.int64)
    count = 0
    for j in range(key_prev.shape[0]):
        for i in range(row_key.shape[0]):
            if abs(row_key[i] - key_prev[j]) < time_tol and \
                    _cmul(normals[i, 0], -normals[i, 1], normals_prev[j, 0], normals_prev[j, 1])[0] > cos_min:
                out[count] = i
                count += 1
                break
    return out[:count]


@njit(cache=True, nogil=True)
def condense(a, b, grow, h, w_centroid, w_velocity, min_velocity_dt_s, stability_weight, centroids, final_centroid,
             origin, zeta0, normals, offsets):  # noqa: ANN001, ANN201, PLR0913
    """``ComMpc._condense``'s numbers (:meth:`ComMpc._condense_numpy` is the reference; equal to rounding: ``D``'s
    inverse and the solves with ``D`` here by its tridiagonal LDLᵀ factors, there by LAPACK's LU and products). Segment coefficients ``a, b, grow, h``
    of :class:`engine.control.mpc.lip._Segments`, centroid targets (N+1, 2), the frame ``origin`` and the DCM
    ``zeta0`` in it, the polygon rows. Returns ``(d_mat, d_inv, g, beta, u, kappa, r0, p_free, hess_inv, rhs)``."""
    n = h.shape[0]
    beta = np.empty(n)
    for j in range(n):  # exp(-omega tau_j) b_j (p_j+1 term) + exp(-omega tau_j+1) a_j+1 (p_j+1's next segment)
        beta[j] = (1.0 / grow[j]) * b[j]
        if j + 1 < n:
            beta[j] += (1.0 / grow[j + 1]) * a[j + 1]
    wv = np.empty(n)
    for j in range(n):
        dt = max(h[j], min_velocity_dt_s)
        wv[j] = w_velocity / (dt * dt)
    diag = np.empty(n)
    off = np.zeros(n)  # off[j] = D[j, j+1] (last unused)
    for j in range(n):
        diag[j] = (w_centroid + 1e-9) + wv[j]
        if j + 1 < n:
            diag[j] += wv[j + 1]
            off[j] = -wv[j + 1]
    d_mat = np.zeros((n, n))
    for j in range(n):
        d_mat[j, j] = diag[j]
        if j + 1 < n:
            d_mat[j, j + 1] = d_mat[j + 1, j] = off[j]
    # The same LAPACK (getrf/getri: numba's inverse) and BLAS (gemv/gemm/dot) calls as the numpy code.
    d_inv = np.linalg.inv(d_mat)
    u = np.dot(d_inv, beta)
    kappa = stability_weight / (1.0 + stability_weight * np.dot(beta, u))
    g = np.empty((n, 2))
    for j in range(n):
        g[j, 0] = w_centroid * (centroids[j + 1, 0] - origin[0])
        g[j, 1] = w_centroid * (centroids[j + 1, 1] - origin[1])
    decay_t = 1.0 / grow[n]
    r0 = np.empty(2)
    r0[0] = zeta0[0] - decay_t * (final_centroid[0] - origin[0])
    r0[1] = zeta0[1] - decay_t * (final_centroid[1] - origin[1])
    y = np.dot(d_inv, g)
    beta_y = np.dot(beta, y)
    c0, c1 = kappa * (r0[0] - beta_y[0]), kappa * (r0[1] - beta_y[1])
    p_free = np.empty((n, 2))
    hess_inv = np.empty((n, n))
    for i in range(n):
        p_free[i, 0] = y[i, 0] + u[i] * c0
        p_free[i, 1] = y[i, 1] + u[i] * c1
        ku = kappa * u[i]
        for j in range(n):
            hess_inv[i, j] = d_inv[i, j] - ku * u[j]
    rhs = offsets - np.dot(normals, origin) if offsets.shape[0] else offsets.copy()
    return d_mat, d_inv, g, beta, u, kappa, r0, p_free, hess_inv, rhs


@njit(cache=True, nogil=True)
def window_intervals(t_start, t_end, t_now, t_horizon, min_interval_s, max_interval_s):  # noqa: ANN001, ANN201
    """``ComMpc._build_problem``'s intervals (the same numbers as its former numpy code, kept in
    ``tests/control/test_stack_speed_references.py``): the supports in use (not elapsed, starting before the
    window ends, chronological order) and their pieces (supports longer than ``max_interval_s`` split into
    equal pieces anchored at their start), ends truncated to the window.

    Returns ``(status, index, used (K,), ends (n,), owner (n,))``: status 0, or 1 when support ``index`` has
    invalid times (non-finite or ending before it starts), 2 when no support covers the window."""
    n = t_start.shape[0]
    used = np.empty(n, dtype=np.int64)
    n_used = 0
    prev_end = t_now
    for k in range(n):
        t0, t1 = t_start[k], t_end[k]
        if not (np.isfinite(t0) and np.isfinite(t1) and t1 >= t0):
            return 1, k, used[:0], np.empty(0), used[:0]
        if t1 <= prev_end + min_interval_s:
            continue  # elapsed (or nearly elapsed)
        if prev_end >= t_horizon - min_interval_s:
            break
        used[n_used] = k
        n_used += 1
        prev_end = t1 if t1 < t_horizon else t_horizon
    used = used[:n_used]
    if n_used == 0:
        return 2, -1, used, np.empty(0), used
    n_pieces = np.empty(n_used, dtype=np.int64)
    total = 0
    for i in range(n_used):
        k = used[i]
        n_pieces[i] = int(max(np.ceil((t_end[k] - t_start[k]) / max_interval_s - 1e-9), 1.0))
        total += n_pieces[i]
    if total == n_used:
        ends = np.empty(n_used)
        for i in range(n_used):
            ends[i] = min(t_end[used[i]], t_horizon)
        return 0, -1, used, ends, np.arange(n_used)
    ends = np.empty(total)
    owner = np.empty(total, dtype=np.int64)
    n_int = 0
    prev_end = t_now
    for i in range(n_used):
        t0, t1, n_k = t_start[used[i]], t_end[used[i]], n_pieces[i]
        piece_s = (t1 - t0) / n_k
        first = max(0, int((prev_end + min_interval_s - t0) // piece_s)) if n_k > 1 else 0
        for j in range(first, n_k):
            end = t1 if j == n_k - 1 else t0 + (j + 1) * piece_s
            if end <= prev_end + min_interval_s:
                continue
            if prev_end >= t_horizon - min_interval_s:
                break
            prev_end = min(end, t_horizon)
            ends[n_int] = prev_end
            owner[n_int] = i
            n_int += 1
    return 0, -1, used, ends[:n_int], owner[:n_int]


@njit(cache=True, nogil=True, error_model="numpy")
def plan_from_waypoints(omega, a, b, grow, wps, com, vel, origin):  # noqa: ANN001, ANN201
    """The plan of the QP's waypoints ``p_1..p_N`` (N, 2) in the frame at ``origin`` (where ``p_0 = 0``): CoP
    waypoints (N+1, 2) and the CoM (position, velocity) at their times (:func:`lip_propagate`) in the world
    frame, the final state ``[x_T, v_T]`` and the sum of the propagated CoM's numbers (finite iff they all are).
    """
    n1 = wps.shape[0] + 1
    local = np.zeros((n1, 2))
    local[1:] = wps
    com_local = np.empty(2)
    com_local[0], com_local[1] = com[0] - origin[0], com[1] - origin[1]
    pos, out_vel = lip_propagate(omega, a, b, grow, local, com_local, vel)
    total = 0.0
    for j in range(n1):
        total += pos[j, 0] + pos[j, 1]
    for j in range(n1):
        total += out_vel[j, 0] + out_vel[j, 1]
    wps_world = np.empty((n1, 2))
    pos_world = np.empty((n1, 2))
    for j in range(n1):
        for ax in range(2):
            wps_world[j, ax] = local[j, ax] + origin[ax]
            pos_world[j, ax] = pos[j, ax] + origin[ax]
    final = np.empty(4)
    final[0], final[1] = pos_world[n1 - 1, 0], pos_world[n1 - 1, 1]
    final[2], final[3] = out_vel[n1 - 1, 0], out_vel[n1 - 1, 1]
    return wps_world, pos_world, out_vel, final, total


@njit(cache=True, nogil=True, error_model="numpy")
def plan_is_finite(times, wps, com, vel, final, height):  # noqa: ANN001, ANN201
    """Whether every number of a plan is finite."""
    ok = math.isfinite(height)
    for v in times.ravel():
        ok = ok and math.isfinite(v)
    for arr in (wps, com, vel):
        for v in arr.ravel():
            ok = ok and math.isfinite(v)
    for v in final.ravel():
        ok = ok and math.isfinite(v)
    return ok


@njit(cache=True, nogil=True)
def support_geometry(points, lens, n_v, edge_length, min_area):  # noqa: ANN001, ANN201
    """:func:`geometry_padded` of finite points with its checks: ``status`` 0 (usable), 1 (a non-finite
    vertex, or a polygon not convex: the caller takes the numpy path, which replaces it by its hull), 2 (a
    polygon of area below ``min_area``). Returns ``(status, hull, normals, offsets, centroids, max_h)``,
    ``max_h`` the most half-planes of one polygon."""
    n_s = lens.shape[0]
    for v in points.ravel():
        if not np.isfinite(v):
            return 1, np.empty((0, n_v, 2)), np.empty((0, n_v, 2)), np.empty((0, n_v)), np.empty((0, 2)), 0
    hull, normals, offsets, centroids, area, bad = geometry_padded(points, lens, n_v, edge_length)
    status = 0
    for k in range(n_s):
        if bad[k]:
            return 1, hull, normals, offsets, centroids, 0
        if not area[k] >= min_area:
            status = 2
    max_h = 0
    for k in range(n_s):
        count = 0
        for j in range(n_v):
            if offsets[k, j] < np.inf:
                count += 1
        max_h = max(max_h, count)
    return status, hull, normals, offsets, centroids, max_h
