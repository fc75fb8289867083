"""Tests for the CoM/CoP model predictive controller (engine/control/mpc/)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.constants import GRAVITY_MPS2
from engine.control.mpc import (
    ComMpc,
    ComMpcSolution,
    ComMpcWeights,
    SupportInterval,
    clip_convex_polygons,
    convex_hull,
    polygon_area,
    polygon_centroid,
    polygon_halfplanes,
    propagate_lip,
)
from engine.bench.mpc import benchmark_solve
from engine.bench.mpc_problems import closed_loop_like_problems, example_walking_supports

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
    """Alternating double/single supports of a straight walk (heading ``yaw_rad``), this file's feet."""
    return example_walking_supports(
        n_steps=n_steps, step_length_m=step_length_m, step_width_m=step_width_m, single_support_s=single_support_s,
        double_support_s=double_support_s, initial_double_support_s=initial_double_support_s,
        final_double_support_s=final_double_support_s, foot_length_m=FOOT_LENGTH_M, foot_width_m=FOOT_WIDTH_M,
        yaw_rad=yaw_rad)


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


@pytest.mark.parametrize("solver", ["active_set", "osqp"])
def test_padding_grows_on_demand_only(solver: str) -> None:
    supports = walk(0.2, 0.3, 0.1, n_steps=10)
    mpc = ComMpc(max_intervals=3, max_halfplanes=4, solver=solver)
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
    big = ComMpc(max_intervals=16, max_halfplanes=12, solver=solver)
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
#: A lateral push: several polygon rows are active at the optimum.
PUSHED_STATE = (np.array([0.0, 0.02]), np.array([0.3, 0.35]), np.array([0.0, 0.0]))


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


def test_solver_failure_uses_fallback(monkeypatch) -> None:
    """A failing QP solver gives a flagged, finite fallback (centroid plan, CoM integrated)."""
    import engine.control.mpc.active_set as active_set
    import engine.control.mpc.controller as com_mpc

    supports = walk(0.2, 0.4, 0.1, n_steps=4)

    def broken(*args, **kwargs):
        raise RuntimeError("solver exploded")

    def infeasible_window(*args, **kwargs):  # the one-call solve (solve_window) ending infeasible
        empty = np.zeros((0, 2))
        return active_set._AS_INFEASIBLE, 3, np.zeros(0, np.int64), np.nan, empty, empty, empty, np.zeros(4), np.nan, False

    for failure, window_failure in ((broken, broken),
                                    (lambda *a, **k: ([], np.zeros(0), 3, active_set._AS_INFEASIBLE), infeasible_window)):
        monkeypatch.setattr(com_mpc, "_dual_active_set", failure)  # the step-by-step path's solver
        monkeypatch.setattr(com_mpc, "solve_window", window_failure)  # and the one-call solve's
        monkeypatch.setattr(com_mpc, "plan_window", lambda *a, **k: (1,) + (None,) * 9)  # the one-call plan: no plan
        sol = ComMpc().solve(0.2, *PUSHED_STATE, COM_HEIGHT_M, window(supports, 0.2))
        assert sol.status == "solver_failed_centroid_fallback"
        assert not sol.ok
        _assert_finite(sol)
        np.testing.assert_allclose(sol.com_at(0.2)[0], PUSHED_STATE[0])
        np.testing.assert_allclose(sol.cop_at(0.2), PUSHED_STATE[2])
        assert_constraints(sol, supports)  # the fallback CoP stays in the supports too
        ref = rk4_com(sol, PUSHED_STATE[0], PUSHED_STATE[1])  # and its CoM is the integrated LIP
        np.testing.assert_allclose(ref[-1, :2], sol.final_com_xy_m, atol=1e-4)


@pytest.mark.parametrize("limit", [dict(max_iter=1), dict(time_limit_s=1e-9)])
def test_iteration_cap_returns_flagged_feasible_iterate(limit) -> None:
    """A budget too small to converge returns the last iterate pulled into the supports, flagged."""
    supports = walk(0.2, 0.4, 0.1, n_steps=4)
    args = (0.2, *PUSHED_STATE, COM_HEIGHT_M, window(supports, 0.2))
    exact = ComMpc().solve(*args)
    assert exact.status == "solved" and exact.osqp_iterations > 1  # really needs a few steps
    sol = ComMpc(**limit).solve(*args)
    assert sol.status == "solved_inaccurate" and sol.ok
    _assert_finite(sol)
    np.testing.assert_allclose(sol.cop_at(0.2), PUSHED_STATE[2], atol=1e-12)
    np.testing.assert_allclose(sol.com_at(0.2)[0], PUSHED_STATE[0], atol=1e-12)
    assert_constraints(sol, supports)
    ref = rk4_com(sol, PUSHED_STATE[0], PUSHED_STATE[1])
    np.testing.assert_allclose(ref[-1, :2], sol.final_com_xy_m, atol=1e-4)


def test_benchmark_runs() -> None:
    stats = benchmark_solve(n=40)
    assert {"median_us", "p99_us", "osqp_median_us", "median_iterations"} <= stats.keys()
    assert stats["solved_fraction"] == 1.0 and stats["setup_count"] == 1.0
    assert 0.0 < stats["median_us"] <= stats["p99_us"]


# ------------------------------------------- closed-loop-like regression (no pickle)


def _plan_quality(sol: ComMpcSolution, args: tuple, check_constraints: bool) -> float:
    """Asserts exactness of the plan for its inputs; returns the final capture-point error [m]."""
    t_now, com, vel, cop, height, supports = args
    assert sol.waypoint_times_s[0] == t_now
    np.testing.assert_allclose(sol.waypoints_xy_m[0], cop, atol=1e-12)
    omega = math.sqrt(GRAVITY_MPS2 / height)
    # The CoM plan is the exact LIP trajectory of its CoP from the given initial state.
    pos, vel_wp = propagate_lip(sol.waypoint_times_s, sol.waypoints_xy_m, com, vel, omega)
    np.testing.assert_allclose(sol.waypoint_com_xy_m, pos, atol=1e-9 * max(1.0, np.abs(pos).max()))
    np.testing.assert_allclose(sol.waypoint_com_vel_xy_mps, vel_wp, atol=1e-9 * max(1.0, np.abs(vel_wp).max()))
    if check_constraints:
        assert_constraints(sol, list(supports))
    return float(np.linalg.norm(sol.final_capture_point_xy_m - sol.region_centroids_xy_m[-1]))


def test_closed_loop_like_sequence_converges_in_few_iterations() -> None:
    """Regression for the closed-loop slowness: a realistic receding sequence (moving footholds,
    time scaling kappa in [0.75, 1.35], initial states off the previous plan) is solved with
    one instance in a few active-set steps, never falling back, with exact, feasible plans."""
    problems = closed_loop_like_problems(250, seed=2)
    # The sequence really has varying timing and moving footholds.
    singles = [s.t_end_s - s.t_start_s for args, _ in problems for s in args[5][1:-1] if len(s.polygon) == 4]
    assert min(singles) < 0.31 and max(singles) > 0.44
    moved = [
        np.linalg.norm(polygon_centroid(a[5][2].polygon) - polygon_centroid(b[5][2].polygon))
        for (a, _), (b, _) in zip(problems[:-1], problems[1:])
        if abs(a[5][2].t_start_s - b[5][2].t_start_s) < 0.05
    ]
    assert max(moved) > 0.005
    mpc = ComMpc()
    iterations = []
    for k, (args, kwargs) in enumerate(problems):
        sol = mpc.solve(*args, **kwargs)
        assert sol.status == "solved", (k, sol.status, sol.message)
        iterations.append(sol.osqp_iterations)
        cp_error = _plan_quality(sol, args, check_constraints=k % 10 == 0)
        assert cp_error < 0.01, (k, cp_error)  # final capture point at the last centroid
    assert np.median(iterations) <= 2
    assert max(iterations) <= 25
    assert mpc.setup_count <= 2


def test_large_deviations_and_alternating_streams_stay_solved() -> None:
    """Centimetre state deviations (often uncapturable) and a stream alternating between plan
    continuations and pushed restarts (what the controller does after a failed solve) are all
    solved well inside the iteration cap; plans stay feasible and exact."""
    problems = closed_loop_like_problems(150, seed=3, state_noise=(0.02, 0.05))
    mpc = ComMpc()
    iterations = []
    for k, (args, _) in enumerate(problems):
        pushed = list(args)
        pushed[2] = np.asarray(args[2]) + [0.3, -0.25]
        for a in (args, tuple(pushed)):
            sol = mpc.solve(*a)
            assert sol.status == "solved", (k, sol.status, sol.message)
            iterations.append(sol.osqp_iterations)
            _assert_finite(sol)
            _plan_quality(sol, a, check_constraints=k % 15 == 0)
    assert max(iterations) <= 90 < mpc.max_iter
    assert np.median(iterations) <= 6


def test_hopeless_state_is_solved_quickly() -> None:
    """A falling robot (2 m/s sideways): the QP is still solved exactly, CoP at the extremes."""
    supports = walk(0.25, 0.4, 0.1, n_steps=6)
    state = (np.array([0.0, 0.0]), np.array([0.5, 2.0]), np.array([0.0, 0.0]))
    sol = ComMpc().solve(0.1, *state, COM_HEIGHT_M, window(supports, 0.1))
    assert sol.status == "solved" and sol.osqp_iterations < 60
    _assert_finite(sol)
    assert_constraints(sol, supports)
    assert sol.waypoints_xy_m[1:, 1].max() > 0.09  # pushes the CoP to the outer edges


# ----------------------------------------------------- optimality and equivalence


def _eq14_cost(sol: ComMpcSolution, com, vel, weights: ComMpcWeights, cop_xy: np.ndarray) -> float:
    """Eq. 14's objective, with the final state from forward integration (independent of the QP)."""
    times = sol.waypoint_times_s
    omega = math.sqrt(GRAVITY_MPS2 / sol.com_height_m)
    pos, v = propagate_lip(times, cop_xy, com, vel, omega)
    cp = pos[-1] + v[-1] / omega
    dt = np.maximum(np.diff(times), 0.02)
    return float(
        weights.final_capture_point * np.sum((cp - sol.region_centroids_xy_m[-1]) ** 2)
        + weights.cop_centroid * np.sum((cop_xy[1:] - sol.region_centroids_xy_m[1:]) ** 2)
        + weights.cop_velocity * np.sum((np.diff(cop_xy, axis=0) / dt[:, None]) ** 2)
    )


def _independent_constraints(sol: ComMpcSolution, supports: list[SupportInterval]):
    """Rows A p <= b over waypoints 1..N from polygon_halfplanes (midpoint: C_k; end: C_k and C_k+1)."""
    n = len(sol.waypoint_times_s) - 1
    used = [s for s in supports if s.t_end_s > sol.t_start_s + 1e-3][: n // 2]
    rows, rhs = [], []
    for k, s in enumerate(used):
        for wp, polys in ((2 * k, [s]), (2 * k + 1, [s] + used[k + 1 : k + 2])):
            for poly in polys:
                for normal, offset in zip(*polygon_halfplanes(poly.polygon)):
                    row = np.zeros(2 * n)
                    row[2 * wp : 2 * wp + 2] = normal
                    rows.append(row)
                    rhs.append(offset)
    return np.array(rows), np.array(rhs)


def test_solution_is_the_eq14_optimum() -> None:
    """The condensed QP has Eq. 14's optimum: KKT conditions hold for the paper's objective
    evaluated independently (forward-integrated final state, finite-difference gradient,
    constraints from polygon_halfplanes), and the OSQP backend agrees with the active set."""
    from scipy.optimize import nnls

    supports = walk(0.25, 0.4, 0.1, n_steps=6)
    weights = ComMpcWeights()
    for t_now, push in ((0.63, [0.05, 0.12]), (1.37, [-0.1, -0.2])):
        com, vel, cop = consistent_state(supports, t_now)
        vel = vel + push  # a push: the optimum has active rows
        args = (t_now, com, vel, cop, COM_HEIGHT_M, window(supports, t_now))
        sol = ComMpc().solve(*args)
        assert sol.status == "solved" and sol.osqp_iterations > 0
        a_mat, b_vec = _independent_constraints(sol, window(supports, t_now))
        x_qp = sol.waypoints_xy_m[1:].ravel()
        slack = b_vec - a_mat @ x_qp
        assert slack.min() > -1e-9

        def cost(x: np.ndarray) -> float:
            return _eq14_cost(sol, com, vel, weights, np.vstack([cop, x.reshape(-1, 2)]))

        h = 1e-6  # the cost is quadratic: central differences are exact up to rounding
        grad = np.array([(cost(x_qp + h * e) - cost(x_qp - h * e)) / (2 * h) for e in np.eye(len(x_qp))])
        active = slack < 1e-7
        assert active.any()
        lam, residual = nnls(a_mat[active].T, -grad)  # grad + A_act^T lam = 0, lam >= 0
        assert residual <= 1e-5 * np.linalg.norm(grad) + 1e-9
        # Independent QP solver on the same condensed QP (a softer W_s, which ADMM handles).
        soft = ComMpcWeights(stability=1e4)
        osqp_sol = ComMpc(solver="osqp", weights=soft).solve(*args)
        assert osqp_sol.status == "solved"
        np.testing.assert_allclose(osqp_sol.waypoints_xy_m, ComMpc(weights=soft).solve(*args).waypoints_xy_m, atol=1e-6)


def test_stability_weight_softens_the_final_capture_point() -> None:
    supports = walk(0.25, 0.4, 0.1, n_steps=6)
    com, vel, cop = consistent_state(supports, 0.7)
    args = (0.7, com, vel + [0.0, 0.1], cop, COM_HEIGHT_M, window(supports, 0.7))
    exact = ComMpc().solve(*args)
    soft = ComMpc(weights=ComMpcWeights(stability=1e3)).solve(*args)
    assert exact.status == soft.status == "solved"

    def cp_error(sol: ComMpcSolution) -> float:
        return float(np.linalg.norm(sol.final_capture_point_xy_m - sol.region_centroids_xy_m[-1]))

    assert cp_error(exact) < 1e-3 < cp_error(soft)
    with pytest.raises(ValueError):
        ComMpc(weights=ComMpcWeights(stability=-1.0))


# ------------------------------------------------------------- geometry fast path


@HYPOTHESIS
@given(
    seed=st.integers(0, 2**31 - 1),
    n_points=st.integers(3, 12),
    clockwise=st.booleans(),
    collinear=st.booleans(),
    shift=st.integers(0, 11),
)
def test_vectorised_geometry_matches_reference(seed, n_points, clockwise, collinear, shift) -> None:
    from engine.control.mpc.regions import _support_geometry

    rng = np.random.default_rng(seed)
    polys = []
    for _ in range(3):
        hull = convex_hull(rng.uniform(-0.2, 0.2, (n_points, 2)) + rng.uniform(-1, 1, 2))
        if len(hull) < 3 or polygon_area(hull) < 1e-4:
            return
        if collinear:  # a vertex in the middle of an edge
            hull = np.insert(hull, 1, 0.5 * (hull[0] + hull[1]), axis=0)
        hull = np.roll(hull, shift % len(hull), axis=0)
        polys.append(hull[::-1].copy() if clockwise else hull)
    polys.append(np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 0.0], [0.0, 1.0]]))  # not convex in this order
    geom = _support_geometry(polys)
    assert geom is not None
    for k, poly in enumerate(polys):
        normals, offsets = polygon_halfplanes(convex_hull(poly))
        used = np.isfinite(geom.offsets[k])
        fast = np.column_stack([geom.normals[k][used].real, geom.normals[k][used].imag, geom.offsets[k][used]])
        ref = np.unique(np.round(np.column_stack([normals, offsets]), 9), axis=0)
        np.testing.assert_allclose(np.unique(np.round(fast, 9), axis=0), ref, atol=1e-8)
        centroid = geom.centroids[k]
        np.testing.assert_allclose([centroid.real, centroid.imag], polygon_centroid(convex_hull(poly)), atol=1e-9)


# ---------------------------------------------------------------- benchmark tools


def test_benchmark_captured_replays_an_npz(tmp_path) -> None:
    from engine.bench.mpc import benchmark_captured, load_problems, save_problems

    path = tmp_path / "cases.npz"
    problems = closed_loop_like_problems(40, seed=5)
    save_problems(path, problems)
    loaded = load_problems(path)
    assert len(loaded) == 40
    for (a, _), (b, _) in zip(problems, loaded):
        assert a[0] == b[0] and a[4] == b[4] and len(a[5]) == len(b[5])
        np.testing.assert_array_equal(a[1], b[1])
        np.testing.assert_array_equal(a[5][-1].polygon, b[5][-1].polygon)
    stats = benchmark_captured(str(path))
    assert stats["n"] == 40 and stats["solved_fraction"] == 1.0 and stats["fallback_count"] == 0
    assert stats["max_iterations"] <= 25 and 0.0 < stats["median_us"] <= stats["p99_us"]


def test_scalar_com_at_matches_the_vectorised_evaluation() -> None:
    """The controller's scalar fast path computes what the array path (the original) does."""
    supports = example_walking_supports(n_steps=4)
    plan = ComMpc().solve(0.0, np.zeros(2), np.array([0.05, -0.02]), np.zeros(2), COM_HEIGHT_M, supports)
    assert plan.ok
    times = np.concatenate([[-0.3, plan.t_start_s, plan.t_end_s, plan.t_end_s + 0.4], plan.waypoint_times_s,
                            np.linspace(plan.t_start_s - 0.1, plan.t_end_s + 0.1, 157)])
    pos, vel, acc = plan.com_at(times)
    for k, t in enumerate(times):
        p, v, a = plan.com_at(float(t))
        np.testing.assert_allclose(p, pos[k], rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(v, vel[k], rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(a, acc[k], rtol=1e-13, atol=1e-12)
