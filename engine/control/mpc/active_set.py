"""Dense dual active-set QP solver (Goldfarb–Idnani) on the condensed MPC QP, warm-started.

:func:`_dual_active_set` runs the compiled solver (:mod:`engine.control.mpc.active_set_kernel`), or the
numpy one (:func:`_dual_active_set_numpy`, the reference) when the solve has a wall-time limit."""

from __future__ import annotations

import itertools
import math
import time
from collections.abc import Callable, Iterable, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.linalg.lapack import dgetrf as _dgetrf
from scipy.linalg.lapack import dgetri as _dgetri
from scipy.linalg.lapack import dpotrf as _dpotrf
from scipy.linalg.lapack import dpotrs as _dpotrs
from scipy.linalg.lapack import dtrtrs as _dtrtrs

from engine.control.mpc import active_set_kernel
from engine.control.mpc.kernels import match_rows


FloatArray = NDArray[np.float64]

#: Active-set outcomes.
_AS_OPTIMAL, _AS_CAPPED, _AS_INFEASIBLE = 0, 1, 2


def _inverse(mat: FloatArray) -> FloatArray:
    """Inverse of a small well-conditioned matrix (LAPACK getrf/getri: less overhead than numpy)."""
    lu, piv, info = _dgetrf(mat)
    if info == 0:
        inv, info = _dgetri(lu, piv)
        if info == 0:
            return inv
    return np.asarray(np.linalg.inv(mat), dtype=np.float64)


def _chol(mat: FloatArray) -> FloatArray | None:
    """Lower Cholesky factor of a symmetric matrix, None unless it is safely positive definite."""
    if len(mat) == 0:
        return mat
    c, info = _dpotrf(mat, lower=1, clean=1)
    if info != 0 or c.diagonal().min() ** 2 <= 1e-13 * mat.diagonal().max():  # (nearly) dependent rows
        return None
    return c


def _dual_active_set_numpy(
    cols: Callable[[Sequence[int]], FloatArray],
    s: FloatArray,
    warm_sets: Iterable[Sequence[int]],
    row_var: NDArray[np.intp],
    tol: float,
    max_iter: int,
    deadline: float,
    block_rounds: int = 4,
) -> tuple[list[int], FloatArray, int, int]:
    """Dual active-set QP solver on ``min 1/2 x'Hx + q'x s.t. A x <= b``.

    Works on the dual data only: columns ``cols(J) = G[:, J]`` of ``G = A H^-1 A^T``
    and the slacks ``s = b - A x_free`` of the unconstrained optimum; the slacks of the
    iterate ``x = x_free - H^-1 A_W' lam`` are ``s + G[:, W] lam``.  Phases (each
    factorisation / step counts as one iteration):

    1. Warm start: each candidate set of rows guessed active (e.g. the previous two
       solutions' active rows) is solved as equalities; an exact guess ends here, else
       the candidate with the fewest violated rows and negative multipliers is kept.
    2. Block steps (primal-dual active set, Hintermüller et al. 2002): keep the rows
       with positive multipliers, add the violated ones (at most two per waypoint
       ``row_var``, most violated first); many rows change per step.
    3. Dual-feasible start: drop rows with negative multipliers until none is left.
    4. Goldfarb-Idnani (as in ``quadprog``): add the most violated row, dropping rows
       whose multiplier reaches zero on the way, until no row is violated by more than
       ``tol``.  Finite; the Cholesky factor of ``G_WW`` is extended by one row per
       added row (two triangular solves) and refactored when a row is dropped.

    Returns ``(W, lam, iterations, outcome)``.
    """
    n_var = int(row_var.max()) + 1 if len(row_var) else 0
    it = 0

    def evaluate(rows: list[int]) -> tuple | None:
        gw = cols(rows)
        c = _chol(gw[rows])
        if c is None:
            return None
        lam = _dpotrs(c, -s[rows], lower=1)[0] if rows else np.zeros(0)
        slack = s + gw @ lam if rows else s
        viol = np.flatnonzero(slack < -tol)
        positive = lam > 0.0
        return rows, gw, lam, slack, viol, positive, len(viol) + len(lam) - int(positive.sum())

    best = None
    for cand in itertools.chain(warm_sets, [[]]):
        rows = list(dict.fromkeys(cand))
        if best is not None and not rows:
            break
        it += 1
        ev = evaluate(rows)
        if ev is None:
            continue
        if ev[-1] == 0:
            return ev[0], ev[2], it, _AS_OPTIMAL
        if best is None or ev[-1] < best[-1]:
            best = ev
    assert best is not None  # the empty set always evaluates
    W, gw, lam, slack, viol, positive, _ = best
    for _ in range(block_rounds):
        if it >= max_iter or time.perf_counter() > deadline:
            break
        kept = [j for j, k in zip(W, positive) if k]
        count = np.bincount(row_var[kept], minlength=n_var) if kept else np.zeros(n_var, int)
        added: list[int] = []
        for i in viol[np.argsort(slack[viol])]:
            v = row_var[i]
            if count[v] < 2:
                count[v] += 1
                added.append(int(i))
        if not added and len(kept) == len(W):
            break
        it += 1
        ev = evaluate(kept + added)
        if ev is None:
            break
        W, gw, lam, slack, viol, positive, score = ev
        if score == 0:
            return W, lam, it, _AS_OPTIMAL
    # Dual-feasible start: positive multipliers on W, slack 0 on W.
    chol = _chol(gw[W])
    while W:
        if chol is None:
            W, gw, lam = [], gw[:, :0], np.zeros(0)
            break
        lam = _dpotrs(chol, -s[W], lower=1)[0]
        keep = lam > 0.0
        if keep.all():
            break
        it += 1
        W = [j for j, k in zip(W, keep) if k]
        gw = gw[:, keep]
        chol = _chol(gw[W])
    if not W:
        lam, chol = np.zeros(0), np.zeros((0, 0))
    while True:
        if W:
            slack = s + gw @ lam
            slack[W] = np.inf  # active rows hold with equality (up to rounding)
        else:
            slack = s
        p = int(np.argmin(slack))
        wp = float(slack[p])
        if wp >= -tol:
            return W, lam, it, _AS_OPTIMAL
        if it >= max_iter or time.perf_counter() > deadline:
            return W, lam, it, _AS_CAPPED
        lam_p = 0.0
        gp = cols([p])[:, 0]
        gpp = gp[p]
        while True:  # add row p, dropping rows whose multiplier reaches zero on the way
            it += 1
            k = len(W)
            if k:
                gwp = gp[W]
                ell = _dtrtrs(chol, gwp, lower=1)[0]
                d = -_dtrtrs(chol, ell, lower=1, trans=1)[0]
                z = gpp - float(ell @ ell)
            else:
                ell = d = lam
                z = gpp
            t_full = -wp / z if z > 1e-12 * gpp else math.inf
            t_part, j_block = math.inf, -1
            if k:
                neg = np.flatnonzero(d < 0.0)
                if len(neg):
                    ratios = lam[neg] / -d[neg]
                    jj = int(np.argmin(ratios))
                    t_part, j_block = float(ratios[jj]), int(neg[jj])
            if t_full == math.inf and t_part == math.inf:
                return W, lam, it, _AS_INFEASIBLE
            if t_full <= t_part:
                lam = np.append(lam + t_full * d, lam_p + t_full) if k else np.array([lam_p + t_full])
                grown = np.zeros((k + 1, k + 1))
                grown[:k, :k] = chol
                grown[k, :k] = ell
                grown[k, k] = math.sqrt(z)
                chol = grown
                W.append(p)
                gw = np.column_stack([gw, gp])
                break
            lam = lam + t_part * d
            lam_p += t_part
            wp += t_part * z
            del W[j_block]
            lam = np.delete(lam, j_block)
            gw = np.delete(gw, j_block, axis=1)
            chol = _chol(gw[W]) if W else np.zeros((0, 0))
            if chol is None:  # numerically dependent after all: restart from this row set
                return W, lam, it, _AS_CAPPED
            if it >= max_iter or time.perf_counter() > deadline:
                W.append(p)
                lam = np.append(lam, lam_p)
                return W, lam, it, _AS_CAPPED


_NO_KEYS = np.zeros(0)
_NO_NORMALS = np.zeros((0, 2))


def _dual_active_set(
    hess_inv: FloatArray,
    normals: FloatArray,
    row_var: NDArray[np.intp],
    s: FloatArray,
    row_key: FloatArray,
    warm_history: Sequence[tuple[FloatArray, FloatArray]],
    warm_match: tuple[float, float],
    tol: float,
    max_iter: int,
    deadline: float,
) -> tuple[NDArray[np.int64], FloatArray, int, int]:
    """The dual active set on the condensed QP (rows ``normals[i] . p[row_var[i]] <= b_i``, ``H^-1`` the same
    for both axes, ``s = b - A p_free``), warm-started from the rows of this problem matching each remembered
    solution's active rows (``warm_history``, newest first, at most two: (row keys, normals (k, 2));
    ``warm_match``: key tolerance, normal cosine). Compiled without a wall-time limit (``deadline`` inf), else
    :func:`_dual_active_set_numpy`. Returns ``(W, lam, iterations, outcome)``."""
    time_tol, cos_min = warm_match
    if math.isinf(deadline) and len(warm_history) <= 2:
        (keys_a, nrm_a), (keys_b, nrm_b) = (list(warm_history) + [(_NO_KEYS, _NO_NORMALS)] * 2)[:2]
        return active_set_kernel.dual_active_set(
            hess_inv, normals, row_var, s, row_key, keys_a, nrm_a, keys_b, nrm_b, len(warm_history), time_tol,
            cos_min, tol, max_iter, 4)
    h_rows = hess_inv[row_var]

    def cols(j: Sequence[int]) -> FloatArray:
        return h_rows[:, row_var[j]] * (normals @ normals[j].T)

    def matched(entry: tuple[FloatArray, FloatArray]) -> list[int]:
        key_prev, n_prev = entry
        if len(key_prev) == 0:
            return []
        return match_rows(row_key, normals, key_prev, n_prev, time_tol, cos_min).tolist()

    warm = (matched(entry) for entry in warm_history)  # matched lazily
    active, lam, iterations, outcome = _dual_active_set_numpy(cols, s, warm, row_var, tol, max_iter, deadline)
    return np.asarray(active, dtype=np.int64), lam, iterations, outcome
