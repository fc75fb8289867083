"""The CoM MPC's compiled code computes what the numpy code it replaced computed (issue 12).

The numpy implementations are kept (in the engine where they still serve a path, here otherwise) as the
references: the intervals of a window, the support geometry, the condensation, the dual active set, the plan's
propagation and its finiteness check.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from engine.bench.mpc_problems import closed_loop_like_problems, example_walking_supports
from engine.constants import GRAVITY_MPS2
from engine.control.mpc import ComMpc, SupportInterval
from engine.control.mpc.state_input import sanitize_state as _sanitize_state
from engine.control.mpc.lip import _Segments


def _assert_equal_to_rounding(got, want, rtol: float = 1e-12) -> None:  # noqa: ANN001
    """Equal to rounding relative to the array's scale (BLAS/LAPACK builds may differ between numpy and scipy)."""
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape
    scale = float(np.max(np.abs(want))) if want.size else 0.0
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale)


def window_intervals_reference(t_start, t_end, t_now, t_horizon, min_int, max_interval_s):  # noqa: ANN001, ANN201
    """ComMpc._build_problem's intervals before the speed-up (numpy and Python loops)."""
    invalid = ~(np.isfinite(t_start) & np.isfinite(t_end) & (t_end >= t_start))
    used: list[int] = []
    prev_end = t_now
    for k, t1 in enumerate(t_end.tolist()):
        if invalid[k]:
            return 1, k, None, None, None
        if t1 <= prev_end + min_int:
            continue
        if prev_end >= t_horizon - min_int:
            break
        used.append(k)
        prev_end = t1 if t1 < t_horizon else t_horizon
    if not used:
        return 2, -1, None, None, None
    t0_used, t1_used = t_start[used], t_end[used]
    n_pieces = np.maximum(np.ceil((t1_used - t0_used) / max_interval_s - 1e-9), 1.0)
    if (n_pieces == 1.0).all():
        return 0, -1, np.array(used), np.minimum(t1_used, t_horizon), np.arange(len(used))
    ends: list[float] = []
    owner: list[int] = []
    prev_end = t_now
    for k, (t0, t1, n_k) in enumerate(zip(t0_used.tolist(), t1_used.tolist(), n_pieces.astype(int).tolist())):
        piece_s = (t1 - t0) / n_k
        first = max(0, int((prev_end + min_int - t0) // piece_s)) if n_k > 1 else 0
        for j in range(first, n_k):
            end = t1 if j == n_k - 1 else t0 + (j + 1) * piece_s
            if end <= prev_end + min_int:
                continue
            if prev_end >= t_horizon - min_int:
                break
            prev_end = min(end, t_horizon)
            ends.append(prev_end)
            owner.append(k)
    return 0, -1, np.array(used), np.array(ends), np.array(owner)


def test_compiled_window_intervals_equal_the_numpy_code() -> None:
    """Elapsed, current, split (long) and truncated supports, invalid times, windows past the schedule."""
    from engine.control.mpc.kernels import window_intervals

    rng = np.random.default_rng(31)
    for case in range(3000):
        n = int(rng.integers(1, 12))
        durations = rng.choice([0.0, 1e-4, 0.09, 0.36, 0.7, 1.3, 3.0], size=n) * rng.uniform(0.5, 1.5, n)
        t_end = float(rng.uniform(-1.0, 0.5)) + np.cumsum(durations)
        t_start = t_end - durations
        if case % 10 == 0:  # an invalid interval
            k = int(rng.integers(n))
            t_start[k], t_end[k] = [(np.nan, t_end[k]), (t_end[k], t_end[k] - 0.1), (t_start[k], np.inf)][case % 3]
        t_now = float(rng.uniform(-0.5, 1.0))
        preview, min_int = float(rng.choice([0.5, 2.0])), float(rng.choice([1e-3, 1e-6]))
        max_piece = float(rng.choice([0.5, 0.3, np.inf]))
        got = window_intervals(t_start, t_end, t_now, t_now + preview, min_int, max_piece)
        want = window_intervals_reference(t_start, t_end, t_now, t_now + preview, min_int, max_piece)
        assert got[:2] == want[:2]
        if want[0] == 0:
            for g, w in zip(got[2:], want[2:]):
                np.testing.assert_array_equal(g, w)


def test_float_support_geometry_equals_the_complex_one() -> None:
    """regions._support_geometry_xy (straight to the compiled kernel) against _support_geometry: convex either
    way round, collinear vertices, non-convex, repeated, non-finite, degenerate and > 16-vertex polygons."""
    from engine.control.mpc.regions import _support_geometry, _support_geometry_xy

    rng = np.random.default_rng(37)
    for case in range(600):
        polygons: list[object] = []
        for _ in range(int(rng.integers(1, 10))):
            n = int(rng.choice([3, 4, 5, 8, 20]))
            ang = np.sort(rng.uniform(0, 2 * np.pi, n))
            poly = np.stack([np.cos(ang), np.sin(ang)], axis=1) * rng.uniform(0.02, 0.3) + rng.normal(0, 0.2, 2)
            kind = rng.integers(8)
            if kind == 0:
                poly = poly[::-1].copy()  # clockwise
            elif kind == 1:
                poly = np.insert(poly, 1, 0.5 * (poly[0] + poly[1]), axis=0)  # collinear vertex
            elif kind == 2 and n > 3:
                poly[[0, 2]] = poly[[2, 0]]  # not convex
            elif kind == 3:
                poly = poly * 1e-4  # degenerate (tiny area)
            elif kind == 4 and case % 7 == 0:
                poly[0, 0] = np.nan
            elif kind == 5:
                poly = poly.tolist()  # not an array
            polygons.append(poly)
        got = _support_geometry_xy(polygons)
        want = _support_geometry(polygons)
        assert (got is None) == (want is None)
        if want is None or got is None:
            continue
        n_s, n_v = want.offsets.shape
        np.testing.assert_array_equal(got[0], want.hull.view(np.float64).reshape(n_s, n_v, 2))
        np.testing.assert_array_equal(got[1], want.normals.view(np.float64).reshape(n_s, n_v, 2))
        np.testing.assert_array_equal(got[2], want.offsets)
        np.testing.assert_array_equal(got[3], want.centroids.view(np.float64).reshape(n_s, 2))
        assert got[4] == int((want.offsets < np.inf).sum(axis=1).max())


def _calls() -> list[tuple]:
    """Walking problems as the controller poses them, perturbed ones, and pushed restarts."""
    calls = [args for args, _ in closed_loop_like_problems(120, seed=5, pull=0.0, state_noise=(0.0, 0.0))]
    for args, _ in closed_loop_like_problems(60, seed=6, state_noise=(0.02, 0.05)):
        pushed = list(args)
        pushed[2] = np.asarray(args[2]) + [0.3, -0.25]
        calls += [args, tuple(pushed)]
    return calls


def test_compiled_condensation_equals_numpy() -> None:
    """ComMpc._condense (compiled, the same LAPACK/BLAS calls) against _condense_numpy."""
    mpc = ComMpc()
    for args in _calls():
        t_now, com, vel, cop, height, _ = _sanitize_state(*args[:5])
        pb, _ = mpc._build_problem(t_now, args[5])
        assert pb is not None
        seg = _Segments.build(pb.times_s, math.sqrt(GRAVITY_MPS2 / height))
        zeta0 = com + vel / seg.omega - cop
        got, want = mpc._condense(pb, seg, cop, zeta0), mpc._condense_numpy(pb, seg, cop, zeta0)
        for name in ("d_mat", "d_inv", "g", "stability_weight", "beta", "u", "kappa", "r0", "p_free", "hess_inv",
                     "normals", "rhs", "row_var"):
            _assert_equal_to_rounding(getattr(got, name), getattr(want, name))


def test_compiled_active_set_equals_numpy() -> None:
    """The compiled dual active set against the numpy one on the same condensed QPs and warm starts: the same
    outcome, active rows and waypoints (equal to rounding: its Cholesky factors are loops, LAPACK's there).
    On the controller's problems (plan continuations) the iteration counts are the same too; on pushed
    restarts ties between rows broken by rounding may change a count."""
    from engine.control.mpc.active_set import _dual_active_set
    from engine.control.mpc.active_set_kernel import waypoints_from_multipliers

    mpc = ComMpc()
    controller_like = 120
    same_count = 0
    for i, args in enumerate(_calls()):
        t_now, com, vel, cop, height, _ = _sanitize_state(*args[:5])
        pb, _ = mpc._build_problem(t_now, args[5])
        assert pb is not None
        seg = _Segments.build(pb.times_s, math.sqrt(GRAVITY_MPS2 / height))
        qp = mpc._condense(pb, seg, cop, com + vel / seg.omega - cop)
        s = qp.rhs - qp.row_values(qp.p_free)
        if s.min() >= -1e-9:
            continue
        common = (qp.hess_inv, qp.normals, qp.row_var, s, pb.row_key, mpc._warm_history, (0.03, 0.999), 1e-9, 100)
        w_got, lam_got, it_got, out_got = _dual_active_set(*common, math.inf)
        w_want, lam_want, it_want, out_want = _dual_active_set(*common, time.perf_counter() + 60.0)  # numpy
        assert out_got == out_want == 0
        assert sorted(w_got.tolist()) == sorted(w_want.tolist()), i
        order = {r: k for k, r in enumerate(w_want.tolist())}
        _assert_equal_to_rounding(lam_got[np.argsort([order[r] for r in w_got.tolist()])], lam_want, 1e-7)
        p_got = waypoints_from_multipliers(qp.p_free, qp.hess_inv, qp.normals, qp.row_var, qp.rhs, w_got, lam_got)[0]
        p_want = waypoints_from_multipliers(qp.p_free, qp.hess_inv, qp.normals, qp.row_var, qp.rhs, w_want, lam_want)[0]
        np.testing.assert_allclose(p_got, p_want, atol=1e-9)
        if i < controller_like:
            assert it_got == it_want, i
        same_count += it_got == it_want
        mpc._store_warm(pb, w_want)
    assert same_count > 0.8 * len(_calls())


def test_compiled_plan_and_finiteness_equal_numpy() -> None:
    """plan_from_waypoints (propagation, world frame, final state) and _is_finite against their numpy code."""
    from engine.control.mpc.fallbacks import is_finite_plan as _is_finite
    from engine.control.mpc.kernels import plan_from_waypoints
    from engine.control.mpc.types import ComMpcSolution

    rng = np.random.default_rng(41)
    for case in range(500):
        n = int(rng.integers(1, 30))
        times = float(rng.uniform(-2, 2)) + np.r_[0.0, np.cumsum(rng.uniform(0.0, 0.3, n))]
        seg = _Segments.build(times, float(rng.uniform(2.0, 6.0)))
        wps, com, vel, origin = rng.normal(0, 0.2, (n, 2)), rng.normal(0, 0.2, 2), rng.normal(0, 0.5, 2), rng.normal(0, 1, 2)
        got = plan_from_waypoints(seg.omega, seg.a, seg.b, seg.grow, wps, com, vel, origin)
        local = np.zeros((n + 1, 2))
        local[1:] = wps
        pos, vel_wp = seg.propagate(local, com - origin, vel)
        for g, w in zip(got, (local + origin, pos + origin, vel_wp, np.concatenate([pos[-1] + origin, vel_wp[-1]]))):
            np.testing.assert_array_equal(g, w)
        assert math.isfinite(got[4]) == math.isfinite(float(pos.sum() + vel_wp.sum()))
        sol = ComMpcSolution(times, got[0], got[1], got[2], 0.7, "solved", 0.0, qp_final_state=got[3])
        if case % 3 == 0:
            arr = [sol.waypoints_xy_m, sol.waypoint_com_xy_m, sol.waypoint_com_vel_xy_mps, sol.qp_final_state][case % 4]
            arr.flat[int(rng.integers(arr.size))] = [np.nan, np.inf, -np.inf][case % 5 % 3]
        want = math.isfinite(float(sol.waypoint_times_s.sum() + sol.waypoints_xy_m.sum() + sol.waypoint_com_xy_m.sum()
                                    + sol.waypoint_com_vel_xy_mps.sum() + sol.qp_final_state.sum() + sol.com_height_m))
        assert _is_finite(sol) == want


def test_walking_supports_solve_the_same_with_either_active_set() -> None:
    """Whole solves: a time-limited ComMpc (numpy active set) and the default one (compiled) give the same plans."""
    rng = np.random.default_rng(43)
    fast, reference = ComMpc(), ComMpc(time_limit_s=60.0)
    for _ in range(40):
        supports = example_walking_supports(n_steps=int(rng.integers(2, 8)), step_length_m=float(rng.uniform(-0.2, 0.35)),
                                            yaw_rad=float(rng.uniform(-3, 3)))
        args = (float(rng.uniform(0, 1)), rng.normal(0, 0.03, 2), rng.normal(0, 0.2, 2), np.zeros(2), 0.7, supports)
        a, b = fast.solve(*args), reference.solve(*args)
        assert a.status == b.status
        np.testing.assert_allclose(a.waypoints_xy_m, b.waypoints_xy_m, atol=1e-9)
        np.testing.assert_allclose(a.waypoint_com_xy_m, b.waypoint_com_xy_m, atol=1e-9)
    assert isinstance(supports[0], SupportInterval)


def test_scalar_cop_at_equals_numpy_interp() -> None:
    """ComMpcSolution.cop_at for one time (floats) against the array version (np.interp): at, between, before
    and after the waypoints, with repeated values, huge values and infinities."""
    from engine.control.mpc.types import ComMpcSolution

    rng = np.random.default_rng(47)
    for case in range(300):
        n = int(rng.integers(2, 30))
        times = float(rng.uniform(-3, 3)) + np.r_[0.0, np.cumsum(rng.uniform(1e-3, 0.3, n - 1))]
        wps = rng.normal(0, 0.3, (n, 2))
        if case % 5 == 0:
            wps[rng.integers(n)] = wps[0]
        if case % 7 == 0:
            wps[rng.integers(n), rng.integers(2)] = [np.inf, -np.inf, 1e308][case % 3]
        sol = ComMpcSolution(times, wps, wps.copy(), wps.copy(), 0.7, "solved", 0.0)
        queries = np.r_[times, rng.uniform(times[0] - 0.5, times[-1] + 0.5, 30), np.nextafter(times, np.inf)]
        for t in queries.tolist():
            got, want = sol.cop_at(t), sol._cop_at_array(t)
            assert got.shape == want.shape == (2,)
            np.testing.assert_array_equal(got, want)


def test_one_call_solve_equals_the_step_by_step_solve(monkeypatch) -> None:  # noqa: ANN001
    """ComMpc._solve_compiled (segments, condensation, active set and plan in one compiled call) against the
    step-by-step path (the same kernels called one by one), over sequences of solves sharing their warm starts:
    the same statuses, plans (bit for bit), iteration counts and remembered active rows."""
    from engine.control.mpc.controller import ComMpc as Mpc

    calls = _calls()
    fast, reference = Mpc(), Mpc()
    fast._solve_window = reference._solve_window = lambda *_, **__: None  # the one-call plan: tested below
    fused_solves = 0
    original = Mpc._solve_compiled

    def counting(self, *args, **kwargs):  # noqa: ANN001, ANN002, ANN003, ANN202
        nonlocal fused_solves
        out = original(self, *args, **kwargs)
        fused_solves += out is not None
        return out

    for args in calls:
        monkeypatch.setattr(Mpc, "_solve_compiled", counting)
        a = fast.solve(*args)
        monkeypatch.setattr(Mpc, "_solve_compiled", lambda *_, **__: None)
        b = reference.solve(*args)
        assert a.status == b.status and a.message == b.message and a.osqp_iterations == b.osqp_iterations
        for name in ("waypoint_times_s", "waypoints_xy_m", "waypoint_com_xy_m", "waypoint_com_vel_xy_mps",
                     "region_centroids_xy_m", "qp_final_state"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert len(fast._warm_history) == len(reference._warm_history)
        for (ka, na), (kb, nb) in zip(fast._warm_history, reference._warm_history):
            np.testing.assert_array_equal(ka, kb)
            np.testing.assert_array_equal(na, nb)
    assert fused_solves > 0.9 * len(calls)


def _assert_same_solves(a, b, mpc_a, mpc_b) -> None:  # noqa: ANN001
    """The same solution (statuses, messages, iterations, every array bit for bit) and remembered active rows."""
    assert (a.status, a.message, a.osqp_iterations, a.com_height_m) == (b.status, b.message, b.osqp_iterations,
                                                                        b.com_height_m)
    for name in ("waypoint_times_s", "waypoints_xy_m", "waypoint_com_xy_m", "waypoint_com_vel_xy_mps",
                 "region_centroids_xy_m", "qp_final_state"):
        got, want = getattr(a, name), getattr(b, name)
        assert got.shape == want.shape and got.dtype == want.dtype, name
        np.testing.assert_array_equal(got, want, err_msg=name)
    assert len(mpc_a._warm_history) == len(mpc_b._warm_history)
    for (ka, na), (kb, nb) in zip(mpc_a._warm_history, mpc_b._warm_history):
        np.testing.assert_array_equal(ka, kb)
        np.testing.assert_array_equal(na, nb)
    assert mpc_a.padded_shape == mpc_b.padded_shape and mpc_a.setup_count == mpc_b.setup_count


def _step_by_step_mpc(**kwargs):  # noqa: ANN003, ANN202
    """A ComMpc whose one-call plan (plan_window) is switched off: main's path before it (the reference)."""
    mpc = ComMpc(**kwargs)
    mpc._solve_window = lambda *_, **__: None
    return mpc


def test_numpy_complex_abs_in_the_kernel() -> None:
    """plan_window's edge lengths are numpy's abs of the edges (its SIMD formula, not libm's hypot): the same
    numbers on walking-scale, tiny, huge, axis-aligned and zero edges."""
    from engine.control.mpc.active_set_kernel import edge_length

    rng = np.random.default_rng(53)
    parts = [rng.normal(0.0, scale, (20000, 2)) for scale in (1e-6, 1e-3, 0.1, 1.0, 1e3, 1e150)]
    special = np.array([[0.0, 0.0], [0.0, 0.3], [-0.3, 0.0], [1e308, 1e308], [-1e308, 1e-300], [3.0, 4.0]])
    d = np.concatenate([*parts, special])
    want = np.abs(d.view(np.complex128)[:, 0])
    got = np.array([edge_length(x, y) for x, y in d.tolist()])
    np.testing.assert_array_equal(got, want)


def test_one_call_plan_equals_the_step_by_step_solve_on_the_bench_problems() -> None:
    """ComMpc.solve with plan_window (supports to plan in one compiled call) against the same solves without it,
    in sequence (warm starts shared): bit for bit, and plan_window plans almost all of them."""
    from engine.control.mpc import active_set_kernel
    import engine.control.mpc.controller as controller

    planned = 0
    original = controller.plan_window

    def counting(*args):  # noqa: ANN002, ANN202
        nonlocal planned
        out = original(*args)
        planned += out[0] == active_set_kernel.WINDOW_PLANNED
        return out

    calls = _calls()
    fast, reference = ComMpc(), _step_by_step_mpc()
    controller.plan_window = counting
    try:
        for args in calls:
            _assert_same_solves(fast.solve(*args), reference.solve(*args), fast, reference)
    finally:
        controller.plan_window = original
    assert planned > 0.9 * len(calls)


def test_one_call_plan_on_odd_inputs_gives_the_same_fallbacks() -> None:
    """Inputs the one-call plan leaves to the step-by-step path (non-finite or invalid state, lists, integer or
    degenerate or non-convex polygons, supports not covering the window, malformed supports, a workspace to grow,
    a general intersection of supports) give what they gave before: the same statuses and numbers."""
    supports = example_walking_supports(n_steps=4, step_length_m=0.2, yaw_rad=0.3)
    com, vel, cop = np.array([0.01, 0.0]), np.array([0.1, 0.05]), np.array([0.0, 0.0])

    def shifted(polygons):  # noqa: ANN001, ANN202
        return [SupportInterval(s.t_start_s, s.t_end_s, p) for s, p in zip(supports, polygons)]

    polys = [s.polygon for s in supports]
    left = np.array([[0.0, 0.0], [0.2, 0.0], [0.2, 0.1], [0.0, 0.1]])
    hop = [SupportInterval(0.0, 0.4, left), SupportInterval(0.4, 0.8, left + [0.1, -0.3]),
           SupportInterval(0.8, 3.0, left + [0.1, 0.0])]
    cases = {
        "nan state": (0.2, np.array([np.nan, 0.0]), vel, cop, 0.7, supports),
        "inf velocity": (0.2, com, np.array([np.inf, 0.0]), cop, 0.7, supports),
        "nan time": (math.nan, com, vel, cop, 0.7, supports),
        "zero height": (0.2, com, vel, cop, 0.0, supports),
        "list state": (0.2, [0.01, 0.0], (0.1, 0.05), [0.0, 0.0], 0.7, supports),
        "integer time and height": (0, com, vel, cop, 1, supports),
        "float32 state": (np.float32(0.2), com.astype(np.float32), vel, cop, np.float32(0.7), supports),
        "nan polygon": (0.2, com, vel, cop, 0.7, shifted([polys[0] * np.nan] + polys[1:])),
        "degenerate polygon": (0.2, com, vel, cop, 0.7, shifted([polys[0] * 0.0] + polys[1:])),
        "two vertices": (0.2, com, vel, cop, 0.7, shifted([polys[0][:2]] + polys[1:])),
        "non-convex polygon": (0.2, com, vel, cop, 0.7, shifted([polys[0][[0, 2, 1, 3]]] + polys[1:])),
        "integer polygon": (0.2, com, vel, cop, 0.7, shifted([np.round(polys[0] * 10).astype(int)] + polys[1:])),
        "list polygon": (0.2, com, vel, cop, 0.7, shifted([polys[0].tolist()] + polys[1:])),
        "many vertices": (0.2, com, vel, cop, 0.7, shifted(
            [0.1 * np.stack([np.cos(a), np.sin(a)], axis=1) for a in [np.linspace(0, 2 * np.pi, 20, endpoint=False)]]
            + polys[1:])),
        "window not covered": (5.0, com, vel, cop, 0.7, supports[:2]),
        "no supports": (0.2, com, vel, cop, 0.7, []),
        "inverted times": (0.2, com, vel, cop, 0.7, [SupportInterval(1.0, 0.5, polys[0])] + supports[1:]),
        "malformed support": (0.2, com, vel, cop, 0.7, [object()] + supports[1:]),
        "general intersection": (0.0, np.array([0.1, 0.05]), np.zeros(2), np.array([0.1, 0.05]), 0.7, hop),
        "pushed": (0.2, com, np.array([1.5, -1.2]), cop, 0.7, supports),
    }
    fast, reference = ComMpc(max_intervals=2), _step_by_step_mpc(max_intervals=2)  # the first call grows them
    statuses = {}
    for name, args in cases.items():
        for _ in range(2):  # cold, then warm started
            a, b = fast.solve(*args), reference.solve(*args)
            _assert_same_solves(a, b, fast, reference)
        statuses[name] = a.status
    assert statuses["nan state"].startswith("invalid_input") and statuses["nan polygon"].startswith("invalid_input")
    assert statuses["window not covered"].startswith("invalid_input")
    assert statuses["degenerate polygon"].startswith("invalid_input")
    assert statuses["general intersection"] == "solved_empty_intersection"
    assert statuses["list polygon"] == statuses["pushed"] == "solved"


@pytest.mark.slow
@pytest.mark.parametrize("robot_name", ["g1", "talos"])
def test_one_call_plan_equals_the_step_by_step_solve_in_closed_loop(robot_name: str) -> None:
    """The controller's own solve sequence (walking forward while turning, a push from the side, restarts): each
    call solved by the controller's ComMpc (one-call plan) and by a step-by-step twin fed the same calls gives the
    same solutions bit for bit."""
    import engine.control.mpc.controller as controller
    from engine.control.walking_controller import WalkingController
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import Simulation

    robot = load_robot(robot_name)
    style = load_style(styles_dir(robot_name) / "neutral.json")
    walker = WalkingController(robot, style)
    sim = Simulation(robot, walker)
    original = controller.ComMpc.solve
    twins: dict[int, ComMpc] = {}
    statuses: list[str] = []
    pushed_calls = 0

    def twin_solve(self, *args):  # noqa: ANN001, ANN002, ANN202
        twin = twins.setdefault(id(self), _step_by_step_mpc(preview_s=self.preview_s))
        a = original(self, *args)
        b = original(twin, *args)
        _assert_same_solves(a, b, self, twin)
        statuses.append(a.status)
        nonlocal pushed_calls
        pushed_calls += bool(walker.observer.force_n.any())  # supports shifted by the observed push
        return a

    controller.ComMpc.solve = twin_solve
    try:
        v = style.velocities
        for k in range(int(3.0 / 0.002)):
            t = k * 0.002
            walker.set_command(np.array([0.6 * v.x_max_mps, 0.0, 0.8 * v.yaw_max_radps]) if t > 0.5 else np.zeros(3))
            if k == int(1.8 / 0.002):
                sim.push(np.array([0.0, 1.0 * robot.mass_kg, 0.0]), 0.3)
            sim.step()
    finally:
        controller.ComMpc.solve = original
    assert len(statuses) > 300 and not sim.detect_fall()
    assert pushed_calls > 10 and statuses.count("solved") > 0.9 * len(statuses)
