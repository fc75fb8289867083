"""Tests for the CoM/CoP model predictive controller (engine/control/com_mpc.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.control.com_mpc import (
    GRAVITY_MPS2,
    ComMpc,
    ComMpcSolution,
    ComMpcWeights,
    SupportInterval,
    benchmark_solve,
    clip_convex_polygons,
    convex_hull,
    polygon_area,
    polygon_centroid,
    polygon_halfplanes,
    propagate_lip,
)

COM_HEIGHT_M = 0.8
DT_CONTROL_S = 0.008
FOOT_LENGTH_M = 0.2
FOOT_WIDTH_M = 0.08
HYPOTHESIS = settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# ----------------------------------------------------------------- test helpers


def foot(center_xy_m: np.ndarray, yaw_rad: float) -> np.ndarray:
    """CCW foot rectangle."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    local = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]]) * [FOOT_LENGTH_M, FOOT_WIDTH_M]
    return local @ np.array([[c, -s], [s, c]]).T + center_xy_m


def walk(
    step_length_m: float,
    single_support_s: float,
    double_support_s: float,
    n_steps: int,
    yaw_rad: float = 0.0,
    step_width_m: float = 0.2,
    initial_double_support_s: float = 0.4,
    final_double_support_s: float = 4.0,
) -> list[SupportInterval]:
    """Alternating double/single supports of a straight walk (heading ``yaw_rad``)."""
    heading = np.array([math.cos(yaw_rad), math.sin(yaw_rad)])
    lateral = np.array([-math.sin(yaw_rad), math.cos(yaw_rad)])

    def place(x_m: float, side: int) -> np.ndarray:
        return foot(x_m * heading + side * 0.5 * step_width_m * lateral, yaw_rad)

    feet = {1: place(0.0, 1), -1: place(0.0, -1)}
    t = 0.0
    out = [SupportInterval(t, t + initial_double_support_s, convex_hull(np.vstack([feet[1], feet[-1]])))]
    t += initial_double_support_s
    for i in range(n_steps):
        swing = -1 if i % 2 == 0 else 1
        out.append(SupportInterval(t, t + single_support_s, feet[-swing]))
        t += single_support_s
        feet[swing] = place((i + 1) * step_length_m, swing)
        ds = final_double_support_s if i == n_steps - 1 else double_support_s
        out.append(SupportInterval(t, t + ds, convex_hull(np.vstack([feet[1], feet[-1]]))))
        t += ds
    return out


def window(supports: list[SupportInterval], t_s: float, preview_s: float = 2.0) -> list[SupportInterval]:
    return [s for s in supports if s.t_end_s > t_s and s.t_start_s < t_s + preview_s]


def inside(point: np.ndarray, polygon: np.ndarray, tol_m: float) -> bool:
    """Point in CCW convex polygon, using edge cross products (independent of the module)."""
    v = np.asarray(polygon)
    e = np.roll(v, -1, axis=0) - v
    d = point - v
    signed_dist = (e[:, 0] * d[:, 1] - e[:, 1] * d[:, 0]) / np.hypot(e[:, 0], e[:, 1])
    return bool(signed_dist.min() >= -tol_m)


def active(supports: list[SupportInterval], t_s: float, eps_s: float = 1e-9) -> list[np.ndarray]:
    return [s.polygon for s in supports if s.t_start_s - eps_s <= t_s <= s.t_end_s + eps_s]


def rk4_com(sol: ComMpcSolution, com_xy_m: np.ndarray, com_vel_xy_mps: np.ndarray, max_step_s: float = 1e-3):
    """Integrate x'' = w^2 (x - cop_at(t)) with RK4 (steps aligned to the waypoints)."""
    w2 = GRAVITY_MPS2 / sol.com_height_m
    state = np.concatenate([com_xy_m, com_vel_xy_mps])
    times = sol.waypoint_times_s
    out = [state.copy()]

    def f(t: float, s: np.ndarray) -> np.ndarray:
        return np.concatenate([s[2:], w2 * (s[:2] - sol.cop_at(t))])

    for t0, t1 in zip(times[:-1], times[1:]):
        n = max(1, math.ceil((t1 - t0) / max_step_s))
        h = (t1 - t0) / n
        for i in range(n):
            t = t0 + i * h
            k1 = f(t, state)
            k2 = f(t + h / 2, state + h / 2 * k1)
            k3 = f(t + h / 2, state + h / 2 * k2)
            k4 = f(t + h, state + h * k3)
            state = state + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(state.copy())
    return np.array(out)


def run_receding(mpc: ComMpc, supports: list[SupportInterval], t0_s: float, t1_s: float, state=None):
    """Solve, advance DT_CONTROL_S along the plan, re-solve; yields (t, solution, inputs)."""
    t = t0_s
    if state is None:
        com = polygon_centroid(supports[0].polygon)
        state = (com, np.zeros(2), com.copy())
    com, vel, cop = state
    while t < t1_s:
        sol = mpc.solve(t, com, vel, cop, COM_HEIGHT_M, window(supports, t, mpc.preview_s))
        yield t, sol, (com, vel, cop)
        t += DT_CONTROL_S
        com, vel, _ = sol.com_at(t)
        cop = sol.cop_at(t)


def assert_constraints(sol: ComMpcSolution, supports: list[SupportInterval], tol_m: float = 1e-4) -> None:
    times, wps = sol.waypoint_times_s, sol.waypoints_xy_m
    for i, (t, wp) in enumerate(zip(times[1:], wps[1:]), start=1):
        polys = active(supports, t)
        if i == len(times) - 1:  # window end: only the support it closes (the next one is not in the window)
            polys = [s.polygon for s in supports if s.t_start_s < t <= s.t_end_s + 1e-9]
        assert polys, f"no support at waypoint time {t}"
        for poly in polys:
            assert inside(wp, poly, tol_m), f"waypoint {wp} at t={t:.3f} outside its region"
    # The linear CoP between waypoints 1..N stays in the support active at each instant.
    for t0, t1 in zip(times[1:-1], times[2:]):
        for t in np.linspace(t0, t1, 7)[1:-1]:
            for poly in active(supports, t):
                assert inside(sol.cop_at(t), poly, tol_m), f"CoP at t={t:.3f} outside the active polygon"


walks = st.builds(
    walk,
    step_length_m=st.floats(0.0, 0.3),
    single_support_s=st.floats(0.3, 0.6),
    double_support_s=st.floats(0.1, 0.3),
    n_steps=st.integers(2, 8),
    yaw_rad=st.floats(-math.pi, math.pi),
)


# ------------------------------------------------------------- polygon helpers


def test_halfplanes_unit_normals_and_orientation() -> None:
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    for poly in (square, square[::-1]):
        normals, offsets = polygon_halfplanes(poly)
        assert normals.shape == (4, 2)
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0)
        assert np.all(normals @ np.array([0.5, 0.5]) - offsets < 0)  # centre strictly inside
        assert np.max(normals @ np.array([1.5, 0.5]) - offsets) == pytest.approx(0.5)  # signed distance


def test_centroid_area_and_hull() -> None:
    rect = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]])
    assert polygon_area(rect) == pytest.approx(2.0)
    assert polygon_area(rect[::-1]) == pytest.approx(-2.0)
    np.testing.assert_allclose(polygon_centroid(rect), [1.0, 0.5])
    tri = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 3.0]])
    np.testing.assert_allclose(polygon_centroid(tri), [1.0, 1.0])
    # Interior and collinear points are removed, the result is CCW.
    pts = np.vstack([rect, [[1.0, 0.5], [1.0, 0.0], [0.3, 0.7]]])
    hull = convex_hull(pts)
    assert len(hull) == 4 and polygon_area(hull) == pytest.approx(2.0)


@HYPOTHESIS
@given(
    a=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.05, 1), st.floats(0.05, 1)),
    b=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.05, 1), st.floats(0.05, 1)),
)
def test_clip_matches_axis_aligned_overlap(a, b) -> None:
    def box(x, y, w, h):
        return np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]])

    overlap_w = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    overlap_h = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    inter = clip_convex_polygons(box(*a), box(*b))
    if overlap_w < -1e-9 or overlap_h < -1e-9:
        assert len(inter) == 0
    else:
        assert polygon_area(inter) == pytest.approx(max(overlap_w, 0) * max(overlap_h, 0), abs=1e-9)
        if overlap_w > 1e-6 and overlap_h > 1e-6:
            centre = [max(a[0], b[0]) + overlap_w / 2, max(a[1], b[1]) + overlap_h / 2]
            np.testing.assert_allclose(polygon_centroid(inter), centre, atol=1e-9)


def test_clip_rotated_feet() -> None:
    left, right = foot(np.array([0.0, 0.1]), 0.0), foot(np.array([0.0, -0.1]), 0.0)
    hull = convex_hull(np.vstack([left, right]))
    inter = clip_convex_polygons(hull, left)
    assert polygon_area(inter) == pytest.approx(FOOT_LENGTH_M * FOOT_WIDTH_M)
    assert len(clip_convex_polygons(left, right)) == 0


# -------------------------------------------------------------------- dynamics


@HYPOTHESIS
@given(
    durations=st.lists(st.floats(0.01, 0.5), min_size=1, max_size=8),
    seed=st.integers(0, 2**31 - 1),
    height=st.floats(0.3, 1.2),
)
def test_propagate_lip_matches_rk4(durations, seed, height) -> None:
    rng = np.random.default_rng(seed)
    times = np.concatenate([[0.3], 0.3 + np.cumsum(durations)])
    wps = rng.uniform(-0.2, 0.2, (len(times), 2))
    x0, v0 = rng.uniform(-0.1, 0.1, 2), rng.uniform(-0.5, 0.5, 2)
    omega = math.sqrt(GRAVITY_MPS2 / height)
    pos, vel = propagate_lip(times, wps, x0, v0, omega)
    sol = ComMpcSolution(times, wps, pos, vel, height, "test", 0.0)
    ref = rk4_com(sol, x0, v0, max_step_s=5e-4)
    np.testing.assert_allclose(pos, ref[:, :2], atol=1e-7)
    np.testing.assert_allclose(vel, ref[:, 2:], atol=1e-6)


# ------------------------------------------------------------------- MPC tests


def consistent_state(supports: list[SupportInterval], t0_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """State at ``t0_s`` of a robot that started at rest and followed (1 s open-loop chunks of) the plan."""
    mpc = ComMpc()
    com = polygon_centroid(supports[0].polygon)
    vel, cop, t = np.zeros(2), com.copy(), 0.0
    while t < t0_s:
        sol = mpc.solve(t, com, vel, cop, COM_HEIGHT_M, window(supports, t))
        assert sol.status == "solved", sol.message
        t = min(t + 1.0, t0_s)
        com, vel, _ = sol.com_at(t)
        cop = sol.cop_at(t)
    return com, vel, cop


@HYPOTHESIS
@given(supports=walks, start_fraction=st.floats(0.0, 1.0), seed=st.integers(0, 2**31 - 1))
def test_waypoints_and_cop_stay_in_support(supports, start_fraction, seed) -> None:
    """Req. 1: waypoints in their regions, linear CoP in the active polygon (receding horizon)."""
    rng = np.random.default_rng(seed)
    t0 = start_fraction * (supports[-1].t_start_s + 0.5)
    com, vel, cop = consistent_state(supports, t0)
    vel = vel + rng.uniform(-0.03, 0.03, 2)  # a small disturbance
    mpc = ComMpc()
    shape, setups = mpc.padded_shape, mpc.setup_count
    for k, (_, sol, _) in enumerate(run_receding(mpc, supports, t0, t0 + 0.4, state=(com, vel, cop))):
        assert sol.status == "solved", sol.message
        if k % 5 == 0:
            assert_constraints(sol, supports)
            final = np.concatenate([sol.final_com_xy_m, sol.final_com_vel_xy_mps])
            np.testing.assert_allclose(sol.qp_final_state, final, atol=1e-4)
        # OSQP setup runs again only when the padded shape has to grow.
        assert mpc.setup_count == setups + (mpc.padded_shape != shape)
        shape, setups = mpc.padded_shape, mpc.setup_count


def test_initial_conditions_and_forward_simulation() -> None:
    """Req. 2 and 3: com_at / cop_at start at the given state; RK4 with cop_at reproduces com_at and xi_T."""
    supports = walk(0.25, 0.4, 0.15, n_steps=6)
    t_now = 1.13
    com, vel, cop = consistent_state(supports, t_now)
    com, vel = com + [0.004, -0.003], vel + [0.02, 0.03]  # off the previous plan
    sol = ComMpc().solve(t_now, com, vel, cop, COM_HEIGHT_M, window(supports, t_now))
    assert sol.status == "solved", sol.message
    pos0, vel0, acc0 = sol.com_at(t_now)
    np.testing.assert_allclose(pos0, com, atol=1e-12)
    np.testing.assert_allclose(vel0, vel, atol=1e-12)
    np.testing.assert_allclose(sol.cop_at(t_now), cop, atol=1e-12)
    np.testing.assert_allclose(acc0, GRAVITY_MPS2 / COM_HEIGHT_M * (com - cop), atol=1e-9)
    assert sol.waypoint_times_s[0] == t_now and sol.t_end_s == pytest.approx(t_now + 2.0)

    ref = rk4_com(sol, com, vel)
    # Forward simulation from the initial state reproduces the QP's xi_T (Eq. 14 equalities are exact).
    np.testing.assert_allclose(ref[-1], sol.qp_final_state, atol=1e-4)
    np.testing.assert_allclose(ref[-1, :2], sol.final_com_xy_m, atol=1e-6)
    np.testing.assert_allclose(ref[-1, 2:], sol.final_com_vel_xy_mps, atol=1e-6)
    pos, vel_wp, _ = sol.com_at(sol.waypoint_times_s)
    np.testing.assert_allclose(pos, ref[:, :2], atol=1e-4)
    np.testing.assert_allclose(vel_wp, ref[:, 2:], atol=1e-4)
    # Vectorised evaluation agrees with scalar evaluation and with LIP acceleration.
    ts = np.linspace(t_now, sol.t_end_s, 37)
    p_vec, v_vec, a_vec = sol.com_at(ts)
    for i in (0, 11, 36):
        p_s, v_s, a_s = sol.com_at(ts[i])
        np.testing.assert_allclose([p_s, v_s, a_s], [p_vec[i], v_vec[i], a_vec[i]], atol=1e-12)
    np.testing.assert_allclose(a_vec, GRAVITY_MPS2 / COM_HEIGHT_M * (p_vec - sol.cop_at(ts)), atol=1e-9)
    # Velocity is the derivative of position (central differences).
    h = 1e-5
    fd = (sol.com_at(ts[1:-1] + h)[0] - sol.com_at(ts[1:-1] - h)[0]) / (2 * h)
    np.testing.assert_allclose(fd, v_vec[1:-1], atol=1e-5)
    times, path = sol.com_path(0.02)
    assert times[0] == t_now and times[-1] == pytest.approx(sol.t_end_s) and path.shape == (len(times), 2)


def test_stop_capture_point_and_rest() -> None:
    """Req. 4: a walk ending in a long double support ends at rest over the final support."""
    supports = walk(0.25, 0.4, 0.1, n_steps=4, final_double_support_s=8.0)
    final_poly = supports[-1].polygon
    centroid = polygon_centroid(final_poly)
    t_stop = supports[-1].t_start_s
    mpc = ComMpc()
    last = None
    for t, sol, _ in run_receding(mpc, supports, 0.0, t_stop + 4.5):
        assert sol.status == "solved", sol.message
        if t > t_stop - 1.5:
            # The window ends inside the final support: its final capture point is its centroid.
            np.testing.assert_allclose(sol.final_capture_point_xy_m, centroid, atol=3e-3)
        last = sol, t
    sol, t = last
    com, vel, _ = sol.com_at(t)
    assert inside(com, final_poly, 0.0)
    assert np.linalg.norm(com - centroid) < 0.01
    assert np.linalg.norm(vel) < 0.01
    assert mpc.setup_count == 1


def test_walking_com_is_plausible() -> None:
    """The CoM moves forward at the walking speed and sways towards the stance foot."""
    supports = walk(0.25, 0.4, 0.1, n_steps=8)
    xs, ys, ts = [], [], []
    for t, sol, (com, _, cop) in run_receding(ComMpc(), supports, 0.0, 4.0):
        xs.append(com[0])
        ys.append(com[1])
        ts.append(t)
    speed = (xs[-1] - xs[250]) / (ts[-1] - ts[250])
    assert 0.35 < speed < 0.65  # 0.25 m every 0.5 s
    assert 0.01 < max(np.abs(ys[100:])) < 0.1  # lateral sway, smaller than half the step width


def test_warm_start_matches_cold_and_reuses_pattern() -> None:
    """Req. 5: warm-started receding solves equal cold solves; setup runs once per padded shape."""
    supports = walk(0.2, 0.35, 0.15, n_steps=8)
    mpc = ComMpc()
    for k, (t, sol, (com, vel, cop)) in enumerate(run_receding(mpc, supports, 0.0, 2.5)):
        if k % 20 == 0:
            cold = ComMpc().solve(t, com, vel, cop, COM_HEIGHT_M, window(supports, t))
            assert cold.status == sol.status == "solved"
            np.testing.assert_allclose(sol.waypoint_times_s, cold.waypoint_times_s)
            np.testing.assert_allclose(sol.waypoints_xy_m, cold.waypoints_xy_m, atol=1e-6)
            np.testing.assert_allclose(sol.final_capture_point_xy_m, cold.final_capture_point_xy_m, atol=1e-5)
    assert mpc.setup_count == 1
    assert mpc.padded_shape == (10, 8)


def test_time_jumps_reuse_the_pattern() -> None:
    """Non-consecutive calls (time jumps either way) are solved with the same pattern."""
    supports = walk(0.2, 0.4, 0.1, n_steps=8)
    mpc = ComMpc()
    for t in (0.2, 3.0, 2.0, 5.9, 0.1):
        sol = mpc.solve(t, *consistent_state(supports, t), COM_HEIGHT_M, window(supports, t))
        assert sol.status == "solved", sol.message
        cold = ComMpc().solve(t, *consistent_state(supports, t), COM_HEIGHT_M, window(supports, t))
        np.testing.assert_allclose(sol.waypoints_xy_m, cold.waypoints_xy_m, atol=1e-6)
    assert mpc.setup_count == 1


def test_invalid_configuration_raises() -> None:
    with pytest.raises(ValueError):
        ComMpc(preview_s=0.0)
    with pytest.raises(ValueError):
        ComMpc(weights=ComMpcWeights(cop_velocity=-1.0))


def test_padding_grows_on_demand_only() -> None:
    supports = walk(0.2, 0.3, 0.1, n_steps=10)
    mpc = ComMpc(max_intervals=3, max_halfplanes=4)
    assert mpc.setup_count == 1
    sols = [sol for _, sol, _ in run_receding(mpc, supports, 0.0, 0.6)]
    assert all(s.status == "solved" for s in sols)
    grown = mpc.setup_count
    assert grown > 1
    k_max, h_max = mpc.padded_shape
    assert k_max >= 10 and h_max >= 6
    # Once large enough, the pattern is reused.
    assert all(sol.status == "solved" for _, sol, _ in run_receding(mpc, supports, 0.0, 0.6))
    assert mpc.setup_count == grown
    # Same result as a generously padded controller.
    s = sols[-1]
    state = (*s.com_at(s.t_start_s)[:2], s.cop_at(s.t_start_s))
    big = ComMpc(max_intervals=16, max_halfplanes=12)
    ref = big.solve(s.t_start_s, *state, COM_HEIGHT_M, window(supports, s.t_start_s))
    np.testing.assert_allclose(s.waypoints_xy_m, ref.waypoints_xy_m, atol=1e-6)


def test_weights_change_the_plan() -> None:
    supports = walk(0.25, 0.4, 0.1, n_steps=6)
    com, vel, cop = consistent_state(supports, 0.7)
    args = (0.7, com, vel, cop, COM_HEIGHT_M, window(supports, 0.7))
    smooth = ComMpc(weights=ComMpcWeights(cop_velocity=1.0)).solve(*args)
    centred = ComMpc(weights=ComMpcWeights(cop_velocity=1e-5)).solve(*args)
    assert smooth.status == centred.status == "solved"

    def centroid_error(sol: ComMpcSolution) -> float:
        return float(np.linalg.norm(sol.waypoints_xy_m[1:] - sol.region_centroids_xy_m[1:], axis=1).sum())

    def cop_speed(sol: ComMpcSolution) -> float:
        return float(np.abs(np.diff(sol.waypoints_xy_m, axis=0) / np.diff(sol.waypoint_times_s)[:, None]).max())

    assert centroid_error(centred) < centroid_error(smooth)
    assert cop_speed(smooth) < cop_speed(centred)


# ------------------------------------------------------------------ robustness


def _assert_finite(sol: ComMpcSolution) -> None:
    assert np.isfinite(sol.waypoint_times_s).all() and np.isfinite(sol.waypoints_xy_m).all()
    assert np.isfinite(sol.waypoint_com_xy_m).all() and np.isfinite(sol.waypoint_com_vel_xy_mps).all()
    ts = np.linspace(sol.t_start_s - 0.1, sol.t_end_s + 0.1, 9)
    assert np.isfinite(sol.cop_at(ts)).all()
    assert all(np.isfinite(x).all() for x in sol.com_at(ts))
    assert np.isfinite(sol.final_capture_point_xy_m).all() and math.isfinite(sol.solve_time_s)
    assert np.isfinite(sol.qp_final_state).all()


NAN2 = np.array([np.nan, 0.0])
GOOD_STATE = (np.array([0.0, 0.0]), np.array([0.1, 0.0]), np.array([0.0, 0.0]))


def _garbage_cases():
    supports = walk(0.2, 0.4, 0.1, n_steps=4)
    ok = window(supports, 0.2)
    degenerate = [SupportInterval(0.0, 5.0, np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0]]))]
    return {
        "nan_com": (0.2, NAN2, GOOD_STATE[1], GOOD_STATE[2], COM_HEIGHT_M, ok),
        "nan_vel": (0.2, GOOD_STATE[0], NAN2, GOOD_STATE[2], COM_HEIGHT_M, ok),
        "nan_cop": (0.2, GOOD_STATE[0], GOOD_STATE[1], NAN2, COM_HEIGHT_M, ok),
        "nan_time": (math.nan, *GOOD_STATE, COM_HEIGHT_M, ok),
        "bad_height": (0.2, *GOOD_STATE, -1.0, ok),
        "nan_height": (0.2, *GOOD_STATE, math.nan, ok),
        "no_supports": (0.2, *GOOD_STATE, COM_HEIGHT_M, []),
        "elapsed_supports": (99.0, *GOOD_STATE, COM_HEIGHT_M, ok),
        "empty_polygon": (0.2, *GOOD_STATE, COM_HEIGHT_M, [SupportInterval(0.0, 5.0, np.zeros((0, 2)))]),
        "degenerate_polygon": (0.2, *GOOD_STATE, COM_HEIGHT_M, degenerate),
        "nan_polygon": (0.2, *GOOD_STATE, COM_HEIGHT_M, [SupportInterval(0.0, 5.0, np.full((4, 2), np.nan))]),
        "nan_interval": (0.2, *GOOD_STATE, COM_HEIGHT_M, [SupportInterval(math.nan, 5.0, ok[0].polygon)]),
        "bad_polygon_later": (
            0.2, *GOOD_STATE, COM_HEIGHT_M, ok[:2] + [SupportInterval(ok[1].t_end_s, 9.0, np.zeros((2, 2)))]
        ),
        "wrong_shapes": (0.2, np.zeros(3), GOOD_STATE[1], GOOD_STATE[2], COM_HEIGHT_M, ok),
    }


@pytest.mark.parametrize("case", sorted(_garbage_cases()))
def test_garbage_in_gives_finite_fallback(case: str) -> None:
    """Req. 6: invalid input never raises, never returns NaN, and says so in the status."""
    args = _garbage_cases()[case]
    sol = ComMpc().solve(*args)
    assert sol.status != "solved" and sol.status.startswith("invalid_input"), sol.status
    assert not sol.ok
    _assert_finite(sol)


def test_garbage_after_good_solution_reuses_or_falls_back() -> None:
    supports = walk(0.2, 0.4, 0.1, n_steps=4)
    mpc = ComMpc()
    good = mpc.solve(0.2, *GOOD_STATE, COM_HEIGHT_M, window(supports, 0.2))
    assert good.status == "solved"
    bad = mpc.solve(0.208, NAN2, *GOOD_STATE[1:], COM_HEIGHT_M, window(supports, 0.208))
    assert bad.status == "invalid_input_previous_solution"
    np.testing.assert_array_equal(bad.waypoints_xy_m, good.waypoints_xy_m)
    degenerate = window(supports, 0.208)[:1] + [SupportInterval(0.4, 9.0, np.zeros((3, 2)))]
    bad2 = mpc.solve(0.208, *good.com_at(0.208)[:2], good.cop_at(0.208), COM_HEIGHT_M, degenerate)
    assert bad2.status.startswith("invalid_input")
    _assert_finite(bad2)
    # The controller recovers on the next valid input, without a new setup.
    again = mpc.solve(0.216, *good.com_at(0.216)[:2], good.cop_at(0.216), COM_HEIGHT_M, window(supports, 0.216))
    assert again.status == "solved" and mpc.setup_count == 1


def test_empty_intersection_falls_back_to_closing_polygon() -> None:
    """Single support to single support without double support (a hop): disjoint feet."""
    left, right = foot(np.array([0.0, 0.1]), 0.0), foot(np.array([0.1, -0.1]), 0.0)
    final = convex_hull(np.vstack([foot(np.array([0.1, 0.1]), 0.0), right]))
    supports = [SupportInterval(0.0, 0.4, left), SupportInterval(0.4, 0.8, right), SupportInterval(0.8, 3.0, final)]
    com, vel, cop = np.array([0.0, 0.05]), np.array([0.07, 0.0245]), np.array([0.0, 0.1])
    sol = ComMpc().solve(0.0, com, vel, cop, COM_HEIGHT_M, supports)
    assert sol.status == "solved_empty_intersection" and sol.ok, sol.message
    _assert_finite(sol)
    i_end = int(np.argmin(np.abs(sol.waypoint_times_s - 0.4)))
    assert sol.waypoint_times_s[i_end] == pytest.approx(0.4)
    assert inside(sol.waypoints_xy_m[i_end], left, 1e-4)  # the polygon of the interval it closes
    np.testing.assert_allclose(sol.final_capture_point_xy_m, polygon_centroid(final), atol=3e-3)


def test_solver_failure_uses_fallback() -> None:
    """An iteration budget too small to converge gives a flagged, finite fallback."""
    supports = walk(0.2, 0.4, 0.1, n_steps=4)
    mpc = ComMpc(max_iter=1)
    sol = mpc.solve(0.2, *GOOD_STATE, COM_HEIGHT_M, window(supports, 0.2))
    assert sol.status == "solver_failed_centroid_fallback"
    _assert_finite(sol)
    np.testing.assert_allclose(sol.com_at(0.2)[0], GOOD_STATE[0])
    np.testing.assert_allclose(sol.cop_at(0.2), GOOD_STATE[2])
    assert_constraints(sol, supports)  # the fallback CoP stays in the supports too
    ref = rk4_com(sol, GOOD_STATE[0], GOOD_STATE[1])  # and its CoM is the integrated LIP
    np.testing.assert_allclose(ref[-1, :2], sol.final_com_xy_m, atol=1e-4)


def test_benchmark_runs() -> None:
    stats = benchmark_solve(n=40)
    assert {"median_us", "p99_us", "osqp_median_us", "median_iterations"} <= stats.keys()
    assert stats["solved_fraction"] == 1.0 and stats["setup_count"] == 1.0
    assert 0.0 < stats["median_us"] <= stats["p99_us"]
