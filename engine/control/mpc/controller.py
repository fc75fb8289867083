"""The CoM MPC: builds, condenses and solves one QP per planner tick (warm starts: :mod:`.warm_start`; the OSQP
backend: :mod:`.osqp_backend`, the maintained ones: :mod:`engine.control.qp_backends`; finite fallbacks:
:mod:`.fallbacks`; the input state: :mod:`.state_input`)."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.constants import GRAVITY_MPS2
from engine.control import qp_backends
from engine.control.mpc.active_set import _AS_CAPPED, _AS_INFEASIBLE, _AS_OPTIMAL, _dual_active_set, _inverse
from engine.control.mpc.active_set_kernel import (
    WINDOW_PLANNED,
    free_slacks,
    plan_window,
    solve_window,
    waypoints_from_multipliers,
)
from engine.control.mpc.fallbacks import (
    centroid_plan,
    hold_solution,
    is_finite_plan,
    plan_matches_state,
    pull_into_regions,
    replace_status,
)
from engine.control.mpc.kernels import (
    condense,
    match_rows,
    plan_from_waypoints,
    problem_rows,
    window_intervals,
)
from engine.control.mpc.lip import _Segments
from engine.control.mpc.osqp_backend import PaddedOsqp
from engine.control.mpc.problem import _Condensed, _Problem, problem_numpy
from engine.control.mpc.regions import _CONTAIN_TOL_M, _support_geometry_complex, _support_geometry_xy
from engine.control.mpc.state_input import FLOAT64_DTYPE, sanitize_state, state_floats
from engine.control.mpc.types import (
    CONSTRAINT_TOL_M,
    MAX_STABILITY_WEIGHT,
    MIN_POLYGON_AREA_M2,
    ComMpcSolution,
    ComMpcWeights,
    SupportPhase,
)
from engine.control.mpc.warm_start import (
    WARM_HISTORY,
    WARM_KIND_OFFSET_S,
    WARM_NORMAL_COS,
    WARM_TIME_TOL_S,
    two_newest,
)

FloatArray = NDArray[np.float64]
#: Active-set feasibility tolerance on the polygon rows [m].
_AS_TOL_M = 1e-9

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
        self._osqp: PaddedOsqp | None = None  # solver="osqp": the padded workspace
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
        packed: tuple[FloatArray, FloatArray] | None = None,
    ) -> ComMpcSolution:
        """Plan CoP waypoints and the CoM over ``[t_now_s, t_now_s + preview_s]``.

        Never raises: invalid input or solver failure yield a fallback solution whose
        ``status`` says so (see :class:`ComMpcSolution`). ``packed``: the same supports packed as the one-call plan
        reads them, when the caller has them (:meth:`engine.gait.planner.GaitPlanner.packed_supports`): per support
        its start, end [s] and vertex count (n, 3) and the polygons' vertices one after the other (Σ counts, 2),
        float64; otherwise it builds them from ``supports`` (the same numbers).
        """
        t_start = time.perf_counter()
        try:
            supports = list(supports)  # iterated more than once (problem, fallback)
        except TypeError:
            pass
        args = (t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m, supports)
        solution: ComMpcSolution | None = None
        try:
            solution = self._solve(*args, t_start=t_start, packed=packed)
        except Exception as exc:  # noqa: BLE001 - a controller must never raise
            try:
                solution = self._fallback(*args, reason="solver_failed", message=f"exception: {exc!r}", t_start=t_start)
            except Exception:  # noqa: BLE001
                solution = None
        if solution is not None and (solution.__dict__.get("_checked_finite", False) or is_finite_plan(solution)):
            return solution
        # Last resort (e.g. a diverged, overflowing state): hold the CoP, finite by construction.
        t_now, com, vel, cop, height, _ = sanitize_state(*args[:5])
        hold = hold_solution(t_now, com, vel, cop, height, self.preview_s)
        invalid = solution is not None and solution.status.startswith("invalid_input")
        status = "invalid_input_hold_fallback" if invalid else "solver_failed_hold_fallback"
        return replace_status(hold, status, "non-finite plan", time.perf_counter() - t_start)

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
        packed: tuple[FloatArray, FloatArray] | None = None,
    ) -> ComMpcSolution:
        if self.solver == "active_set" and math.isinf(self.time_limit_s):
            try:  # the one-call plan is only a shortcut: whatever it cannot do, the steps below do as before
                solution = self._solve_window(t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m, supports,
                                              t_start, packed)
            except Exception:  # noqa: BLE001
                solution = None
            if solution is not None:
                return solution
        args = (t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m, supports)
        t_now, com, vel, cop, height, state_ok = sanitize_state(*args[:5])
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
        if self._osqp is not None:
            wps, iterations, outcome, message = self._osqp.solve(problem, qp, deadline, self._last_good)
        elif self.solver != "active_set":  # a maintained backend on the standard form
            result = qp_backends.solve(qp.standard_form(), self.solver)
            wps = result.x.reshape(-1, 2) if result.ok and result.x is not None else qp.p_free
            iterations, outcome, message = 0, (_AS_OPTIMAL if result.ok else _AS_INFEASIBLE), result.status
        else:
            wps, iterations, outcome, message, violation = self._solve_active_set(problem, qp, deadline)
        qp_time = time.perf_counter() - t_qp
        if outcome == _AS_CAPPED:  # best iterate: pull each waypoint into its region
            wps = pull_into_regions(wps, qp, problem.centroids[1:] - origin)
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
        (keys_a, nrm_a), (keys_b, nrm_b) = two_newest(history)
        times = problem.times_s
        outcome, iterations, rows, violation, wps_world, pos_world, vel_wp, final_state, total, finite = solve_window(
            times, omega, float(w.cop_centroid), float(w.cop_velocity), self.min_velocity_dt_s,
            self._stability_weight(omega, float(times[-1] - times[0])), problem.centroids, problem.final_centroid,
            com, vel, cop, problem.normals, problem.offsets, problem.row_wp, problem.row_key, keys_a, nrm_a, keys_b,
            nrm_b, len(history), WARM_TIME_TOL_S, WARM_NORMAL_COS, _AS_TOL_M, self.max_iter, 4)
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
                      com_height_m: float, supports: Sequence[SupportPhase], t_start: float,
                      packed: tuple[FloatArray, FloatArray] | None = None) -> ComMpcSolution | None:
        """The default solve (active set, no wall-time limit) from the supports to the plan in one compiled call
        (:func:`engine.control.mpc.active_set_kernel.plan_window`: :meth:`_build_problem` and :meth:`_solve_compiled`
        compiled together, the same numbers). None (nothing changed) for anything else than the usual input (a
        finite state of float arrays (2,), float polygons (M, 2)) solved to a clean optimum: :meth:`_solve` then
        takes its step-by-step path, which computes the same and handles the rest."""
        state = state_floats(t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m)
        history = self._warm_history
        if state is None or len(history) > 2:
            return None
        packed = _checked_packing(packed)
        if packed is not None and packed[0].shape[0] != len(supports):  # packed from other supports: not these
            packed = None
        if packed is None:  # not packed by the caller (the planner's preview): the same arrays built here
            try:
                polygons = [s.polygon for s in supports]
                # (start, end, vertex count) of each support: the times converted as _build_problem converts them
                packed = _checked_packing((
                    np.array([(s.t_start_s, s.t_end_s, len(p)) for s, p in zip(supports, polygons)], dtype=float),
                    np.concatenate(polygons, casting="no")))  # float64 polygons only (no conversion)
            except (TypeError, ValueError, AttributeError):
                return None
            if packed is None:
                return None
        table, points = packed
        (keys_a, nrm_a), (keys_b, nrm_b) = two_newest(history)
        t_now, com_x, com_y, vel_x, vel_y, cop_x, cop_y, height = state
        w = self.weights
        t_qp = time.perf_counter()
        status, iterations, times, wps_world, pos_world, vel_wp, final_state, centroids, warm_keys, warm_normals = \
            plan_window(table, points, t_now, com_x, com_y, vel_x, vel_y, cop_x, cop_y,
                        height, GRAVITY_MPS2, self.preview_s, self.min_interval_s, self.max_interval_s,
                        float(w.cop_centroid), float(w.cop_velocity), self.min_velocity_dt_s,
                        float(w.final_capture_point), -1.0 if w.stability is None else float(w.stability),
                        MAX_STABILITY_WEIGHT, self._max_intervals, self._max_halfplanes, MIN_POLYGON_AREA_M2,
                        _CONTAIN_TOL_M, WARM_KIND_OFFSET_S, keys_a, nrm_a, keys_b, nrm_b, len(history),
                        WARM_TIME_TOL_S, WARM_NORMAL_COS, _AS_TOL_M, self.max_iter, 4, CONSTRAINT_TOL_M)
        qp_time = time.perf_counter() - t_qp  # (the polygons' geometry and rows included: one compiled call)
        if status != WINDOW_PLANNED:
            return None
        self._remember_warm(warm_keys, warm_normals)
        return self._optimal_solution(times, wps_world, pos_world, vel_wp, height, int(iterations), len(warm_keys),
                                      False, qp_time, centroids, final_state, t_start)

    # ------------------------------------------------------------ geometry

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
            own, n_sup, hull_xy, normals_xy, offsets, centroids_xy, ends_arr, t_now, _CONTAIN_TOL_M, WARM_KIND_OFFSET_S)
        if overlap:  # an end waypoint needs the general intersection of two supports (rare): clip them
            geom = _support_geometry_complex(hull_xy, normals_xy, offsets, centroids_xy)
            return problem_numpy(geom, own, n_sup, ends_arr, t_now), ""
        problem = _Problem(times, ends_arr, normals, normals.view(np.complex128)[:, 0], row_key, row_offsets, row_wp,
                           centroids, centroids_xy[own[-1]].copy(), False)
        return problem, ""

    # ---------------------------------------------------------- condensed QP

    def _setup(self) -> None:
        """(Re)size the solver workspace for the current ``padded_shape``."""
        self.setup_count += 1
        self._warm_history = []
        if self.solver == "osqp":
            self._osqp = PaddedOsqp(self._max_intervals, self._max_halfplanes, self._osqp_settings)

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
            (WARM_TIME_TOL_S, WARM_NORMAL_COS), _AS_TOL_M, self.max_iter, deadline)
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
        self._warm_history = [(keys, normals)] + self._warm_history[: WARM_HISTORY - 1]

    def _match_warm(self, pb: _Problem, entry: tuple[FloatArray, NDArray[np.complex128]]) -> list[int]:
        """Rows of this problem matching a remembered solution's active rows.

        A row matches an active row of the same waypoint kind (midpoint / end) within
        ``WARM_TIME_TOL_S`` and with a parallel edge normal, so that shifted timings
        and moved footholds keep the warm start.
        """
        key_prev, n_prev = entry
        if len(key_prev) == 0:
            return []
        return match_rows(pb.row_key, pb.normals, key_prev, n_prev.view(np.float64).reshape(-1, 2),
                          WARM_TIME_TOL_S, WARM_NORMAL_COS).tolist()  # compiled: _match_warm_numpy's rows

    def _match_warm_numpy(self, pb: _Problem, entry: tuple[FloatArray, NDArray[np.complex128]]) -> list[int]:
        """The reference of :meth:`_match_warm`."""
        key_prev, n_prev = entry
        if len(key_prev) == 0:
            return []
        match = (np.abs(pb.row_key[:, None] - key_prev) < WARM_TIME_TOL_S) & (
            (pb.normals_c[:, None].conj() * n_prev).real > WARM_NORMAL_COS
        )
        return match.argmax(axis=0)[match.any(axis=0)].tolist()

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
        t_now, com, vel, cop, height, state_ok = sanitize_state(
            t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m
        )
        prev = self._last_good
        if prev is not None and (not state_ok or plan_matches_state(prev, t_now, com, vel, cop)):
            return replace_status(prev, f"{reason}_previous_solution", message, time.perf_counter() - t_start)
        try:
            solution = centroid_plan(t_now, com, vel, cop, height, state_ok, supports, self.preview_s, self.min_interval_s)
        except Exception as exc:  # noqa: BLE001
            message += f"; centroid fallback failed: {exc!r}"
            solution = hold_solution(t_now, com, vel, cop, height, self.preview_s)
        return replace_status(solution, f"{reason}_centroid_fallback", message, time.perf_counter() - t_start)


def _checked_packing(packed: object) -> tuple[FloatArray, FloatArray] | None:
    """``packed`` (``ComMpc.solve``'s: the supports' table (n, 3) and points (Σ counts, 2), float64, the points
    C-contiguous) when it has that form, else None (the supports are then packed from the sequence)."""
    if not isinstance(packed, tuple) or len(packed) != 2:
        return None
    table, points = packed
    if not isinstance(table, np.ndarray) or not isinstance(points, np.ndarray):
        return None
    if table.ndim != 2 or table.shape[1] != 3 or points.ndim != 2 or points.shape[1] != 2 \
            or not (table.dtype is FLOAT64_DTYPE or table.dtype == FLOAT64_DTYPE) \
            or not (points.dtype is FLOAT64_DTYPE or points.dtype == FLOAT64_DTYPE) or not points.flags.c_contiguous \
            or not table.flags.c_contiguous:  # (another layout would compile another plan_window mid-walk)
        return None
    return table, points

