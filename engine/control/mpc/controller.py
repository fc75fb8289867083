"""The CoM MPC: builds, condenses and solves one QP per planner tick, with warm starts, an OSQP or
maintained-backend alternative and finite fallbacks."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

from engine.constants import GRAVITY_MPS2
from engine.control import qp_backends
from engine.control.mpc.active_set import (
    _AS_CAPPED,
    _AS_INFEASIBLE,
    _AS_OPTIMAL,
    _NO_KEYS,
    _NO_NORMALS,
    _dual_active_set,
    _inverse,
)
from engine.control.mpc.active_set_kernel import (
    WINDOW_PLANNED,
    free_slacks,
    plan_window,
    solve_window,
    waypoints_from_multipliers,
)
from engine.control.mpc.kernels import (
    condense,
    match_rows,
    plan_from_waypoints,
    plan_is_finite,
    problem_rows,
    window_intervals,
)
from engine.control.mpc.lip import _Segments, propagate_lip
from engine.control.mpc.problem import _Condensed, _Problem
from engine.control.mpc.regions import (
    _CONTAIN_TOL_M,
    _make_region,
    _Region,
    _support_geometry_complex,
    _support_geometry_xy,
)
from engine.control.mpc.types import (
    CONSTRAINT_TOL_M,
    FALLBACK_COM_HEIGHT_M,
    MAX_STABILITY_WEIGHT,
    MIN_POLYGON_AREA_M2,
    ComMpcSolution,
    ComMpcWeights,
    SupportPhase,
)
from engine.geometry.polygon import clip_convex_polygons, convex_hull, polygon_centroid

FloatArray = NDArray[np.float64]
_ROW_WAYPOINTS: dict[tuple[int, int], NDArray[np.intp]] = {}


def _row_waypoints(n_int: int, n_v: int) -> NDArray[np.intp]:
    """Waypoint index of each row slot: per interval ``n_v`` midpoint slots, ``2 n_v`` end slots."""
    key = (n_int, n_v)
    out = _ROW_WAYPOINTS.get(key)
    if out is None:
        out = (2 * np.arange(n_int)[:, None] + np.repeat([1, 2], [n_v, 2 * n_v])[None, :]).ravel()
        _ROW_WAYPOINTS[key] = out
    return out


class ComMpc:
    """CoM/CoP MPC over a preview window (condensed, well-conditioned QP; dense dual active set).

    Parameters
    ----------
    preview_s : float
        Preview window ``T`` [s].
    weights : ComMpcWeights, optional
        Objective weights.
    max_intervals, max_halfplanes : int
        Initial workspace size (support intervals per window, half-planes per polygon);
        grown on demand.  For ``solver="osqp"`` this is the padded sparsity pattern.
    max_interval_s : float
        Supports longer than this are split into equal pieces (same polygon) [s].
    min_velocity_dt_s : float
        Lower bound on the waypoint spacing used in the CoP velocity cost [s]; keeps the
        cost bounded when an interval has almost elapsed.
    min_interval_s : float
        Intervals (or truncated remainders) shorter than this are skipped [s].
    eps_abs, eps_rel, polish
        OSQP settings, used by ``solver="osqp"`` only (the active-set solution is exact).
    max_iter : int or None
        Iteration cap (``None``: 100 active-set steps -- closed-loop problems need 0-3,
        cold starts after large pushes up to ~70, ~40 us each --, 4000 OSQP
        iterations).  When it is reached the current iterate, pulled into the polygons,
        is returned as ``"solved_inaccurate"`` (a finite, feasible, CoM-consistent plan)
        instead of a fallback.
    time_limit_s : float or None
        Same, as a wall-time limit on the QP solve [s] (``None``: no limit).
    solver : {"active_set", "osqp", "daqp", "proxsuite", "quadprog"}
        QP solver of the condensed problem.

    Attributes
    ----------
    setup_count : int
        Number of solver workspace setups so far (1 + the number of workspace growths;
        for OSQP the ``setup`` calls).

    Notes
    -----
    ``supports`` must be in chronological order and are treated as contiguous: interval
    ``k`` spans ``[end_{k-1}, end_k]`` (the first one starts at ``t_now_s``).  Elapsed
    intervals are skipped, the last one is truncated at ``t_now_s + preview_s``; if the
    schedule ends earlier, the window ends with it.
    """

    def __init__(
        self,
        preview_s: float = 2.0,
        weights: ComMpcWeights | None = None,
        max_intervals: int = 10,
        max_halfplanes: int = 8,
        *,
        max_interval_s: float = 0.5,
        min_velocity_dt_s: float = 0.02,
        min_interval_s: float = 1e-3,
        eps_abs: float = 1e-6,
        eps_rel: float = 1e-6,
        max_iter: int | None = None,
        time_limit_s: float | None = None,
        polish: bool = True,
        solver: str = "active_set",
    ) -> None:
        if not (preview_s > 0.0 and math.isfinite(preview_s)):
            raise ValueError("preview_s must be positive")
        choices = ("active_set", "osqp", *(b for b in qp_backends.BACKENDS if b != "osqp"))
        if solver not in choices:
            raise ValueError(f"solver: expected one of {', '.join(choices)}, got {solver!r}")
        self.preview_s = float(preview_s)
        self.weights = weights if weights is not None else ComMpcWeights()
        w = self.weights
        values = [w.final_capture_point, w.cop_centroid, w.cop_velocity]
        if w.stability is not None:
            values.append(w.stability)
        if not all(math.isfinite(v) and v >= 0.0 for v in values):
            raise ValueError(f"weights must be finite and non-negative: {w}")
        self.solver = solver
        self.max_interval_s = float(max_interval_s) if max_interval_s > 0.0 else math.inf
        self.min_velocity_dt_s = float(min_velocity_dt_s)
        self.min_interval_s = max(float(min_interval_s), 1e-6)
        default_iter = 100 if solver == "active_set" else 4000
        self.max_iter = max(int(max_iter), 1) if max_iter is not None else default_iter
        self.time_limit_s = float(time_limit_s) if time_limit_s else math.inf
        self._osqp_settings: dict[str, float | int | bool] = dict(
            eps_abs=eps_abs,
            eps_rel=eps_rel,
            max_iter=self.max_iter,
            time_limit=self.time_limit_s if math.isfinite(self.time_limit_s) else 1e10,
            polishing=polish,
            verbose=False,
            warm_starting=True,
            adaptive_rho_interval=25,  # fixed interval: deterministic (the default is time based)
            check_termination=5,
        )
        self._max_intervals = max(int(max_intervals), 1)
        self._max_halfplanes = max(int(max_halfplanes), 3)
        self.setup_count = 0
        self._last_good: ComMpcSolution | None = None
        self._warm_history: list[tuple[FloatArray, FloatArray]] = []  # (row keys, normals (k, 2))
        self._setup()

    # ------------------------------------------------------------ public API

    @property
    def padded_shape(self) -> tuple[int, int]:
        """Current workspace size ``(max_intervals, max_halfplanes)``."""
        return self._max_intervals, self._max_halfplanes

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts cold."""
        self._last_good = None
        self._warm_history = []

    def solve(
        self,
        t_now_s: float,
        com_xy_m: ArrayLike,
        com_vel_xy_mps: ArrayLike,
        cop_xy_m: ArrayLike,
        com_height_m: float,
        supports: Sequence[SupportPhase],
    ) -> ComMpcSolution:
        """Plan CoP waypoints and the CoM over ``[t_now_s, t_now_s + preview_s]``.

        Never raises: invalid input or solver failure yield a fallback solution whose
        ``status`` says so (see :class:`ComMpcSolution`).
        """
        t_start = time.perf_counter()
        try:
            supports = list(supports)  # iterated more than once (problem, fallback)
        except TypeError:
            pass
        args = (t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m, supports)
        solution: ComMpcSolution | None = None
        try:
            solution = self._solve(*args, t_start=t_start)
        except Exception as exc:  # noqa: BLE001 - a controller must never raise
            try:
                solution = self._fallback(*args, reason="solver_failed", message=f"exception: {exc!r}", t_start=t_start)
            except Exception:  # noqa: BLE001
                solution = None
        if solution is not None and (solution.__dict__.get("_checked_finite", False) or _is_finite(solution)):
            return solution
        # Last resort (e.g. a diverged, overflowing state): hold the CoP, finite by construction.
        t_now, com, vel, cop, height, _ = _sanitize_state(*args[:5])
        hold = _hold_solution(t_now, com, vel, cop, height, self.preview_s)
        invalid = solution is not None and solution.status.startswith("invalid_input")
        status = "invalid_input_hold_fallback" if invalid else "solver_failed_hold_fallback"
        return _replace_status(hold, status, "non-finite plan", time.perf_counter() - t_start)

    # -------------------------------------------------------------- internals

    def _solve(
        self,
        t_now_s: float,
        com_xy_m: ArrayLike,
        com_vel_xy_mps: ArrayLike,
        cop_xy_m: ArrayLike,
        com_height_m: float,
        supports: Sequence[SupportPhase],
        *,
        t_start: float,
    ) -> ComMpcSolution:
        if self.solver == "active_set" and math.isinf(self.time_limit_s):
            try:  # the one-call plan is only a shortcut: whatever it cannot do, the steps below do as before
                solution = self._solve_window(t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m, supports,
                                              t_start)
            except Exception:  # noqa: BLE001
                solution = None
            if solution is not None:
                return solution
        args = (t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m, supports)
        t_now, com, vel, cop, height, state_ok = _sanitize_state(*args[:5])
        if not state_ok:
            return self._fallback(*args, reason="invalid_input", message="non-finite or invalid state", t_start=t_start)
        problem, error = self._build_problem(t_now, supports)
        if problem is None:
            return self._fallback(*args, reason="invalid_input", message=error, t_start=t_start)

        omega = math.sqrt(GRAVITY_MPS2 / height)
        if self.solver == "active_set" and math.isinf(self.time_limit_s) and len(self._warm_history) <= 2:
            solution = self._solve_compiled(problem, omega, com, vel, cop, height, t_start)
            if solution is not None:
                return solution
        seg = _Segments.build(problem.times_s, omega)
        origin = cop  # QP frame: centred on the current CoP, so p_0 = 0
        qp = self._condense(problem, seg, origin, com + vel / seg.omega - origin)
        t_qp = time.perf_counter()
        deadline = t_qp + self.time_limit_s
        violation = math.nan  # not known yet
        if self.solver == "osqp":
            wps, iterations, outcome, message = self._solve_osqp(problem, qp, deadline)
        elif self.solver != "active_set":  # a maintained backend on the standard form
            result = qp_backends.solve(qp.standard_form(), self.solver)
            wps = result.x.reshape(-1, 2) if result.ok and result.x is not None else qp.p_free
            iterations, outcome, message = 0, (_AS_OPTIMAL if result.ok else _AS_INFEASIBLE), result.status
        else:
            wps, iterations, outcome, message, violation = self._solve_active_set(problem, qp, deadline)
        qp_time = time.perf_counter() - t_qp
        if outcome == _AS_CAPPED:  # best iterate: pull each waypoint into its region
            wps = _pull_into_regions(wps, qp, problem.centroids[1:] - origin)
        if math.isnan(violation):
            violation = 0.0
            if len(qp.rhs):
                violation = max(float((qp.row_values(wps) - qp.rhs).max()), 0.0) if np.isfinite(wps).all() else math.inf
        if outcome == _AS_INFEASIBLE or not violation <= CONSTRAINT_TOL_M:
            self._warm_history = []
            return self._fallback(
                *args,
                reason="solver_failed",
                message=message + (f", max constraint violation {violation:.2e} m" if math.isfinite(violation) else ""),
                t_start=t_start,
            )

        # CoP waypoints (the first one exactly the current CoP) and the CoM propagated, in the world frame
        wps_world, pos_world, vel_wp, final_state, total = plan_from_waypoints(
            seg.omega, seg.a, seg.b, seg.grow, np.ascontiguousarray(wps, dtype=np.float64), com, vel, origin)
        if outcome == _AS_CAPPED:
            status = "solved_inaccurate"
        elif problem.empty_intersection:
            status = "solved_empty_intersection"
        else:
            status = "solved"
        if problem.empty_intersection:
            message += "; empty support intersection: end waypoint constrained to the closing interval's polygon"
        solution = ComMpcSolution(
            waypoint_times_s=problem.times_s,
            waypoints_xy_m=wps_world,
            waypoint_com_xy_m=pos_world,
            waypoint_com_vel_xy_mps=vel_wp,
            com_height_m=height,
            status=status,
            solve_time_s=time.perf_counter() - t_start,
            message=message,
            osqp_iterations=int(iterations),
            osqp_time_s=qp_time,
            region_centroids_xy_m=problem.centroids,
            qp_final_state=final_state,
        )
        if not math.isfinite(total):
            return self._fallback(*args, reason="solver_failed", message="non-finite CoM", t_start=t_start)
        self._last_good = solution
        return solution

    def _solve_compiled(self, problem: _Problem, omega: float, com: FloatArray, vel: FloatArray, cop: FloatArray,
                        height: float, t_start: float) -> ComMpcSolution | None:
        """The default solve (active set, no wall-time limit) from the problem to the plan in one compiled call
        (:func:`engine.control.mpc.active_set_kernel.solve_window`: the steps of :meth:`_solve`, the same numbers).
        None unless it ends in a clean, finite optimum within the rows' tolerance: :meth:`_solve` then takes its
        step-by-step path (which computes the same and handles the rest)."""
        w = self.weights
        t_qp = time.perf_counter()
        history = self._warm_history
        (keys_a, nrm_a), (keys_b, nrm_b) = _two_newest(history)
        times = problem.times_s
        outcome, iterations, rows, violation, wps_world, pos_world, vel_wp, final_state, total, finite = solve_window(
            times, omega, float(w.cop_centroid), float(w.cop_velocity), self.min_velocity_dt_s,
            self._stability_weight(omega, float(times[-1] - times[0])), problem.centroids, problem.final_centroid,
            com, vel, cop, problem.normals, problem.offsets, problem.row_wp, problem.row_key, keys_a, nrm_a, keys_b,
            nrm_b, len(history), _WARM_TIME_TOL_S, _WARM_NORMAL_COS, _AS_TOL_M, self.max_iter, 4)
        qp_time = time.perf_counter() - t_qp
        if outcome != _AS_OPTIMAL or not violation <= CONSTRAINT_TOL_M or not finite:
            return None
        self._store_warm(problem, rows)
        return self._optimal_solution(times, wps_world, pos_world, vel_wp, height, int(iterations), len(rows),
                                      problem.empty_intersection, qp_time, problem.centroids, final_state, t_start)

    def _optimal_solution(self, times: FloatArray, wps_world: FloatArray, pos_world: FloatArray, vel_wp: FloatArray,
                          height: float, iterations: int, n_active: int, empty_intersection: bool, qp_time: float,
                          centroids: FloatArray, final_state: FloatArray, t_start: float) -> ComMpcSolution:
        """The plan of a clean, finite active-set optimum (the compiled paths :meth:`_solve_compiled` and
        :meth:`_solve_window`), kept as the last good one."""
        if iterations == 0:  # the free optimum holds every row: the active set did not run
            message = "active set: unconstrained optimum"
        else:
            message = f"active set: optimal, {n_active} active rows"
        status = "solved"
        if empty_intersection:
            status = "solved_empty_intersection"
            message += "; empty support intersection: end waypoint constrained to the closing interval's polygon"
        solution = ComMpcSolution(
            waypoint_times_s=times,
            waypoints_xy_m=wps_world,
            waypoint_com_xy_m=pos_world,
            waypoint_com_vel_xy_mps=vel_wp,
            com_height_m=height,
            status=status,
            solve_time_s=time.perf_counter() - t_start,
            message=message,
            osqp_iterations=iterations,
            osqp_time_s=qp_time,
            region_centroids_xy_m=centroids,
            qp_final_state=final_state,
        )
        object.__setattr__(solution, "_checked_finite", True)  # solve() need not check it again
        self._last_good = solution
        return solution

    def _solve_window(self, t_now_s: float, com_xy_m: ArrayLike, com_vel_xy_mps: ArrayLike, cop_xy_m: ArrayLike,
                      com_height_m: float, supports: Sequence[SupportPhase], t_start: float) -> ComMpcSolution | None:
        """The default solve (active set, no wall-time limit) from the supports to the plan in one compiled call
        (:func:`engine.control.mpc.active_set_kernel.plan_window`: :meth:`_build_problem` and :meth:`_solve_compiled`
        compiled together, the same numbers). None (nothing changed) for anything else than the usual input (a
        finite state of float arrays (2,), float polygons (M, 2)) solved to a clean optimum: :meth:`_solve` then
        takes its step-by-step path, which computes the same and handles the rest."""
        state = _state_floats(t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m)
        history = self._warm_history
        if state is None or len(history) > 2:
            return None
        try:
            polygons = [s.polygon for s in supports]
            # (start, end, vertex count) of each support: the times converted as _build_problem converts them
            table = np.array([(s.t_start_s, s.t_end_s, len(p)) for s, p in zip(supports, polygons)], dtype=float)
            points = np.concatenate(polygons, casting="no")  # float64 polygons only (no conversion)
        except (TypeError, ValueError, AttributeError):
            return None
        if table.ndim != 2 or table.shape[1] != 3 or points.dtype != np.float64 or points.ndim != 2 \
                or points.shape[1] != 2:
            return None
        (keys_a, nrm_a), (keys_b, nrm_b) = _two_newest(history)
        t_now, com_x, com_y, vel_x, vel_y, cop_x, cop_y, height = state
        w = self.weights
        t_qp = time.perf_counter()
        status, iterations, times, wps_world, pos_world, vel_wp, final_state, centroids, warm_keys, warm_normals = \
            plan_window(table, points, t_now, com_x, com_y, vel_x, vel_y, cop_x, cop_y,
                        height, GRAVITY_MPS2, self.preview_s, self.min_interval_s, self.max_interval_s,
                        float(w.cop_centroid), float(w.cop_velocity), self.min_velocity_dt_s,
                        float(w.final_capture_point), -1.0 if w.stability is None else float(w.stability),
                        MAX_STABILITY_WEIGHT, self._max_intervals, self._max_halfplanes, MIN_POLYGON_AREA_M2,
                        _CONTAIN_TOL_M, _WARM_KIND_OFFSET_S, keys_a, nrm_a, keys_b, nrm_b, len(history),
                        _WARM_TIME_TOL_S, _WARM_NORMAL_COS, _AS_TOL_M, self.max_iter, 4, CONSTRAINT_TOL_M)
        qp_time = time.perf_counter() - t_qp  # (the polygons' geometry and rows included: one compiled call)
        if status != WINDOW_PLANNED:
            return None
        self._remember_warm(warm_keys, warm_normals)
        return self._optimal_solution(times, wps_world, pos_world, vel_wp, height, int(iterations), len(warm_keys),
                                      False, qp_time, centroids, final_state, t_start)

    # ------------------------------------------------------------ geometry

    def _region(self, polygon: object) -> _Region:
        """Geometry of one polygon (reference path, used by the fallback plan)."""
        return _make_region(polygon)  # type: ignore[arg-type]

    def _build_problem(self, t_now: float, supports: Sequence[SupportPhase]) -> tuple[_Problem | None, str]:
        t_horizon = t_now + self.preview_s
        try:
            t_start = np.array([s.t_start_s for s in supports], dtype=float)
            t_end = np.array([s.t_end_s for s in supports], dtype=float)
        except (TypeError, ValueError, AttributeError) as exc:
            return None, f"malformed supports: {exc!r}"
        if t_start.ndim != 1 or t_end.shape != t_start.shape:
            return None, "malformed supports: support times must be scalars"
        # Supports in use (not elapsed, starting before the window ends; chronological order) and their
        # intervals (long ones split into equal pieces anchored at their start), compiled.
        status, bad_k, used, ends_arr, own = window_intervals(
            t_start, t_end, t_now, t_horizon, self.min_interval_s, self.max_interval_s)
        if status == 1:
            return None, f"invalid support interval times ({t_start[bad_k]}, {float(t_end[bad_k])})"
        if status == 2:
            return None, "no support interval covers the preview window"
        try:
            polygons = [supports[k].polygon for k in used.tolist()]
        except (TypeError, AttributeError, IndexError) as exc:
            return None, f"malformed supports: {exc!r}"
        geom_xy = _support_geometry_xy(polygons)
        if geom_xy is None:
            return None, "empty or degenerate support polygon"
        hull_xy, normals_xy, offsets, centroids_xy, max_h = geom_xy
        n_int = len(own)
        if n_int > self._max_intervals or max_h > self._max_halfplanes:
            # Grow with some headroom so that the window's usual fluctuation does not re-grow it.
            self._max_intervals = max(self._max_intervals, n_int + 2)
            self._max_halfplanes = max(self._max_halfplanes, max_h)
            self._setup()

        # End waypoints: C_k ∩ C_k+1 (consecutive supports nest in walking: the inner polygon), compiled.
        n_sup = len(used)
        overlap, normals, row_offsets, row_wp, row_key, times, centroids = problem_rows(
            own, n_sup, hull_xy, normals_xy, offsets, centroids_xy, ends_arr, t_now, _CONTAIN_TOL_M, _WARM_KIND_OFFSET_S)
        if overlap:  # an end waypoint needs the general intersection of two supports (rare): clip them
            geom = _support_geometry_complex(hull_xy, normals_xy, offsets, centroids_xy)
            return _problem_numpy(geom, own, n_sup, ends_arr, t_now), ""
        problem = _Problem(times, ends_arr, normals, normals.view(np.complex128)[:, 0], row_key, row_offsets, row_wp,
                           centroids, centroids_xy[own[-1]].copy(), False)
        return problem, ""

    # ---------------------------------------------------------- condensed QP

    def _setup(self) -> None:
        """(Re)size the solver workspace for the current ``padded_shape``."""
        self.setup_count += 1
        self._warm_history = []
        if self.solver == "osqp":
            self._build_osqp_pattern()

    def _stability_weight(self, omega: float, horizon_s: float) -> float:
        w = self.weights
        if w.stability is not None:
            return min(float(w.stability), MAX_STABILITY_WEIGHT)
        return min(w.final_capture_point * math.exp(min(2.0 * omega * horizon_s, 700.0)), MAX_STABILITY_WEIGHT)

    def _condense(self, pb: _Problem, seg: _Segments, origin: FloatArray, zeta0: FloatArray) -> _Condensed:
        """Eliminate the final state: cost and rows in the waypoints ``p_1..p_N`` (frame at ``origin``); compiled
        (:func:`engine.control.mpc.kernels.condense`), :meth:`_condense_numpy` is the reference."""
        w = self.weights
        ws = self._stability_weight(seg.omega, float(pb.times_s[-1] - pb.times_s[0]))
        d_mat, d_inv, g, beta, u, kappa, r0, p_free, hess_inv, rhs = condense(
            seg.a, seg.b, seg.grow, seg.h, float(w.cop_centroid), float(w.cop_velocity), self.min_velocity_dt_s, ws,
            pb.centroids, pb.final_centroid, origin, zeta0, pb.normals, pb.offsets)
        return _Condensed(
            origin, d_mat, d_inv, g, ws, beta, u, kappa, r0, p_free, hess_inv, pb.normals, rhs, pb.row_wp - 1
        )

    def _condense_numpy(self, pb: _Problem, seg: _Segments, origin: FloatArray, zeta0: FloatArray) -> _Condensed:
        """The reference of :meth:`_condense` (numpy, LAPACK's inverse of ``D``)."""
        w = self.weights
        n = len(pb.times_s) - 1
        decay = 1.0 / seg.grow  # exp(-omega tau_n)
        beta = decay[:-1] * seg.b  # b_{n-1} term of p_n, n = 1..N
        beta[:-1] += decay[1:-1] * seg.a[1:]  # a_n term, n = 1..N-1 (p_0 = 0 in this frame)
        wv = w.cop_velocity / np.maximum(seg.h, self.min_velocity_dt_s) ** 2
        diag = (w.cop_centroid + 1e-9) + wv  # tiny regularisation: D stays definite for zero weights
        diag[:-1] += wv[1:]
        d_mat = np.zeros((n, n))
        d_mat.flat[:: n + 1] = diag
        d_mat.flat[1 :: n + 1] = -wv[1:]
        d_mat.flat[n :: n + 1] = -wv[1:]
        d_inv = _inverse(d_mat)
        u = d_inv @ beta
        ws = self._stability_weight(seg.omega, float(pb.times_s[-1] - pb.times_s[0]))
        kappa = ws / (1.0 + ws * float(beta @ u))
        g = w.cop_centroid * (pb.centroids[1:] - origin)  # (the p_0 term of the velocity cost vanishes: p_0 = 0)
        r0 = zeta0 - decay[-1] * (pb.final_centroid - origin)
        y = d_inv @ g
        p_free = y + np.outer(u, kappa * (r0 - beta @ y))
        rhs = pb.offsets - pb.normals @ origin
        hess_inv = d_inv - np.outer(kappa * u, u)
        return _Condensed(
            origin, d_mat, d_inv, g, ws, beta, u, kappa, r0, p_free, hess_inv, pb.normals, rhs, pb.row_wp - 1
        )

    def _solve_active_set(
        self, pb: _Problem, qp: _Condensed, deadline: float
    ) -> tuple[FloatArray, int, int, str, float]:
        """Waypoints, iterations, outcome, message and the largest row violation of the waypoints."""
        s = free_slacks(qp.p_free, qp.normals, qp.row_var, qp.rhs)
        if len(s) == 0 or s.min() >= -_AS_TOL_M:
            self._store_warm(pb, np.zeros(0, dtype=np.intp))
            return qp.p_free, 0, _AS_OPTIMAL, "active set: unconstrained optimum", max(-float(s.min(initial=0.0)), 0.0)
        active, lam, iterations, outcome = _dual_active_set(
            qp.hess_inv, qp.normals, qp.row_var, s, pb.row_key, self._warm_history,
            (_WARM_TIME_TOL_S, _WARM_NORMAL_COS), _AS_TOL_M, self.max_iter, deadline)
        if outcome == _AS_INFEASIBLE:
            return qp.p_free, iterations, outcome, "active set: infeasible", math.nan
        rows = np.asarray(active, dtype=np.int64)
        wps, violation = waypoints_from_multipliers(qp.p_free, qp.hess_inv, qp.normals, qp.row_var, qp.rhs, rows,
                                                    np.asarray(lam, dtype=np.float64))
        if outcome == _AS_OPTIMAL:
            self._store_warm(pb, rows)
            return wps, iterations, outcome, f"active set: optimal, {len(rows)} active rows", violation
        return wps, iterations, outcome, "active set: iteration cap or time limit reached", math.nan

    def _store_warm(self, pb: _Problem, rows: NDArray[np.intp]) -> None:
        """Remember the active rows by waypoint time and kind (encoded together) and normal."""
        self._remember_warm(pb.row_key[rows], pb.normals[rows])

    def _remember_warm(self, keys: FloatArray, normals: FloatArray) -> None:
        """The newest active rows (keys, normals (k, 2)) first in the warm-start history."""
        self._warm_history = [(keys, normals)] + self._warm_history[: _WARM_HISTORY - 1]

    def _match_warm(self, pb: _Problem, entry: tuple[FloatArray, NDArray[np.complex128]]) -> list[int]:
        """Rows of this problem matching a remembered solution's active rows.

        A row matches an active row of the same waypoint kind (midpoint / end) within
        ``_WARM_TIME_TOL_S`` and with a parallel edge normal, so that shifted timings
        and moved footholds keep the warm start.
        """
        key_prev, n_prev = entry
        if len(key_prev) == 0:
            return []
        return match_rows(pb.row_key, pb.normals, key_prev, n_prev.view(np.float64).reshape(-1, 2),
                          _WARM_TIME_TOL_S, _WARM_NORMAL_COS).tolist()  # compiled: _match_warm_numpy's rows

    def _match_warm_numpy(self, pb: _Problem, entry: tuple[FloatArray, NDArray[np.complex128]]) -> list[int]:
        """The reference of :meth:`_match_warm`."""
        key_prev, n_prev = entry
        if len(key_prev) == 0:
            return []
        match = (np.abs(pb.row_key[:, None] - key_prev) < _WARM_TIME_TOL_S) & (
            (pb.normals_c[:, None].conj() * n_prev).real > _WARM_NORMAL_COS
        )
        return match.argmax(axis=0)[match.any(axis=0)].tolist()

    # ------------------------------------------------------------ OSQP backend

    def _build_osqp_pattern(self) -> None:
        """Padded sparsity pattern of the condensed QP for OSQP, and ``setup``.

        Variables ``[p_x (N_max), p_y (N_max), r_x, r_y]``; rows: the two stability
        residual equalities ``beta . p + r = r0`` then ``3 max_halfplanes`` polygon rows
        per interval (midpoint, then end waypoint).  Unused waypoints are pinned to 0 by
        a unit cost, unused rows are ``0 <= +inf``.
        """
        k_max, h_max = self._max_intervals, self._max_halfplanes
        nw = 2 * k_max
        n_var = 2 * nw + 2
        n_con = 2 + k_max * 3 * h_max
        self._osqp_nw = nw
        slot_wp = np.tile(np.repeat([0, 1], [h_max, 2 * h_max]), k_max) + np.repeat(2 * np.arange(k_max), 3 * h_max)
        self._osqp_slot_base = np.concatenate([[0], np.cumsum(np.bincount(slot_wp, minlength=nw))[:-1]])
        a_rows = np.concatenate(
            [np.zeros(nw + 1, int), np.ones(nw + 1, int), np.repeat(2 + np.arange(n_con - 2), 2)]
        )
        a_cols = np.concatenate(
            [np.r_[0:nw, 2 * nw], np.r_[nw : 2 * nw, 2 * nw + 1], np.stack([slot_wp, nw + slot_wp], axis=1).ravel()]
        )
        self._osqp_a_val = np.zeros(len(a_rows))
        self._osqp_a_perm, a_mat = _csc_pattern(a_rows, a_cols, (n_con, n_var))
        off = np.concatenate([np.arange(nw - 1), nw + np.arange(nw - 1)])
        p_rows = np.concatenate([np.arange(n_var), off])
        p_cols = np.concatenate([np.arange(n_var), off + 1])
        self._osqp_p_val = np.zeros(len(p_rows))
        self._osqp_p_perm, p_mat = _csc_pattern(p_rows, p_cols, (n_var, n_var))
        self._osqp_p_val[:n_var] = 1.0
        p_mat.data[:] = self._osqp_p_val[self._osqp_p_perm]
        self._osqp_a_val[:] = 1.0
        a_mat.data[:] = self._osqp_a_val[self._osqp_a_perm]
        self._osqp_l = np.full(n_con, -np.inf)
        self._osqp_u = np.full(n_con, np.inf)
        self._osqp_l[:2] = self._osqp_u[:2] = 0.0
        self._osqp = osqp.OSQP()
        self._osqp.setup(p_mat, np.zeros(n_var), a_mat, self._osqp_l, self._osqp_u, **self._osqp_settings)

    def _solve_osqp(self, pb: _Problem, qp: _Condensed, deadline: float) -> tuple[FloatArray, int, int, str]:
        nw = self._osqp_nw
        n = len(qp.beta)
        n_var = 2 * nw + 2
        # P: per axis D (diagonal, super-diagonal), W_s on r; padded waypoints pinned by a unit cost.
        d_mat = qp.d_mat
        pv = self._osqp_p_val
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
        av = self._osqp_a_val
        av[:] = 0.0
        av[:n] = qp.beta
        av[nw] = 1.0
        av[nw + 1 : nw + 1 + n] = qp.beta
        av[2 * nw + 1] = 1.0
        lo, up = self._osqp_l, self._osqp_u
        lo[:2] = up[:2] = qp.r0
        up[2:] = np.inf
        rv = qp.row_var
        ordinal = np.arange(len(rv)) - np.searchsorted(rv, rv)
        slots = self._osqp_slot_base[rv] + ordinal
        poly = av[2 * nw + 2 :].reshape(-1, 2)
        poly[slots] = qp.normals
        up[2 + slots] = qp.rhs
        self._osqp.update(q=q, l=lo, u=up, Px=pv[self._osqp_p_perm], Ax=av[self._osqp_a_perm])
        time_left = deadline - time.perf_counter()
        if math.isfinite(time_left):
            self._osqp.update_settings(time_limit=max(time_left, 1e-6))
        # Warm start: the previous plan's CoP at the new waypoint times (duals from zero).
        x0 = np.zeros(n_var)
        prev = self._last_good
        if prev is not None and prev.t_start_s <= pb.times_s[0] < prev.t_end_s:
            p_prev = prev.cop_at(pb.times_s[1:]) - qp.origin
            x0[:n] = p_prev[:, 0]
            x0[nw : nw + n] = p_prev[:, 1]
            x0[2 * nw : 2 * nw + 2] = qp.r0 - qp.beta @ p_prev
        self._osqp.warm_start(x=x0, y=np.zeros(len(lo)))
        res = self._osqp.solve(raise_error=False)
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

    def _fallback(
        self,
        t_now_s: float,
        com_xy_m: ArrayLike,
        com_vel_xy_mps: ArrayLike,
        cop_xy_m: ArrayLike,
        com_height_m: float,
        supports: Sequence[SupportPhase],
        *,
        reason: str,
        message: str,
        t_start: float,
    ) -> ComMpcSolution:
        """Previous good plan (if consistent with the state) or CoP at the region centroids, CoM integrated."""
        t_now, com, vel, cop, height, state_ok = _sanitize_state(
            t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m
        )
        prev = self._last_good
        if prev is not None and (not state_ok or _plan_matches_state(prev, t_now, com, vel, cop)):
            return _replace_status(prev, f"{reason}_previous_solution", message, time.perf_counter() - t_start)
        try:
            solution = self._centroid_plan(t_now, com, vel, cop, height, state_ok, supports)
        except Exception as exc:  # noqa: BLE001
            message += f"; centroid fallback failed: {exc!r}"
            solution = _hold_solution(t_now, com, vel, cop, height, self.preview_s)
        return _replace_status(solution, f"{reason}_centroid_fallback", message, time.perf_counter() - t_start)

    def _centroid_plan(
        self,
        t_now: float,
        com: FloatArray,
        vel: FloatArray,
        cop: FloatArray,
        height: float,
        state_ok: bool,
        supports: Sequence[SupportPhase],
    ) -> ComMpcSolution:
        """Safe plan: CoP waypoints at their regions' centroids (from the current CoP), CoM integrated exactly."""
        t_horizon = t_now + self.preview_s
        times = [t_now]
        regions: list[_Region] = []
        prev_end = t_now
        for s in supports:
            try:
                t1 = float(s.t_end_s)
            except (TypeError, ValueError, AttributeError):
                continue
            if not math.isfinite(t1) or t1 <= prev_end + self.min_interval_s:
                continue
            if prev_end >= t_horizon - self.min_interval_s:
                break
            end = min(t1, t_horizon)
            regions.append(self._region(getattr(s, "polygon", None)))
            times += [0.5 * (prev_end + end), end]
            prev_end = end
        if not state_ok:
            first_valid = next((r for r in regions if r.valid), None)
            if first_valid is not None:  # no usable state: start at rest over the support
                cop = first_valid.centroid.copy()
                com, vel = cop.copy(), np.zeros(2)
        if not regions:
            return _hold_solution(t_now, com, vel, cop, height, self.preview_s)
        points = [cop]
        for k, region in enumerate(regions):
            mid = region.centroid if region.valid else points[-1]
            end_wp = mid
            nxt = regions[k + 1] if k + 1 < len(regions) else None
            if region.valid and nxt is not None and nxt.valid:
                inter = clip_convex_polygons(region.hull, nxt.hull)
                end_wp = polygon_centroid(inter) if len(inter) else mid
            points += [mid, end_wp]
        wps = np.array(points)
        t_arr = np.array(times)
        pos, vel_wp = propagate_lip(t_arr, wps - com, np.zeros(2), vel, math.sqrt(GRAVITY_MPS2 / height))
        return ComMpcSolution(t_arr, wps, pos + com, vel_wp, height, "", 0.0)


def _problem_numpy(geom, own, n_sup, ends_arr, t_now):  # noqa: ANN001, ANN202
    """The rows of one call's QP from its supports' geometry (numpy; :func:`problem_rows` computes the same
    numbers compiled and hands the calls whose end waypoints need a general intersection to this)."""
    n_int = len(own)
    # End waypoints: C_k ∩ C_k+1.  Consecutive supports nest in walking (a foot inside
    # the double-support hull): the intersection is the inner polygon.  Otherwise both
    # polygons' rows are stacked (clipped only for the centroid and the empty check).
    nrm, off, hull, cent = geom.normals, geom.offsets, geom.hull, geom.centroids
    nxt = np.append(own[1:], own[-1])
    switch = nxt != own  # the interval closes its support
    if n_sup > 1:
        # max over (half-plane of one polygon, vertex of the other) of the signed distance
        inner_b = ((nrm[:-1, :, None].conj() * hull[1:, None, :]).real - off[:-1, :, None]).max(axis=(1, 2))
        inner_a = ((nrm[1:, :, None].conj() * hull[:-1, None, :]).real - off[1:, :, None]).max(axis=(1, 2))
        pair = np.minimum(own, n_sup - 2)
        in_a = inner_a[pair] <= _CONTAIN_TOL_M  # C_k ⊂ C_k+1: the intersection is C_k
        in_b = inner_b[pair] <= _CONTAIN_TOL_M  # C_k+1 ⊂ C_k: it is C_k+1
        use_b = switch & ~in_a
        use_a = ~(use_b & in_b)
    else:
        use_a, use_b = np.ones(n_int, bool), np.zeros(n_int, bool)
    end_centroids = np.where(use_a, cent[own], cent[nxt])
    empty = False
    for i in np.flatnonzero(use_a & use_b):  # general overlap (rare)
        k = own[i]
        hull_a = convex_hull(np.stack([hull[k].real, hull[k].imag], axis=1))
        hull_b = convex_hull(np.stack([hull[k + 1].real, hull[k + 1].imag], axis=1))
        inter = clip_convex_polygons(hull_a, hull_b)
        if len(inter) == 0:  # fall back to C_k alone
            use_b[i] = False
            empty = True
        else:
            c = polygon_centroid(inter)
            end_centroids[i] = c[0] + 1j * c[1]

    # Rows, per interval: V midpoint slots (C_k), then 2V end slots (C_k, C_k+1);
    # unused slots (+inf offsets) are dropped.
    n_v = off.shape[1]
    off_all = np.concatenate(
        [off[own], np.where(use_a[:, None], off[own], np.inf), np.where(use_b[:, None], off[nxt], np.inf)], axis=1
    ).ravel()
    nrm_all = np.concatenate([nrm[own], nrm[own], nrm[nxt]], axis=1).ravel()
    keep = off_all < np.inf
    wp_all = _row_waypoints(n_int, n_v)

    times = np.empty(2 * n_int + 1)
    times[0] = t_now
    times[2::2] = ends_arr
    times[1::2] = 0.5 * (times[0:-1:2] + ends_arr)
    centroids = np.empty(2 * n_int + 1, np.complex128)
    centroids[0] = cent[own[0]]
    centroids[1::2] = cent[own]
    centroids[2::2] = end_centroids
    final = cent[own[-1]]
    nrm_c = nrm_all[keep]
    row_wp = wp_all[keep]
    problem = _Problem(
        times,
        ends_arr,
        nrm_c.view(np.float64).reshape(-1, 2),
        nrm_c,
        times[row_wp] + _WARM_KIND_OFFSET_S * (row_wp & 1),
        off_all[keep],
        row_wp,
        centroids.view(np.float64).reshape(-1, 2),
        np.array([final.real, final.imag]),
        empty,
    )
    return problem


# ------------------------------------------------------------------ utilities

#: Active-set feasibility tolerance on the polygon rows [m].
_AS_TOL_M = 1e-9
#: Warm start: a previous active row matches a row of a waypoint of the same kind
#: (midpoint / end) within this time [s] and with an edge normal this parallel.
_WARM_TIME_TOL_S = 0.03
_WARM_KIND_OFFSET_S = 1e3  # separates midpoints from end points in the matching key
#: Number of previous solutions whose active rows are tried as warm starts.
_WARM_HISTORY = 2
_WARM_NORMAL_COS = 0.999


def _pull_into_regions(wps: FloatArray, qp: _Condensed, centroids: FloatArray) -> FloatArray:
    """Move each waypoint (N, 2) along the segment to its centroid target until its rows hold."""
    rv = qp.row_var
    c = centroids[rv]
    num = np.maximum(qp.rhs - np.einsum("ij,ij->i", qp.normals, c), 0.0)
    den = np.einsum("ij,ij->i", qp.normals, wps[rv] - c)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(den > 0.0, num / den, np.inf)
    scale = np.ones(len(wps))
    np.minimum.at(scale, rv, ratio)
    scale = np.clip(scale, 0.0, 1.0)
    return centroids + scale[:, None] * (wps - centroids)


def _csc_pattern(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, sp.csc_matrix]:
    """CSC matrix with explicit (zero) entries at (rows, cols) and the canonical->CSC permutation."""
    perm = np.lexsort((rows, cols))
    r, c = rows[perm], cols[perm]
    if len(r) > 1 and np.any((np.diff(r) == 0) & (np.diff(c) == 0)):
        raise RuntimeError("duplicate entries in sparsity pattern")
    indptr = np.concatenate([[0], np.cumsum(np.bincount(c, minlength=shape[1]))])
    mat = sp.csc_matrix((np.zeros(len(r)), r.astype(np.int64), indptr.astype(np.int64)), shape=shape)
    return perm, mat


def _two_newest(history: list) -> list:
    """The warm-start history's two newest entries, padded with empty ones (what the compiled solves take)."""
    return (list(history) + [(_NO_KEYS, _NO_NORMALS)] * 2)[:2]


def _state_floats(t_now_s: object, com_xy_m: object, com_vel_xy_mps: object, cop_xy_m: object,
                  com_height_m: object) -> tuple[float, float, float, float, float, float, float, float] | None:
    """The usual input of :meth:`ComMpc.solve` as floats ``(t, com, vel, cop, height)``: a finite time and height
    above 1 mm (Python or numpy floats) and finite float arrays (2,), the numbers :func:`_sanitize_state` passes
    on; None for anything else (:func:`_sanitize_state` then handles it)."""
    scalar = (float, int, np.float64, np.float32)
    if type(t_now_s) not in scalar or type(com_height_m) not in scalar:
        return None
    values = [float(t_now_s)]  # type: ignore[arg-type]
    for v in (com_xy_m, com_vel_xy_mps, cop_xy_m):
        if type(v) is not np.ndarray or v.dtype != np.float64 or v.shape != (2,):
            return None
        values += v.tolist()
    height = float(com_height_m)  # type: ignore[arg-type]
    values.append(height)
    if not height > 1e-3:
        return None
    if not math.isfinite(sum(values)) and not all(math.isfinite(x) for x in values):  # (a finite sum can overflow)
        return None
    return tuple(values)  # type: ignore[return-value]


def _sanitize_state(
    t_now_s: float, com_xy_m: ArrayLike, com_vel_xy_mps: ArrayLike, cop_xy_m: ArrayLike, com_height_m: float
) -> tuple[float, FloatArray, FloatArray, FloatArray, float, bool]:
    """Finite versions of the inputs and whether the originals were all valid."""

    def vec2(v: ArrayLike) -> tuple[FloatArray, bool]:
        if type(v) is np.ndarray and v.dtype == np.float64 and v.shape == (2,):  # the usual case, fast
            x, y = v.tolist()
            if math.isfinite(x) and math.isfinite(y):
                return v.copy(), True
        try:
            arr = np.asarray(v, dtype=float).reshape(2)
        except (TypeError, ValueError):
            return np.zeros(2), False
        ok = bool(np.isfinite(arr).all())
        return (arr.copy() if ok else np.nan_to_num(arr, nan=0.0, posinf=0.0, neginf=0.0)), ok

    try:
        t_now = float(t_now_s)
    except (TypeError, ValueError):
        t_now = math.nan
    t_ok = math.isfinite(t_now)
    com, com_ok = vec2(com_xy_m)
    vel, vel_ok = vec2(com_vel_xy_mps)
    cop, cop_ok = vec2(cop_xy_m)
    try:
        height = float(com_height_m)
    except (TypeError, ValueError):
        height = math.nan
    h_ok = math.isfinite(height) and height > 1e-3
    if not cop_ok and com_ok:
        cop = com.copy()
    if not com_ok and cop_ok:
        com = cop.copy()
    ok = t_ok and com_ok and vel_ok and cop_ok and h_ok
    return (t_now if t_ok else 0.0), com, vel, cop, (height if h_ok else FALLBACK_COM_HEIGHT_M), ok


def _plan_matches_state(plan: ComMpcSolution, t_now: float, com: FloatArray, vel: FloatArray, cop: FloatArray) -> bool:
    if not (plan.t_start_s <= t_now < plan.t_end_s):
        return False
    pos_p, vel_p, _ = plan.com_at(t_now)
    return bool(
        np.linalg.norm(pos_p - com) < 0.01
        and np.linalg.norm(vel_p - vel) < 0.05
        and np.linalg.norm(plan.cop_at(t_now) - cop) < 0.01
    )


def _hold_solution(
    t_now: float, com: FloatArray, vel: FloatArray, cop: FloatArray, height: float, preview_s: float
) -> ComMpcSolution:
    times = np.array([t_now, t_now + preview_s])
    wps = np.vstack([cop, cop])
    pos, vel_wp = propagate_lip(times, wps - com, np.zeros(2), vel, math.sqrt(GRAVITY_MPS2 / height))
    if not (np.isfinite(pos).all() and np.isfinite(vel_wp).all()):
        pos, vel_wp = np.zeros((2, 2)), np.zeros((2, 2))
    return ComMpcSolution(times, wps, pos + com, vel_wp, height, "", 0.0)


def _is_finite(sol: ComMpcSolution) -> bool:
    """Whether all the plan's numbers are finite (compiled: :func:`engine.control.mpc.kernels.plan_is_finite`)."""
    c = np.ascontiguousarray
    return bool(plan_is_finite(c(sol.waypoint_times_s, np.float64), c(sol.waypoints_xy_m, np.float64),
                               c(sol.waypoint_com_xy_m, np.float64), c(sol.waypoint_com_vel_xy_mps, np.float64),
                               c(sol.qp_final_state, np.float64), float(sol.com_height_m)))


def _replace_status(sol: ComMpcSolution, status: str, message: str, solve_time_s: float) -> ComMpcSolution:
    final_state = sol.qp_final_state
    if not np.isfinite(final_state).all():  # fallback plans: the propagated final state
        final_state = np.concatenate([sol.waypoint_com_xy_m[-1], sol.waypoint_com_vel_xy_mps[-1]])
    return dataclasses.replace(
        sol, status=status, message=message, solve_time_s=solve_time_s, qp_final_state=final_state
    )
