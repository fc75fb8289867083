"""The dual active-set QP solver of :mod:`engine.control.mpc.active_set`, compiled (numba).

:func:`dual_active_set` takes the same steps as :func:`engine.control.mpc.active_set._dual_active_set_numpy`
(warm candidates, block steps, dual-feasible start, Goldfarb–Idnani), on the condensed MPC QP's data
(``H^-1``, the polygon rows) instead of a column callback, and matches the warm-start rows itself
(:func:`engine.control.mpc.kernels.match_rows`). Its Cholesky factors and triangular solves are loops
here and LAPACK's there: the multipliers are equal to rounding, the active sets the same
(``tests/control/test_stack_speed_references.py``). It has no wall-time limit (a solve with one runs the
numpy code).

:func:`solve_window` runs one call's whole QP in one compiled call: the LIP segments, the condensation, the free
slacks, this solver, the waypoints and the plan (the kernels the controller called one by one, in its order: the
same numbers), without a dispatch and its argument boxing per step.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from engine.control.mpc.kernels import (
    _fma,
    condense,
    lip_segments,
    match_rows,
    plan_from_waypoints,
    plan_is_finite,
    problem_rows,
    support_geometry,
    window_intervals,
)

#: Active-set outcomes (as in :mod:`engine.control.mpc.active_set`).
AS_OPTIMAL, AS_CAPPED, AS_INFEASIBLE = 0, 1, 2


@njit(cache=True, nogil=True)
def _g_column(hess_inv, normals, row_var, j, out):  # noqa: ANN001, ANN202
    """Column ``j`` of the dual Hessian ``G_ij = (n_i . n_j) H^-1[v_i, v_j]`` into ``out`` (m,)."""
    vj = row_var[j]
    nx, ny = normals[j, 0], normals[j, 1]
    for i in range(row_var.shape[0]):
        out[i] = hess_inv[row_var[i], vj] * (normals[i, 0] * nx + normals[i, 1] * ny)


@njit(cache=True, nogil=True)
def _cholesky(gw, rows, k, out):  # noqa: ANN001, ANN202
    """Lower Cholesky factor of ``gw[rows[:k], :k]`` (its lower triangle) into ``out[:k, :k]``; False
    unless it is safely positive definite (``active_set._chol``'s test)."""
    d_max = -np.inf
    for i in range(k):
        d_max = max(d_max, gw[rows[i], i])
    d_min = np.inf
    for j in range(k):
        d = gw[rows[j], j]
        for p in range(j):
            d -= out[j, p] * out[j, p]
        if not d > 0.0:
            return False
        ljj = math.sqrt(d)
        out[j, j] = ljj
        d_min = min(d_min, ljj)
        for i in range(j + 1, k):
            v = gw[rows[i], j]
            for p in range(j):
                v -= out[i, p] * out[j, p]
            out[i, j] = v / ljj
    return not (k > 0 and d_min * d_min <= 1e-13 * d_max)


@njit(cache=True, nogil=True)
def _chol_solve(chol, k, rhs, out):  # noqa: ANN001, ANN202
    """``out[:k] = (L Lᵀ)^-1 rhs[:k]``."""
    for i in range(k):
        v = rhs[i]
        for p in range(i):
            v -= chol[i, p] * out[p]
        out[i] = v / chol[i, i]
    for i in range(k - 1, -1, -1):
        v = out[i]
        for p in range(i + 1, k):
            v -= chol[p, i] * out[p]
        out[i] = v / chol[i, i]


@njit(cache=True, nogil=True)
def _evaluate(hess_inv, normals, row_var, s, rows, tol, gw, chol, lam, slack):  # noqa: ANN001, ANN202, PLR0913
    """Solve the rows ``rows`` as equalities: their columns into ``gw``, the factor into ``chol``, multipliers
    into ``lam``, the slacks into ``slack``. Returns ``(ok, score)``: score = violated rows + non-positive
    multipliers (0: optimal)."""
    k = rows.shape[0]
    m = s.shape[0]
    for c in range(k):
        _g_column(hess_inv, normals, row_var, rows[c], gw[:, c])
    if not _cholesky(gw, rows, k, chol):
        return False, 0
    rhs = np.empty(k)
    for c in range(k):
        rhs[c] = -s[rows[c]]
    _chol_solve(chol, k, rhs, lam)
    score = 0
    for c in range(k):
        if not lam[c] > 0.0:
            score += 1
    for i in range(m):
        v = s[i]
        for c in range(k):
            v += gw[i, c] * lam[c]
        slack[i] = v
        if v < -tol:
            score += 1
    return True, score


@njit(cache=True, nogil=True)
def dual_active_set(hess_inv, normals, row_var, s, row_key, keys_a, normals_a, keys_b, normals_b, n_warm,
                    warm_time_tol, warm_cos_min, tol, max_iter, block_rounds):  # noqa: ANN001, ANN201, PLR0913, PLR0912, PLR0915
    """Dual active set on ``min 1/2 x'Hx + q'x s.t. A x <= b`` (see ``active_set._dual_active_set_numpy``):
    ``s = b - A x_free`` (m,), rows ``normals[i] . p[row_var[i]] <= ...``; warm candidates: the rows matching
    the first ``n_warm`` (0-2) remembered solutions' active rows (row keys, normals (k, 2)) ``a`` then ``b``.
    Returns ``(W (k,), lam (k,), iterations, outcome)``."""
    m = s.shape[0]
    n_var = 0
    for i in range(m):
        n_var = max(n_var, row_var[i] + 1)
    gw = np.empty((m, m + 1))
    chol = np.empty((m + 1, m + 1))  # only lower triangles written before being read
    lam = np.empty(m + 1)
    slack = np.empty(m)
    it = 0
    # 1. warm candidates, then the empty set
    best_rows = np.empty(0, dtype=np.int64)
    have_best = False
    best_score = 0
    for c in range(n_warm + 1):
        if c < n_warm:
            keys, nrm = (keys_a, normals_a) if c == 0 else (keys_b, normals_b)
            matched = match_rows(row_key, normals, keys, nrm, warm_time_tol, warm_cos_min)
        else:
            matched = np.empty(0, dtype=np.int64)
        rows = np.empty(matched.shape[0], dtype=np.int64)  # first occurrences, in order
        k = 0
        for r in matched:
            seen = False
            for q in range(k):
                if rows[q] == r:
                    seen = True
                    break
            if not seen:
                rows[k] = r
                k += 1
        rows = rows[:k]
        if have_best and k == 0:
            break
        it += 1
        ok, score = _evaluate(hess_inv, normals, row_var, s, rows, tol, gw, chol, lam, slack)
        if not ok:
            continue
        if score == 0:
            return rows, lam[:k].copy(), it, AS_OPTIMAL
        if not have_best or score < best_score:
            have_best, best_score, best_rows = True, score, rows
    # re-evaluate the best candidate (the buffers hold the last one evaluated)
    W = best_rows
    _evaluate(hess_inv, normals, row_var, s, W, tol, gw, chol, lam, slack)
    # 2. block steps
    for _ in range(block_rounds):
        if it >= max_iter:
            break
        k = W.shape[0]
        count = np.zeros(n_var, dtype=np.int64)
        trial = np.empty(m + k, dtype=np.int64)
        n_kept = 0
        for c in range(k):
            if lam[c] > 0.0:
                trial[n_kept] = W[c]
                count[row_var[W[c]]] += 1
                n_kept += 1
        n_viol = 0
        viol = np.empty(m, dtype=np.int64)
        for i in range(m):
            if slack[i] < -tol:
                viol[n_viol] = i
                n_viol += 1
        viol = viol[:n_viol]
        order = np.argsort(slack[viol], kind="mergesort")
        n_trial = n_kept
        for o in order:
            i = viol[o]
            v = row_var[i]
            if count[v] < 2:
                count[v] += 1
                trial[n_trial] = i
                n_trial += 1
        if n_trial == n_kept and n_kept == k:
            break
        it += 1
        trial = trial[:n_trial]
        ok, score = _evaluate(hess_inv, normals, row_var, s, trial, tol, gw, chol, lam, slack)
        if not ok:
            _evaluate(hess_inv, normals, row_var, s, W, tol, gw, chol, lam, slack)  # back to the last good set
            break
        W = trial
        if score == 0:
            return W, lam[:n_trial].copy(), it, AS_OPTIMAL
    # 3. dual-feasible start: positive multipliers on W, slack 0 on W
    k = W.shape[0]
    w_list = np.empty(m + 1, dtype=np.int64)
    w_list[:k] = W
    good = _cholesky(gw, w_list, k, chol)
    while k > 0:
        if not good:
            k = 0
            break
        rhs = np.empty(k)
        for c in range(k):
            rhs[c] = -s[w_list[c]]
        _chol_solve(chol, k, rhs, lam)
        n_keep = 0
        for c in range(k):
            if lam[c] > 0.0:
                w_list[n_keep] = w_list[c]
                gw[:, n_keep] = gw[:, c]
                n_keep += 1
        if n_keep == k:
            break
        it += 1
        k = n_keep
        good = _cholesky(gw, w_list, k, chol)
    # 4. Goldfarb-Idnani
    gp = np.empty(m)
    ell = np.empty(m + 1)
    d = np.empty(m + 1)
    while True:
        for i in range(m):
            v = s[i]
            for c in range(k):
                v += gw[i, c] * lam[c]
            slack[i] = v
        for c in range(k):
            slack[w_list[c]] = np.inf  # active rows hold with equality (up to rounding)
        p = 0
        for i in range(1, m):
            if slack[i] < slack[p]:
                p = i
        wp = slack[p]
        if wp >= -tol:
            return w_list[:k].copy(), lam[:k].copy(), it, AS_OPTIMAL
        if it >= max_iter:
            return w_list[:k].copy(), lam[:k].copy(), it, AS_CAPPED
        lam_p = 0.0
        _g_column(hess_inv, normals, row_var, p, gp)
        gpp = gp[p]
        while True:  # add row p, dropping rows whose multiplier reaches zero on the way
            it += 1
            z = gpp
            if k:
                for i in range(k):  # L ell = G_Wp
                    v = gp[w_list[i]]
                    for q in range(i):
                        v -= chol[i, q] * ell[q]
                    ell[i] = v / chol[i, i]
                for i in range(k - 1, -1, -1):  # Lᵀ d = -ell
                    v = ell[i]
                    for q in range(i + 1, k):
                        v -= chol[q, i] * d[q]
                    d[i] = v / chol[i, i]
                ee = 0.0
                for i in range(k):
                    d[i] = -d[i]
                    ee += ell[i] * ell[i]
                z = gpp - ee
            t_full = -wp / z if z > 1e-12 * gpp else np.inf
            t_part, j_block = np.inf, -1
            for i in range(k):
                if d[i] < 0.0:
                    ratio = lam[i] / -d[i]
                    if ratio < t_part:
                        t_part, j_block = ratio, i
            if t_full == np.inf and t_part == np.inf:
                return w_list[:k].copy(), lam[:k].copy(), it, AS_INFEASIBLE
            if t_full <= t_part:
                for i in range(k):
                    lam[i] += t_full * d[i]
                    chol[k, i] = ell[i]
                lam[k] = lam_p + t_full
                for i in range(k):
                    chol[i, k] = 0.0
                chol[k, k] = math.sqrt(z)
                w_list[k] = p
                gw[:, k] = gp
                k += 1
                break
            for i in range(k):
                lam[i] += t_part * d[i]
            lam_p += t_part
            wp += t_part * z
            for i in range(j_block, k - 1):
                w_list[i] = w_list[i + 1]
                lam[i] = lam[i + 1]
                gw[:, i] = gw[:, i + 1]
            k -= 1
            if not _cholesky(gw, w_list, k, chol):  # numerically dependent after all: restart from this row set
                return w_list[:k].copy(), lam[:k].copy(), it, AS_CAPPED
            if it >= max_iter:
                w_list[k] = p
                lam[k] = lam_p
                return w_list[:k + 1].copy(), lam[:k + 1].copy(), it, AS_CAPPED


@njit(cache=True, nogil=True)
def waypoints_from_multipliers(p_free, hess_inv, normals, row_var, rhs, rows, lam):  # noqa: ANN001, ANN201
    """``p = p_free - H^-1 A_Wᵀ lam`` (N, 2) and the largest row violation ``max(A p - b)`` (0 without rows,
    inf if ``p`` is not finite)."""
    n = p_free.shape[0]
    g = np.zeros((n, 2))
    for c in range(rows.shape[0]):
        r = rows[c]
        g[row_var[r], 0] += normals[r, 0] * lam[c]
        g[row_var[r], 1] += normals[r, 1] * lam[c]
    p = p_free.copy()
    if rows.shape[0]:
        for i in range(n):
            a0, a1 = 0.0, 0.0
            for j in range(n):
                a0 += hess_inv[i, j] * g[j, 0]
                a1 += hess_inv[i, j] * g[j, 1]
            p[i, 0] -= a0
            p[i, 1] -= a1
    worst = 0.0
    finite = True
    for i in range(n):
        finite = finite and math.isfinite(p[i, 0]) and math.isfinite(p[i, 1])
    if not finite:
        return p, np.inf
    for i in range(rhs.shape[0]):
        v = normals[i, 0] * p[row_var[i], 0] + normals[i, 1] * p[row_var[i], 1] - rhs[i]
        worst = max(worst, v)
    return p, worst


@njit(cache=True, nogil=True)
def free_slacks(p_free, normals, row_var, rhs):  # noqa: ANN001, ANN201
    """``s = b - A p_free`` (m,) of the unconstrained optimum."""
    m = rhs.shape[0]
    s = np.empty(m)
    for i in range(m):
        s[i] = rhs[i] - (normals[i, 0] * p_free[row_var[i], 0] + normals[i, 1] * p_free[row_var[i], 1])
    return s


@njit(cache=True, nogil=True)
def solve_window(times, omega, w_centroid, w_velocity, min_velocity_dt_s, stability_weight, centroids,  # noqa: ANN001, ANN201, PLR0913
                 final_centroid, com, vel, origin, normals, offsets, row_wp, row_key, keys_a, normals_a, keys_b,
                 normals_b, n_warm, warm_time_tol, warm_cos_min, tol, max_iter, block_rounds):
    """``ComMpc._solve``'s steps from the problem's rows to the plan, compiled in one call: ``lip_segments``,
    ``condense`` (QP frame at ``origin``, the DCM ``com + vel / omega - origin``), ``free_slacks``, then (some
    slack below ``-tol``) :func:`dual_active_set` and :func:`waypoints_from_multipliers`, and for an optimum
    ``plan_from_waypoints`` and ``plan_is_finite``.

    Returns ``(outcome, iterations, active rows (k,), violation, wps_world (N+1, 2), com (N+1, 2),
    com_vel (N+1, 2), final_state (4,), total, finite)``; the plan's arrays are empty unless the outcome is
    optimal (the caller then takes its step-by-step path, which computes the same)."""
    h, a, b, grow = lip_segments(times, omega)
    zeta0 = np.empty(2)
    for ax in range(2):
        zeta0[ax] = (com[ax] + vel[ax] / omega) - origin[ax]
    _, _, _, _, _, _, _, p_free, hess_inv, rhs = condense(
        a, b, grow, h, w_centroid, w_velocity, min_velocity_dt_s, stability_weight, centroids, final_centroid, origin,
        zeta0, normals, offsets)
    m = rhs.shape[0]
    row_var = np.empty(m, dtype=np.int64)
    for i in range(m):
        row_var[i] = row_wp[i] - 1
    s = free_slacks(p_free, normals, row_var, rhs)
    s_min = np.inf  # s.min() (NaN if one is)
    for i in range(m):
        if s[i] != s[i]:
            s_min = np.nan
            break
        s_min = min(s_min, s[i])
    empty2 = np.empty((0, 2))
    if m == 0 or s_min >= -tol:
        rows = np.empty(0, dtype=np.int64)
        iterations, outcome = 0, AS_OPTIMAL
        wps = p_free
        violation = max(-min(s_min, 0.0), 0.0)  # max(-s.min(initial=0.0), 0.0)
    else:
        rows, lam, iterations, outcome = dual_active_set(
            hess_inv, normals, row_var, s, row_key, keys_a, normals_a, keys_b, normals_b, n_warm, warm_time_tol,
            warm_cos_min, tol, max_iter, block_rounds)
        if outcome != AS_OPTIMAL:
            return outcome, iterations, rows, np.nan, empty2, empty2, empty2, np.empty(4), np.nan, False
        wps, violation = waypoints_from_multipliers(p_free, hess_inv, normals, row_var, rhs, rows, lam)
    wps_world, pos_world, vel_wp, final, total = plan_from_waypoints(omega, a, b, grow, wps, com, vel, origin)
    finite = plan_is_finite(times, wps_world, pos_world, vel_wp, final, 1.0)
    return outcome, iterations, rows, violation, wps_world, pos_world, vel_wp, final, total, finite


#: :func:`plan_window`'s status when it returns a plan; otherwise the caller takes its step-by-step path.
WINDOW_PLANNED, WINDOW_STEP_BY_STEP = 0, 1


@njit(cache=True, nogil=True, inline="always")
def edge_length(dx, dy):  # noqa: ANN001, ANN201
    """numpy's ``abs(dx + i dy)`` (its SIMD complex absolute: ``larger · sqrt(fma(r, r, 1))``, ``r`` the smaller part over
    the larger one; not libm's hypot, which differs in the last bit), for finite parts."""
    a, b = abs(dx), abs(dy)
    larger, smaller = max(a, b), min(a, b)
    if larger == np.inf:
        return np.inf
    ratio = smaller / larger if larger != 0.0 else 0.0
    return math.sqrt(_fma(ratio, ratio, 1.0)) * larger


@njit(cache=True, nogil=True)
def plan_window(supports, points, t_now, com_x, com_y, vel_x, vel_y, cop_x, cop_y, height, gravity,  # noqa: ANN001, ANN201, PLR0913, PLR0915
                preview_s, min_interval_s, max_interval_s, w_centroid, w_velocity, min_velocity_dt_s, w_final,
                w_stability, max_stability_weight, max_intervals, max_halfplanes, min_area, contain_tol,
                kind_offset_s, keys_a, normals_a, keys_b, normals_b, n_warm, warm_time_tol, warm_cos_min, tol, max_iter,
                block_rounds, constraint_tol):
    """``ComMpc.solve``'s default path (active set, no wall-time limit) from the supports to the plan in one
    compiled call: :func:`window_intervals`, :func:`support_geometry`, :func:`problem_rows` and :func:`solve_window`
    with the arguments ``ComMpc._build_problem`` and ``ComMpc._solve_compiled`` give them (the same kernels in the
    same order: the same numbers).

    ``supports`` (K, 3): each support's start and end times and its polygon's vertex count; the polygons stacked in
    ``points`` (P, 2). The state as floats (finite, ``height > 1e-3``); ``w_stability < 0``: ``W_T exp(2 omega T)``.

    Returns ``(status, iterations, times (N+1,), waypoints (N+1, 2), com (N+1, 2), com_vel (N+1, 2),
    final_state (4,), centroids (N+1, 2), warm keys (k,), warm normals (k, 2))``: status
    :data:`WINDOW_PLANNED` for a clean, finite optimum within ``constraint_tol``; :data:`WINDOW_STEP_BY_STEP` (and
    empty arrays) whenever the step-by-step path does something else (invalid or uncovered supports, polygons
    outside 3..16 vertices, non-finite, not convex or degenerate, a workspace to grow, a general intersection of
    two supports, a solve that is not a clean optimum): it then computes it all (the same numbers)."""
    empty1, empty2 = np.empty(0), np.empty((0, 2))
    fail = (WINDOW_STEP_BY_STEP, 0, empty1, empty2, empty2, empty2, empty1, empty2, empty1, empty2)
    n_all = supports.shape[0]
    t_start = np.empty(n_all)
    t_end = np.empty(n_all)
    first = np.empty(n_all, dtype=np.int64)
    total = 0
    for k in range(n_all):
        t_start[k], t_end[k] = supports[k, 0], supports[k, 1]
        first[k] = total
        total += int(supports[k, 2])
    if total != points.shape[0]:
        return fail
    status, _, used, ends, own = window_intervals(t_start, t_end, t_now, t_now + preview_s, min_interval_s,
                                                  max_interval_s)
    if status != 0:
        return fail
    # the used supports' polygons and their edges' lengths in the padded layout (padding: zero-length edges)
    n_sup = used.shape[0]
    lens = np.empty(n_sup, dtype=np.int64)
    n_v, n_min, n_points = 0, 1 << 30, 0
    for i in range(n_sup):
        n = int(supports[used[i], 2])
        lens[i] = n
        n_v, n_min, n_points = max(n_v, n), min(n_min, n), n_points + n
    if n_min < 3 or n_v > 16:
        return fail
    vertices = np.empty((n_points, 2))
    edges = np.zeros((n_sup, n_v))
    r = 0
    for i in range(n_sup):
        s, n = first[used[i]], lens[i]
        for j in range(n):
            vertices[r, 0], vertices[r, 1] = points[s + j, 0], points[s + j, 1]
            jn = s + j + 1 if j + 1 < n else s
            edges[i, j] = edge_length(points[jn, 0] - points[s + j, 0], points[jn, 1] - points[s + j, 1])
            r += 1
    status, hull, normals, offsets, centroids, max_h = support_geometry(vertices, lens, n_v, edges, min_area)
    if status != 0 or own.shape[0] > max_intervals or max_h > max_halfplanes:
        return fail
    overlap, row_normals, row_offsets, row_wp, row_key, times, row_centroids = problem_rows(
        own, n_sup, hull, normals, offsets, centroids, ends, t_now, contain_tol, kind_offset_s)
    if overlap:
        return fail
    final_centroid = centroids[own[own.shape[0] - 1]].copy()
    omega = math.sqrt(gravity / height)
    horizon_s = times[times.shape[0] - 1] - times[0]
    if w_stability >= 0.0:
        stability_weight = min(w_stability, max_stability_weight)
    else:
        stability_weight = min(w_final * math.exp(min(2.0 * omega * horizon_s, 700.0)), max_stability_weight)
    com = np.empty(2)
    vel = np.empty(2)
    cop = np.empty(2)
    com[0], com[1], vel[0], vel[1], cop[0], cop[1] = com_x, com_y, vel_x, vel_y, cop_x, cop_y
    outcome, iterations, rows, violation, wps_world, pos_world, vel_wp, final_state, _, finite = solve_window(
        times, omega, w_centroid, w_velocity, min_velocity_dt_s, stability_weight, row_centroids, final_centroid, com,
        vel, cop, row_normals, row_offsets, row_wp, row_key, keys_a, normals_a, keys_b, normals_b, n_warm,
        warm_time_tol, warm_cos_min, tol, max_iter, block_rounds)
    if outcome != AS_OPTIMAL or not violation <= constraint_tol or not finite:
        return fail
    warm_keys = np.empty(rows.shape[0])
    warm_normals = np.empty((rows.shape[0], 2))
    for c in range(rows.shape[0]):
        warm_keys[c] = row_key[rows[c]]
        warm_normals[c, 0], warm_normals[c, 1] = row_normals[rows[c], 0], row_normals[rows[c], 1]
    return (WINDOW_PLANNED, iterations, times, wps_world, pos_world, vel_wp, final_state, row_centroids, warm_keys,
            warm_normals)
