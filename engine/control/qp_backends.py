"""Quadratic-program backends behind one interface (the controllers' QPs in standard form).

    min ½ xᵀ H x + fᵀ x   s.t.   lb ≤ x ≤ ub,   A_eq x = b_eq,   c_lo ≤ C x ≤ c_up

The CoM MPC (:mod:`engine.control.mpc`) and the whole-body QP
(:mod:`engine.control.wbc`) each keep a hand-written dense active-set solver that
exploits their structure (Sherman–Morrison on the MPC's rank-one stiff term; closed-form
elimination of q̈ in the ID). Both QPs can also be handed to a maintained solver through
:func:`solve`: ``daqp``, ``proxsuite`` (dense ProxQP), ``quadprog`` (Goldfarb–Idnani), ``osqp``
(ADMM, through qpsolvers). ``studio bench qp`` measures all of them on recorded problems; the
hand-written solvers stay the defaults where that table shows they win.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
INF = 1e20  # "no bound" for solvers that want finite numbers


@dataclass
class QpProblem:
    """A QP in standard form (dense). Missing parts are ``None``; infinite bounds are allowed."""

    h: FloatArray  # (n, n) symmetric positive (semi-)definite
    f: FloatArray  # (n,)
    lb: FloatArray | None = None  # (n,)
    ub: FloatArray | None = None  # (n,)
    a_eq: FloatArray | None = None  # (m_eq, n)
    b_eq: FloatArray | None = None  # (m_eq,)
    c: FloatArray | None = None  # (m_in, n)
    c_lo: FloatArray | None = None  # (m_in,)
    c_up: FloatArray | None = None  # (m_in,)

    @property
    def n(self) -> int:
        return int(self.f.size)

    def bounds(self) -> tuple[FloatArray, FloatArray]:
        lb = np.full(self.n, -np.inf) if self.lb is None else self.lb
        ub = np.full(self.n, np.inf) if self.ub is None else self.ub
        return lb, ub

    def equalities(self) -> tuple[FloatArray, FloatArray] | None:
        """(A_eq, b_eq), or None when the problem has no equality rows."""
        if self.a_eq is None:
            return None
        assert self.b_eq is not None, "a_eq comes with b_eq"
        return self.a_eq, self.b_eq

    def inequalities(self) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """(C, c_lo, c_up), or None when the problem has no inequality rows."""
        if self.c is None:
            return None
        assert self.c_lo is not None and self.c_up is not None, "c comes with c_lo and c_up"
        return self.c, self.c_lo, self.c_up

    def violation(self, x: FloatArray) -> float:
        """Largest violation of any constraint at ``x``."""
        lb, ub = self.bounds()
        worst = max(float(np.max(lb - x, initial=0.0)), float(np.max(x - ub, initial=0.0)))
        eq, ineq = self.equalities(), self.inequalities()
        if eq is not None:
            a_eq, b_eq = eq
            worst = max(worst, float(np.max(np.abs(a_eq @ x - b_eq), initial=0.0)))
        if ineq is not None:
            c, c_lo, c_up = ineq
            cx = c @ x
            worst = max(worst, float(np.max(c_lo - cx, initial=0.0)), float(np.max(cx - c_up, initial=0.0)))
        return worst

    def objective(self, x: FloatArray) -> float:
        return float(0.5 * x @ self.h @ x + self.f @ x)


@dataclass
class QpResult:
    x: FloatArray | None
    ok: bool
    status: str = ""


def _finite(v: FloatArray) -> FloatArray:
    return np.clip(v, -INF, INF)


def _solve_daqp(p: QpProblem) -> QpResult:
    import daqp

    lb, ub = p.bounds()
    eq, ineq = p.equalities(), p.inequalities()
    rows_a: list[FloatArray] = []
    up_parts, lo_parts = [ub], [lb]
    if eq is not None:
        rows_a.append(eq[0])
        up_parts.append(eq[1])
        lo_parts.append(eq[1])
    if ineq is not None:
        rows_a.append(ineq[0])
        up_parts.append(ineq[2])
        lo_parts.append(ineq[1])
    a = np.vstack(rows_a) if rows_a else np.zeros((0, p.n))
    up = np.concatenate(up_parts)
    lo = np.concatenate(lo_parts)
    sense = np.zeros(up.size, dtype=np.int32)
    if eq is not None:
        sense[p.n:p.n + eq[0].shape[0]] = 5  # equality (active, immutable)
    x, _, flag, _ = daqp.solve(np.ascontiguousarray(p.h), p.f, np.ascontiguousarray(a), _finite(up), _finite(lo), sense)
    ok = flag in (1, 2) and bool(np.all(np.isfinite(x)))
    return QpResult(np.asarray(x) if ok else None, ok, f"daqp exitflag {flag}")


def _solve_proxsuite(p: QpProblem) -> QpResult:
    import proxsuite

    lb, ub = p.bounds()
    ineq = p.inequalities()
    c_rows, lo_parts, up_parts = [np.eye(p.n)], [lb], [ub]
    if ineq is not None:
        c_rows.append(ineq[0])
        lo_parts.append(ineq[1])
        up_parts.append(ineq[2])
    c = np.vstack(c_rows)
    lo = np.concatenate(lo_parts)
    up = np.concatenate(up_parts)
    res = proxsuite.proxqp.dense.solve(p.h, p.f, p.a_eq, p.b_eq, c, _finite(lo), _finite(up), eps_abs=1e-9, eps_rel=0.0,
                                       max_iter=2000)
    ok = res.info.status == proxsuite.proxqp.QPSolverOutput.PROXQP_SOLVED and bool(np.all(np.isfinite(res.x)))
    return QpResult(np.array(res.x) if ok else None, ok, str(res.info.status))


def _solve_quadprog(p: QpProblem) -> QpResult:
    import quadprog

    # quadprog: min ½xᵀGx − aᵀx  s.t.  Cᵀx ≥ b, the first meq rows equalities.
    lb, ub = p.bounds()
    cols: list[FloatArray] = []
    rhs: list[FloatArray] = []
    meq = 0
    eq, ineq = p.equalities(), p.inequalities()
    if eq is not None:
        cols.append(eq[0])
        rhs.append(eq[1])
        meq = eq[0].shape[0]
    fin_lb, fin_ub = np.isfinite(lb), np.isfinite(ub)
    eye = np.eye(p.n)
    cols += [eye[fin_lb], -eye[fin_ub]]
    rhs += [lb[fin_lb], -ub[fin_ub]]
    if ineq is not None:
        c, c_lo, c_up = ineq
        lo_ok, up_ok = np.isfinite(c_lo), np.isfinite(c_up)
        cols += [c[lo_ok], -c[up_ok]]
        rhs += [c_lo[lo_ok], -c_up[up_ok]]
    try:
        x = quadprog.solve_qp(p.h, -p.f, np.vstack(cols).T.copy(), np.concatenate(rhs), meq)[0]
    except ValueError as exc:  # "constraints are inconsistent" / "matrix G is not positive definite"
        return QpResult(None, False, f"quadprog: {exc}")
    return QpResult(x, bool(np.all(np.isfinite(x))), "quadprog")


def _solve_osqp(p: QpProblem) -> QpResult:
    import qpsolvers
    import scipy.sparse as sp

    lb, ub = p.bounds()
    g = h = None
    ineq = p.inequalities()
    if ineq is not None:  # qpsolvers: G x ≤ h
        c, c_lo, c_up = ineq
        lo_ok, up_ok = np.isfinite(c_lo), np.isfinite(c_up)
        g = sp.csc_matrix(np.vstack([c[up_ok], -c[lo_ok]]))
        h = np.concatenate([c_up[up_ok], -c_lo[lo_ok]])
    x = qpsolvers.solve_qp(sp.csc_matrix(p.h), p.f, g, h, None if p.a_eq is None else sp.csc_matrix(p.a_eq), p.b_eq,
                           _finite(lb), _finite(ub), solver="osqp", eps_abs=1e-7, eps_rel=1e-7, max_iter=20000,
                           polishing=False, verbose=False)
    ok = x is not None and bool(np.all(np.isfinite(x)))
    return QpResult(x if ok else None, ok, "osqp")


BACKENDS: dict[str, Callable[[QpProblem], QpResult]] = {
    "daqp": _solve_daqp, "proxsuite": _solve_proxsuite, "quadprog": _solve_quadprog, "osqp": _solve_osqp,
}


def solve(problem: QpProblem, backend: str) -> QpResult:
    """Solve ``problem`` with a maintained backend (see :data:`BACKENDS`). Never raises on a
    solver failure: the result says ``ok=False`` and why."""
    if backend not in BACKENDS:
        raise ValueError(f"qp backend: expected one of {', '.join(BACKENDS)}, got {backend!r}")
    try:
        return BACKENDS[backend](problem)
    except Exception as exc:  # noqa: BLE001 - a solver's own error is a failed solve
        return QpResult(None, False, f"{backend}: {type(exc).__name__}: {exc}")
