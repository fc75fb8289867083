"""OSQP on the condensed CoM-MPC QP (``ComMpc(solver="osqp")``): one padded sparsity pattern per workspace size,
set up once and updated in place each call; the maintained alternative to the dense active set."""

from __future__ import annotations

import math
import time

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray

from engine.control.mpc.active_set import _AS_CAPPED, _AS_INFEASIBLE, _AS_OPTIMAL
from engine.control.mpc.problem import _Condensed, _Problem
from engine.control.mpc.types import ComMpcSolution

FloatArray = NDArray[np.float64]


class PaddedOsqp:
    """An OSQP workspace for problems up to ``max_intervals`` support intervals of ``max_halfplanes`` rows."""

    def __init__(self, max_intervals: int, max_halfplanes: int, settings: dict[str, float | int | bool]) -> None:
        """Padded sparsity pattern of the condensed QP for OSQP, and ``setup``.

        Variables ``[p_x (N_max), p_y (N_max), r_x, r_y]``; rows: the two stability
        residual equalities ``beta . p + r = r0`` then ``3 max_halfplanes`` polygon rows
        per interval (midpoint, then end waypoint).  Unused waypoints are pinned to 0 by
        a unit cost, unused rows are ``0 <= +inf``.
        """
        k_max, h_max = max_intervals, max_halfplanes
        nw = 2 * k_max
        n_var = 2 * nw + 2
        n_con = 2 + k_max * 3 * h_max
        self._nw = nw
        slot_wp = np.tile(np.repeat([0, 1], [h_max, 2 * h_max]), k_max) + np.repeat(2 * np.arange(k_max), 3 * h_max)
        self._slot_base = np.concatenate([[0], np.cumsum(np.bincount(slot_wp, minlength=nw))[:-1]])
        a_rows = np.concatenate(
            [np.zeros(nw + 1, int), np.ones(nw + 1, int), np.repeat(2 + np.arange(n_con - 2), 2)]
        )
        a_cols = np.concatenate(
            [np.r_[0:nw, 2 * nw], np.r_[nw : 2 * nw, 2 * nw + 1], np.stack([slot_wp, nw + slot_wp], axis=1).ravel()]
        )
        self._a_val = np.zeros(len(a_rows))
        self._a_perm, a_mat = _csc_pattern(a_rows, a_cols, (n_con, n_var))
        off = np.concatenate([np.arange(nw - 1), nw + np.arange(nw - 1)])
        p_rows = np.concatenate([np.arange(n_var), off])
        p_cols = np.concatenate([np.arange(n_var), off + 1])
        self._p_val = np.zeros(len(p_rows))
        self._p_perm, p_mat = _csc_pattern(p_rows, p_cols, (n_var, n_var))
        self._p_val[:n_var] = 1.0
        p_mat.data[:] = self._p_val[self._p_perm]
        self._a_val[:] = 1.0
        a_mat.data[:] = self._a_val[self._a_perm]
        self._l = np.full(n_con, -np.inf)
        self._u = np.full(n_con, np.inf)
        self._l[:2] = self._u[:2] = 0.0
        self._solver = osqp.OSQP()
        self._solver.setup(p_mat, np.zeros(n_var), a_mat, self._l, self._u, **settings)

    def solve(self, pb: _Problem, qp: _Condensed, deadline: float,
              previous: ComMpcSolution | None) -> tuple[FloatArray, int, int, str]:
        """Waypoints, iterations, outcome and message; warm-started from ``previous`` (the last good plan)."""
        nw = self._nw
        n = len(qp.beta)
        n_var = 2 * nw + 2
        # P: per axis D (diagonal, super-diagonal), W_s on r; padded waypoints pinned by a unit cost.
        d_mat = qp.d_mat
        pv = self._p_val
        pv[:] = 0.0
        pv[: 2 * nw] = 1.0
        for ax in (0, nw):
            pv[ax : ax + n] = np.diag(d_mat)
            pv[n_var + (ax // nw) * (nw - 1) + np.arange(n - 1)] = np.diag(d_mat, 1)
        pv[2 * nw : 2 * nw + 2] = qp.stability_weight
        q = np.zeros(n_var)
        q[:n] = -qp.g[:, 0]
        q[nw : nw + n] = -qp.g[:, 1]
        # A: residual rows then polygon rows in their padded slots.
        av = self._a_val
        av[:] = 0.0
        av[:n] = qp.beta
        av[nw] = 1.0
        av[nw + 1 : nw + 1 + n] = qp.beta
        av[2 * nw + 1] = 1.0
        lo, up = self._l, self._u
        lo[:2] = up[:2] = qp.r0
        up[2:] = np.inf
        rv = qp.row_var
        ordinal = np.arange(len(rv)) - np.searchsorted(rv, rv)
        slots = self._slot_base[rv] + ordinal
        poly = av[2 * nw + 2 :].reshape(-1, 2)
        poly[slots] = qp.normals
        up[2 + slots] = qp.rhs
        self._solver.update(q=q, l=lo, u=up, Px=pv[self._p_perm], Ax=av[self._a_perm])
        time_left = deadline - time.perf_counter()
        if math.isfinite(time_left):
            self._solver.update_settings(time_limit=max(time_left, 1e-6))
        # Warm start: the previous plan's CoP at the new waypoint times (duals from zero).
        x0 = np.zeros(n_var)
        prev = previous
        if prev is not None and prev.t_start_s <= pb.times_s[0] < prev.t_end_s:
            p_prev = prev.cop_at(pb.times_s[1:]) - qp.origin
            x0[:n] = p_prev[:, 0]
            x0[nw : nw + n] = p_prev[:, 1]
            x0[2 * nw : 2 * nw + 2] = qp.r0 - qp.beta @ p_prev
        self._solver.warm_start(x=x0, y=np.zeros(len(lo)))
        res = self._solver.solve(raise_error=False)
        status = res.info.status_val
        it = int(res.info.iter)
        msg = f"osqp: {res.info.status}"
        if res.x is None or not np.isfinite(res.x).all():
            return qp.p_free, it, _AS_INFEASIBLE, msg
        wps = np.stack([res.x[:n], res.x[nw : nw + n]], axis=1)
        if status == osqp.SolverStatus.OSQP_SOLVED:
            return wps, it, _AS_OPTIMAL, msg
        if status in (
            osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
            osqp.SolverStatus.OSQP_MAX_ITER_REACHED,
            osqp.SolverStatus.OSQP_TIME_LIMIT_REACHED,
        ):
            return wps, it, _AS_CAPPED, msg
        return wps, it, _AS_INFEASIBLE, msg


def _csc_pattern(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, sp.csc_matrix]:
    """CSC matrix with explicit (zero) entries at (rows, cols) and the canonical->CSC permutation."""
    perm = np.lexsort((rows, cols))
    r, c = rows[perm], cols[perm]
    if len(r) > 1 and np.any((np.diff(r) == 0) & (np.diff(c) == 0)):
        raise RuntimeError("duplicate entries in sparsity pattern")
    indptr = np.concatenate([[0], np.cumsum(np.bincount(c, minlength=shape[1]))])
    mat = sp.csc_matrix((np.zeros(len(r)), r.astype(np.int64), indptr.astype(np.int64)), shape=shape)
    return perm, mat
