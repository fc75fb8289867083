"""The control stack's speed-ups compute the same numbers as the code they replaced (issue 12).

Each test keeps the implementation before the speed-up as the reference and asserts equal results on
random inputs: bit for bit where the code only moves numbers, to rounding (:mod:`tests.rounding`) where a
numpy product became float arithmetic (numpy's kernels round differently from one CPU to another).
"""

from __future__ import annotations

import bisect
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.control.mpc.types import ComMpcSolution
from engine.geometry.polygon import halfplanes_cached, polygon_halfplanes
from tests.rounding import ROUNDING_ULP, assert_equal_to_rounding


def com_at_scalar_reference(sol: ComMpcSolution, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ComMpcSolution._com_at_scalar before the speed-up (numpy scalars, bisect on the array)."""
    times, wps = sol.waypoint_times_s, sol.waypoints_xy_m
    n_seg = len(times) - 1
    t_first, t_last = float(times[0]), float(times[-1])
    j = min(max(bisect.bisect_right(times, t) - 1, 0), n_seg - 1)
    if t > t_last:
        anchor, sx, sy = n_seg, 0.0, 0.0
    else:
        anchor = j
        if t < t_first:
            sx = sy = 0.0
        else:
            h = max(float(times[j + 1] - times[j]), 1e-12)
            sx = float(wps[j + 1, 0] - wps[j, 0]) / h
            sy = float(wps[j + 1, 1] - wps[j, 1]) / h
    s = t - float(times[anchor])
    omega = sol.omega_rps
    ch, sh = math.cosh(omega * s), math.sinh(omega * s)
    px, py = float(wps[anchor, 0]), float(wps[anchor, 1])
    cx, cy = sol.waypoint_com_xy_m[anchor]
    vx, vy = sol.waypoint_com_vel_xy_mps[anchor]
    ex, ey = float(cx) - px, float(cy) - py
    dex, dey = float(vx) - sx, float(vy) - sy
    errx, erry = ex * ch + dex * sh / omega, ey * ch + dey * sh / omega
    pos = np.array([px + sx * s + errx, py + sy * s + erry])
    vel = np.array([sx + ex * omega * sh + dex * ch, sy + ey * omega * sh + dey * ch])
    acc = np.array([omega * omega * errx, omega * omega * erry])
    return pos, vel, acc


def test_com_at_scalar_equals_the_numpy_scalar_version() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        n = int(rng.integers(2, 12))
        times = np.cumsum(np.r_[rng.uniform(-1, 1), rng.uniform(0.0, 0.3, n - 1)])
        sol = ComMpcSolution(times, rng.normal(0, 0.2, (n, 2)), rng.normal(0, 0.2, (n, 2)), rng.normal(0, 0.5, (n, 2)),
                             float(rng.uniform(0.3, 1.0)), "solved", 0.0)
        for t in np.r_[times, rng.uniform(times[0] - 0.5, times[-1] + 0.5, 20)].tolist():
            for got, want in zip(sol.com_at(t), com_at_scalar_reference(sol, t)):
                np.testing.assert_array_equal(got, want)
            floats = sol.com_at_floats(t)  # the same numbers as floats (the walking controller's planner tick)
            assert floats == tuple(tuple(a) for a in (w.tolist() for w in com_at_scalar_reference(sol, t)))


coord = st.floats(-2.0, 2.0, allow_nan=False)


@settings(max_examples=80, deadline=None)
@given(st.lists(st.tuples(coord, coord), min_size=3, max_size=8))
def test_cached_halfplanes_equal_fresh_ones(points) -> None:  # noqa: ANN001
    from engine.geometry.polygon import convex_hull_2d

    polygon = convex_hull_2d(np.array(points))
    for _ in range(2):  # a miss, then a hit
        normals, offsets, bound = halfplanes_cached(polygon)
        want_n, want_o = polygon_halfplanes(polygon)
        np.testing.assert_array_equal(normals, want_n)
        np.testing.assert_array_equal(offsets, want_o)
        np.testing.assert_array_equal(bound, want_o + 1e-9)


def project_reference(support, target, swing_side, region):  # noqa: ANN001, ANN201
    """footsteps.project_to_safe_region before the speed-up (to_local array, np.clip)."""
    local = support.to_local(target)
    sign = 1.0 if swing_side == "left" else -1.0
    x, y_own = float(local[0]), float(sign * local[1])
    candidates = [(x, max(y_own, region.side_m)), (max(x, region.front_m), max(y_own, region.cross_m)),
                  (min(x, -region.front_m), max(y_own, region.cross_m))]
    best = min(candidates, key=lambda p: (p[0] - x) ** 2 + (p[1] - y_own) ** 2)
    yaw = float(np.clip(local[2], -region.max_yaw_rad, region.max_yaw_rad))
    if best == (x, y_own) and yaw == local[2]:
        return target
    return support.from_local(np.array([best[0], sign * best[1], yaw]))


def test_safe_region_projection_equals_the_array_version() -> None:
    from engine.gait.footsteps import Foothold, SafeRegion, project_to_safe_region

    rng = np.random.default_rng(5)
    region = SafeRegion.for_sole(0.2, 0.08)
    for _ in range(2000):
        support = Foothold(*rng.uniform(-1, 1, 2), float(rng.uniform(-4, 4)))
        offset = rng.normal(0, 0.25, 2)
        target = Foothold(support.x + offset[0], support.y + offset[1], float(support.yaw + rng.normal(0, 1.0)))
        for side in ("left", "right"):
            got, want = project_to_safe_region(support, target, side, region), project_reference(support, target, side, region)
            assert (got.x, got.y, got.yaw) == (want.x, want.y, want.yaw)


def edge_strip_reference(corners, length_m, edge):  # noqa: ANN001, ANN201
    """planner._edge_strip before the speed-up."""
    if edge is None:
        return corners
    f = min(0.02 / max(length_m, 1e-9), 1.0)
    bl, br, fr, fl = corners
    if edge == "heel":
        return np.array([bl, br, br + f * (fr - br), bl + f * (fl - bl)])
    return np.array([fl + f * (bl - fl), fr + f * (br - fr), fr, fl])


def test_compiled_support_hull_equals_corners_strips_and_hull() -> None:
    from engine.gait.footsteps import Foothold
    from engine.gait.planner import EDGE_SUPPORT_DEPTH_M
    from engine.gait.planner_kernels import support_hull
    from engine.geometry.polygon import convex_hull_2d

    assert EDGE_SUPPORT_DEPTH_M == 0.02
    rng = np.random.default_rng(7)
    for _ in range(3000):
        n = int(rng.integers(1, 3))
        holds = tuple(Foothold(*rng.uniform(-2, 2, 2), float(rng.uniform(-7, 7))) for _ in range(n))
        length, width = float(rng.uniform(0.005, 0.3)), float(rng.uniform(0.005, 0.15))
        edges = tuple(rng.choice(np.array([None, "heel", "toe"], dtype=object)) for _ in range(n))
        want = convex_hull_2d(np.concatenate([edge_strip_reference(h.corners(length, width), length, e)
                                              for h, e in zip(holds, edges)]))
        np.testing.assert_array_equal(support_hull(holds, length, width, edges, EDGE_SUPPORT_DEPTH_M), want)


def _numpy_fuses_complex_products() -> bool:
    """numpy's complex product rounds once per part (fused multiply-add SIMD, as on this machine's AVX2)."""
    a, b = np.full(4, 1.0 + 2.0 ** -30 + 1j), np.full(4, 1.0 - 2.0 ** -30 + 1j)
    return bool((a * b).real[0] != (1.0 + 2.0 ** -30) * (1.0 - 2.0 ** -30) - 1.0)


def _assert_same(got, want) -> None:  # noqa: ANN001
    """Bit-equal where numpy fuses its complex products as the kernels do; to rounding elsewhere."""
    if _numpy_fuses_complex_products():
        np.testing.assert_array_equal(got, want)
    else:
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_compiled_support_geometry_equals_the_complex_numpy_version() -> None:
    """The MPC's padded polygon geometry: convex (either orientation, collinear vertices), non-convex and
    degenerate polygons, 1–12 per call. numpy's complex products use fused multiply-adds on this machine's
    SIMD (the kernel does too); where numpy would not, the two may differ in the last bit."""
    from engine.control.mpc.regions import _geometry_padded, _geometry_padded_numpy
    from engine.geometry.polygon import convex_hull_2d

    rng = np.random.default_rng(11)
    for _ in range(1500):
        polys = []
        for _ in range(int(rng.integers(1, 13))):
            kind = rng.random()
            if kind < 0.1:  # non-convex or repeated vertices
                p = rng.normal(0.0, 1.0, (int(rng.integers(3, 9)), 2))
                if kind < 0.03:
                    p[1] = p[0]
            else:
                p = convex_hull_2d(rng.normal(0.0, 0.2, (int(rng.integers(3, 12)), 2)) + rng.normal(0.0, 2.0, 2))
                if len(p) < 3:
                    p = np.array([[0.0, 0.0], [0.1, 0.0], [0.0, 0.1]])
                if kind < 0.4:
                    p = p[::-1]
                if kind > 0.9:  # a collinear vertex: the midpoint of an edge
                    p = np.insert(p, 1, 0.5 * (p[0] + p[1]), axis=0)
            polys.append(np.ascontiguousarray(p))
        got, want = _geometry_padded(polys), _geometry_padded_numpy(polys)
        for g, w in zip(got, want):
            _assert_same(g, w)


def test_compiled_mpc_rows_equal_the_numpy_rows() -> None:
    """ComMpc._build_problem's rows (containment of consecutive supports, half-plane rows, waypoint times and
    centroid targets) from the compiled kernel and from the numpy code, on walking supports at random times,
    yaws and step sizes and on random (overlapping, non-nesting) polygons."""
    from dataclasses import fields
    from unittest import mock

    import engine.control.mpc.controller as mpc_controller
    from engine.bench.mpc_problems import example_walking_supports
    from engine.control.mpc import ComMpc, SupportInterval
    from engine.geometry.polygon import convex_hull_2d

    compiled = mpc_controller.problem_rows

    def numpy_rows(*args):  # noqa: ANN002, ANN202
        return (True, *compiled(*args)[1:])

    rng = np.random.default_rng(13)
    mpc = ComMpc()
    for case in range(400):
        if case % 4 == 3:  # random convex polygons: general overlaps, disjoint supports
            t = np.cumsum(rng.uniform(0.05, 0.6, 8))
            supports = [SupportInterval(float(a), float(b), convex_hull_2d(rng.normal(0, 0.15, (6, 2)) + rng.normal(0, 0.1, 2)))
                        for a, b in zip(np.r_[0.0, t[:-1]], t)]
        else:
            supports = example_walking_supports(n_steps=int(rng.integers(2, 10)), step_length_m=float(rng.uniform(-0.3, 0.4)),
                                                step_width_m=float(rng.uniform(0.1, 0.3)), single_support_s=float(rng.uniform(0.2, 0.7)),
                                                double_support_s=float(rng.uniform(0.02, 0.3)), yaw_rad=float(rng.uniform(-3, 3)))
        t_now = float(rng.uniform(0.0, 1.5))
        got, _ = mpc._build_problem(t_now, supports)
        with mock.patch.object(mpc_controller, "problem_rows", numpy_rows):
            want, _ = mpc._build_problem(t_now, supports)
        assert (got is None) == (want is None)
        if got is None:
            continue
        for f in fields(want):
            g, w = np.asarray(getattr(got, f.name)), np.asarray(getattr(want, f.name))
            assert g.dtype == w.dtype, f.name
            _assert_same(g, w)


def _assert_equal_to_rounding(got, want, rtol: float = 1e-12) -> None:  # noqa: ANN001
    """Equal to rounding relative to the array's scale: exp/expm1 are numba's (LLVM's libm) in the kernel and
    numpy's own SIMD implementations in the reference, which differ in the last bit on some CPUs (seen on an
    AVX2 Xeon without AVX-512), and the unstable LIP's propagation grows by e^(ω t) up to ~1e40 here."""
    got, want = np.asarray(got), np.asarray(want)
    assert got.shape == want.shape and got.dtype == want.dtype
    scale = float(np.max(np.abs(want))) if want.size else 0.0
    np.testing.assert_allclose(got, want, rtol=rtol, atol=rtol * scale)


def test_compiled_lip_segments_and_propagation_equal_numpy() -> None:
    from engine.control.mpc.lip import _Segments

    rng = np.random.default_rng(17)
    for _ in range(2000):
        n = int(rng.integers(1, 30))
        steps = rng.uniform(0.0, 0.4, n)
        steps[rng.random(n) < 0.1] = 0.0  # zero-length and tiny segments: the limit branch
        steps[rng.random(n) < 0.1] *= 1e-10
        times = float(rng.uniform(-5, 5)) + np.r_[0.0, np.cumsum(steps)]
        omega = float(rng.uniform(0.5, 8.0))
        got, want = _Segments.build(times, omega), _Segments.build_numpy(times, omega)
        np.testing.assert_array_equal(got.h, want.h)  # a subtraction: the same on every machine
        for name in ("a", "b", "grow"):
            _assert_equal_to_rounding(getattr(got, name), getattr(want, name))
        cop, com, vel = rng.normal(0, 0.3, (n + 1, 2)), rng.normal(0, 0.3, 2), rng.normal(0, 0.5, 2)
        for g, w in zip(got.propagate(cop, com, vel), want.propagate_numpy(cop, com, vel)):
            _assert_equal_to_rounding(g, w)


def test_compiled_warm_start_matching_equals_numpy() -> None:
    """ComMpc._match_warm: the rows of a later problem matching a remembered solution's active rows."""
    from engine.bench.mpc_problems import example_walking_supports
    from engine.control.mpc import ComMpc

    rng = np.random.default_rng(19)
    mpc = ComMpc()
    matched = 0
    for _ in range(300):
        kw = dict(n_steps=int(rng.integers(2, 8)), step_length_m=float(rng.uniform(-0.3, 0.4)), yaw_rad=float(rng.uniform(-3, 3)))
        t0 = float(rng.uniform(0.0, 1.0))
        before, _ = mpc._build_problem(t0, example_walking_supports(**kw))
        after, _ = mpc._build_problem(t0 + float(rng.uniform(0.0, 0.05)),
                                      example_walking_supports(**kw, t0_s=float(rng.normal(0.0, 0.01))))
        rows = rng.choice(len(before.row_key), size=int(rng.integers(0, min(12, len(before.row_key)) + 1)), replace=False)
        entry = (before.row_key[rows], before.normals_c[rows])
        got = mpc._match_warm(after, entry)
        assert got == mpc._match_warm_numpy(after, entry)
        matched += len(got)
    assert matched > 300  # most remembered rows find their match


def path_table_reference(pose, th, dx, dy):  # noqa: ANN001, ANN201
    """GaitPlanner._build_path_table's poses before the speed-up (numpy cumsums)."""
    poses = np.empty((len(th), 3))
    poses[0] = pose
    np.cumsum(th[:-1], out=poses[1:, 2])
    poses[1:, 2] += poses[0, 2]
    c, s_ = np.cos(poses[:-1, 2]), np.sin(poses[:-1, 2])
    np.cumsum(c * dx[:-1] - s_ * dy[:-1], out=poses[1:, 0])
    np.cumsum(s_ * dx[:-1] + c * dy[:-1], out=poses[1:, 1])
    poses[1:, :2] += poses[0, :2]
    return poses


def _command_ramp(command, goal, rate_limits):  # noqa: ANN001, ANN202
    """The planner's path table's velocity part: (times, piece velocities, turn angles, arcs dx, dy)."""
    from engine.gait.planner import _PATH_TABLE_TIMES, PATH_TABLE_STEP_S
    from engine.gait.planner_kernels import command_ramp_pieces

    return (_PATH_TABLE_TIMES, *command_ramp_pieces(np.asarray(command, dtype=float), np.asarray(goal, dtype=float),
                                                    np.asarray(rate_limits, dtype=float), PATH_TABLE_STEP_S,
                                                    len(_PATH_TABLE_TIMES)))


def test_compiled_path_table_equals_the_numpy_cumsums() -> None:
    from engine.gait.planner import PATH_TABLE_STEP_S
    from engine.gait.planner_kernels import path_table, path_table_poses

    rng = np.random.default_rng(23)
    for _ in range(500):
        command, goal = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3)
        if rng.random() < 0.2:
            goal = command.copy()  # held: the ramp's early exit
        limits = rng.uniform(0.1, 3.0, 3)
        _, _, th, dx, dy = _command_ramp(command, goal, limits)
        pose = rng.uniform(-5, 5, 3)
        # cos/sin are libm's in the kernel and numpy's SIMD ones in the reference: equal to rounding (bit-equal on
        # AVX2 machines, not necessarily where numpy dispatches AVX-512 versions)
        _assert_equal_to_rounding(path_table_poses(*pose.tolist(), th, dx, dy), path_table_reference(pose, th, dx, dy))
        # the planner's one call: the ramp and the poses (the same kernels)
        poses, vels = path_table(*pose.tolist(), command, goal, limits, PATH_TABLE_STEP_S, len(th))
        np.testing.assert_array_equal(poses, path_table_poses(*pose.tolist(), th, dx, dy))
        np.testing.assert_array_equal(vels, _command_ramp(command, goal, limits)[1])


def test_compiled_merged_bank_equals_numpy() -> None:
    """MergedBank.evaluate (every channel of every blended sample at its own time) at random member times,
    negative and beyond the cycle, on the shipped G1 neutral style's samples."""
    from engine.gait.blending import ChannelLayout, MergedBank, StyleBanks
    from engine.gait.style import StyleContext, load_style, styles_dir

    ctx = StyleContext.for_robot("g1")
    layout = ChannelLayout(ctx.upper_joints, np.array([ctx.standing_angles[j] for j in ctx.upper_joints]))
    banks = list(StyleBanks(load_style(styles_dir("g1") / "neutral.json"), layout).banks.values())
    rng = np.random.default_rng(29)
    for _ in range(300):
        members = [banks[i] for i in rng.choice(len(banks), size=int(rng.integers(1, 5)), replace=False)]
        merged = MergedBank(members)
        times, scale = rng.uniform(-3.0, 5.0, len(members)), rng.uniform(0.5, 2.0, len(members))
        times[rng.random(len(members)) < 0.2] = 0.0
        for g, w in zip(merged.evaluate(times, scale), merged.evaluate_numpy(times, scale)):
            np.testing.assert_array_equal(g, w)


# ----------------------------------------------------------------------------- per-tick glue (issue 12, wbc pass)


class ObserverReference:
    """ExternalForceObserver before the speed-up (numpy 2-vectors, np.linalg.norm)."""

    def __init__(self, mass_kg: float, time_constant_s: float = 0.08, deadband_n_per_kg: float = 0.25,
                 max_n_per_kg: float = 4.0):
        self.mass_kg = float(mass_kg)
        self.gain = 1.0 / time_constant_s
        self.deadband_n = deadband_n_per_kg * mass_kg
        self.max_n = max_n_per_kg * mass_kg
        self.reset()

    def reset(self, com_vel_xy=None) -> None:  # noqa: ANN001
        self._p0 = None if com_vel_xy is None else self.mass_kg * np.asarray(com_vel_xy, dtype=float)
        self._integral = np.zeros(2)
        self._residual = np.zeros(2)
        self.force_n = np.zeros(2)

    def update(self, dt_s: float, com_vel_xy, ground_force_xy_n):  # noqa: ANN001, ANN201
        p = self.mass_kg * np.asarray(com_vel_xy, dtype=float)
        if not np.all(np.isfinite(p)):
            return self.force_n
        if self._p0 is None:
            self._p0 = p.copy()
            return self.force_n
        if ground_force_xy_n is None or not np.all(np.isfinite(ground_force_xy_n)):
            self._integral = p - self._p0 - self._residual / self.gain
            return self.force_n
        self._integral += (np.asarray(ground_force_xy_n, dtype=float) + self._residual) * dt_s
        self._residual = self.gain * (p - self._p0 - self._integral)
        norm = float(np.linalg.norm(self._residual))
        if norm > self.max_n:
            self._residual *= self.max_n / norm
            norm = self.max_n
        self.force_n = self._residual * (1.0 - self.deadband_n / norm) if norm > self.deadband_n else np.zeros(2)
        return self.force_n


def test_observer_on_floats_equals_the_numpy_version() -> None:
    from engine.control.disturbance_observer import ExternalForceObserver

    rng = np.random.default_rng(1)
    for trial in range(60):
        mass = float(rng.uniform(20.0, 100.0))
        ours, reference = ExternalForceObserver(mass), ObserverReference(mass)
        v0 = rng.normal(0.0, 0.3, 2) if trial % 3 else None
        ours.reset(v0)
        reference.reset(v0)
        v = np.zeros(2)
        scale = 10.0 ** rng.uniform(0.0, 3.5)  # from inside the deadband to beyond the fall cap
        for _ in range(300):
            v = v + rng.normal(0.0, 1e-4 * scale, 2)
            ground = rng.normal(0.0, scale, 2)
            draw = rng.random()
            told = None if draw < 0.05 else (np.array([np.nan, 1.0]) if draw < 0.07 else ground)
            seen = v.copy()
            if rng.random() < 0.02:
                seen[0] = np.inf
            got, want = ours.update(0.002, seen, told), reference.update(0.002, seen, told)
            assert_equal_to_rounding(got, want, scale=4 * scale)  # a residual of forces of size ``scale``


def test_horizontal_ground_force_equals_the_einsum() -> None:
    """The float and compiled sums (numpy's order here) against the einsum they replace: equal to rounding
    (bit for bit on the machine of this pass; numpy's SIMD order may differ on another CPU)."""
    from engine.control.walking_controller import _horizontal_ground_force
    from engine.control.wbc.kernels import horizontal_force
    from engine.control.wbc.reference import WbcDiagnostics

    rng = np.random.default_rng(5)
    for k in range(500):
        rho = np.abs(rng.normal(0.0, 10.0 ** rng.uniform(-2, 3), 32)) * (rng.random(32) > 0.3)
        if k % 7 == 0:
            rho[:16] = 0.0
        basis = rng.normal(0.0, 1.0, (2, 3, 4))
        want = np.einsum("fkb,fb->k", basis[:, :2, :], rho.reshape(2, -1, 4).sum(axis=1))
        scale = float(np.abs(basis).max() * rho.sum())
        for got in (_horizontal_ground_force(WbcDiagnostics(status="solved", rho=rho, basis=basis)),
                    horizontal_force(rho, basis)):
            np.testing.assert_allclose(got, want, rtol=0.0, atol=1e-15 * scale)


def test_early_touchdown_flag_equals_the_array_expression() -> None:
    from engine.control.touchdown import early_touchdown

    for bits in range(2 ** 10):
        corners = np.array([(bits >> i) & 1 for i in range(8)], dtype=bool).reshape(2, 4)
        planned = np.array([(bits >> 8) & 1, (bits >> 9) & 1], dtype=bool)
        assert early_touchdown(corners, planned) == bool(np.any(corners.any(axis=1) & ~planned))


def command_ramp_reference(command, goal, rate_limits):  # noqa: ANN001, ANN201
    """The planner's command ramp before the speed-up (a float loop for the ramp, numpy for the arcs)."""
    from engine.gait.planner import PATH_TABLE_HORIZON_S, PATH_TABLE_STEP_S

    h = PATH_TABLE_STEP_S
    n = int(math.ceil(PATH_TABLE_HORIZON_S / PATH_TABLE_STEP_S)) + 1
    times = np.arange(n) * PATH_TABLE_STEP_S
    vels = np.empty((n, 3))
    for j in range(3):
        g, lim, v = float(goal[j]), abs(float(rate_limits[j])) * h, float(command[j])
        column = vels[:, j]
        for i in range(n):
            dv = min(max(g - v, -lim), lim)
            column[i] = v + 0.5 * dv
            if dv == 0.0:
                column[i + 1:] = v
                break
            v = v + dv
    w = vels[:, 2]
    th = w * h
    small = np.abs(th) < 1e-9
    w_safe = np.where(small, 1.0, w)
    sinc = np.where(small, h * (1.0 - th * th / 6.0), np.sin(th) / w_safe)
    cosc = np.where(small, h * (0.5 * th), (1.0 - np.cos(th)) / w_safe)
    return times, vels, th, vels[:, 0] * sinc - vels[:, 1] * cosc, vels[:, 0] * cosc + vels[:, 1] * sinc


def test_compiled_command_ramp_equals_the_loop_and_numpy_arcs() -> None:

    rng = np.random.default_rng(31)
    for case in range(800):
        command, goal, limits = rng.uniform(-1, 1, 3), rng.uniform(-1, 1, 3), rng.uniform(0.05, 3.0, 3)
        if case % 5 == 0:
            goal = command.copy()  # held: the ramp's early exit
        if case % 7 == 0:
            goal[2] = command[2] = 0.0  # no turn: the arcs' straight-line branch
        if case % 11 == 0:
            limits = -limits  # |limit|
        got, want = _command_ramp(command, goal, limits), command_ramp_reference(command, goal, limits)
        for g, w in zip(got[:3], want[:3]):  # times, the ramp and the turn angles: plain float arithmetic
            np.testing.assert_array_equal(g, w)
        for g, w in zip(got[3:], want[3:]):  # arcs: libm's sin/cos in the kernel, numpy's (the same on AVX2)
            _assert_equal_to_rounding(g, w)


def test_compiled_preview_polygons_equal_corners_and_support_hull() -> None:
    from engine.gait.footsteps import Foothold
    from engine.gait.planner import EDGE_SUPPORT_DEPTH_M
    from engine.gait.planner_kernels import EDGE_CODES, preview_polygons, support_hull

    rng = np.random.default_rng(37)
    names = [None, "heel", "toe"]
    for _ in range(300):
        n = int(rng.integers(1, 12))
        poses = np.column_stack([rng.uniform(-2, 2, (n * 2, 2)), rng.uniform(-7, 7, n * 2)]).reshape(n, 2, 3)
        down = rng.random((n, 2)) < 0.6
        down[~down.any(axis=1), int(rng.integers(0, 2))] = True
        edge_names = [[names[int(rng.integers(0, 3))] for _ in range(2)] for _ in range(n)]
        codes = np.array([[EDGE_CODES[e] for e in row] for row in edge_names], dtype=np.int64)
        length, width = float(rng.uniform(0.005, 0.3)), float(rng.uniform(0.005, 0.15))
        trim = float(rng.choice([0.0, rng.uniform(-0.05, 0.4)]))
        polygons, counts = preview_polygons(poses, down, codes, length, width, trim, EDGE_SUPPORT_DEPTH_M)
        for i in range(n):
            holds = [Foothold(*poses[i, j]) for j in range(2)]
            if down[i].all():
                want = support_hull(tuple(holds), length, width, tuple(edge_names[i]), EDGE_SUPPORT_DEPTH_M)
            else:
                want = holds[0 if down[i, 0] else 1].corners(length, width, trim)
            np.testing.assert_array_equal(polygons[i, :counts[i]], want)


def _at_event(phi: float, event_phi: float) -> bool:
    d = phi - event_phi
    return abs(d - round(d)) < 1e-9


def preview_reference(planner, kappa: float = 1.0, horizon_s: float = 2.0, edges_seen: list | None = None):  # noqa: ANN001, ANN201
    """GaitPlanner.preview before the speed-up: event times from blend.event_time, one support_hull / corners
    call per interval, the rolling edge's pitch from Rz(yaw)ᵀ R, footholds from the numpy path table."""
    from engine.constants import SIDES
    from engine.gait.blending import SWING_PHASES
    from engine.gait.footsteps import foothold_from_path, project_to_safe_region
    from engine.gait.path_frame import predict
    from engine.gait.phase_map import PHI_LTD, PHI_RLO, PHI_RTD
    from engine.gait.planner import EDGE_SUPPORT_DEPTH_M, ContactPhase, _pitched_edge, _remaining_ease_delay
    from engine.gait.planner_kernels import support_hull
    from engine.geometry import rot_z

    self = planner
    sides = ("left", "right")

    def path_ahead(dt_s):  # noqa: ANN001, ANN202
        if self.command_goal is None or self.command_rate_limits is None:
            return self.path.predicted(self.command, dt_s)
        # the table the planner built this tick (kept until its next step, as before: a touchdown's path shift
        # under path_follows_feet does not rebuild it)
        times, poses, vels = self._path_table if self._path_table is not None else self._build_path_table()
        k = min(int(dt_s / 0.05), len(times) - 1)
        return predict(poses[k], vels[k], dt_s - times[k])

    def rolling_edge(side, phi_start, phi_end):  # noqa: ANN001, ANN202
        lo, td = SWING_PHASES[side]
        liftoff_pitch, touchdown_pitch = self.blend.boundary_pitch[side]
        if phi_start == self.phi and self._last_pose is not None:
            rot = self._last_pose["rots"][1 + SIDES.index(side)]  # the sole's rotation (rows: pelvis, left, right)
            yaw = math.atan2(rot[1, 0], rot[0, 0])
            pitch = -math.asin(max(-1.0, min(1.0, (rot_z(yaw).T @ rot)[2, 0])))
            edge = _pitched_edge(min(pitch, 0.0), max(pitch, 0.0))
            if edge is not None:
                return edge
        elif self.landed[side] and _at_event(phi_start, td):
            edge = _pitched_edge(*touchdown_pitch)
            if edge is not None:
                return edge
        if _at_event(phi_end, lo):
            return _pitched_edge(*liftoff_pitch)
        return None

    blend = self.blend
    t_now = blend.time_at(self.phi)
    phases = []
    footholds = {s: (self.target[s] if self.in_swing(s, self.phi) else self.latched[s]) for s in sides}
    swinging = {s for s in sides if self.in_swing(s, self.phi)}
    k = math.floor(self.phi)
    boundaries = [k + c + e for c in range(4) for e in (0.0, PHI_LTD, PHI_RLO, PHI_RTD) if k + c + e > self.phi]
    prev_phi = self.phi
    hold = _remaining_ease_delay(self.hold_s)
    length = self.sole_length_m - 2.0 * self.preview_margin_m
    width = self.sole_width_m - 2.0 * self.preview_margin_m
    for b in boundaries:
        t0 = ((blend.event_time(prev_phi) if prev_phi != self.phi else t_now) - t_now) / kappa
        t1 = (blend.event_time(b) - t_now) / kappa
        if prev_phi != self.phi:
            t0 += hold
        t1 += hold
        down = [s for s in sides if not self.in_swing(s, 0.5 * (prev_phi + b))]
        if len(down) == 1:
            polygon = footholds[down[0]].corners(length, width, self.preview_toe_trim_m)
        else:
            edges = tuple(rolling_edge(s, prev_phi, b) for s in down)
            if edges_seen is not None:
                edges_seen.extend(e for e in edges if e is not None)
            polygon = support_hull(tuple(footholds[s] for s in down), length, width, edges, EDGE_SUPPORT_DEPTH_M)
        phases.append(ContactPhase(self.t_s + t0, self.t_s + t1, {s: footholds[s] for s in down}, polygon))
        if t1 >= horizon_s:
            break
        f = b - math.floor(b)
        for side in sides:
            if abs(f - SWING_PHASES[side][1]) < 1e-9:
                if side in swinging:
                    swinging.discard(side)
                else:
                    lo, _ = SWING_PHASES[side]
                    t_mid = 0.5 * (blend.event_time(b) + blend.event_time(math.floor(b - lo) + 1 + lo))
                    target = foothold_from_path(path_ahead(max(t_mid - t_now, 0.0)), self.stance(side))
                    other = "right" if side == "left" else "left"
                    footholds = {**footholds, side: project_to_safe_region(footholds[other], target, side, self.region)}
        prev_phi = b
    return phases


def _rolling_style():  # noqa: ANN202
    """G1's neutral style with every sample lifting off on its toe and landing on its heel (0.3 rad)."""
    from engine.gait.curves import HermiteCurve, Knot, TangentMode
    from engine.gait.style import load_style, styles_dir

    style = load_style(styles_dir("g1") / "neutral.json")
    flat = TangentMode.FLAT
    for name, sample in style.samples.items():
        for side in ("left", "right"):
            d = sample.intervals.swing_duration_s(side)
            sample = sample.with_curve(f"{side}_foot.toe_pitch", HermiteCurve(
                [Knot(0.0, 0.3, mode=flat), Knot(0.5 * d, 0.0, mode=flat), Knot(d, 0.0, mode=flat)], d))
            sample = sample.with_curve(f"{side}_foot.heel_pitch", HermiteCurve(
                [Knot(0.0, 0.0, mode=flat), Knot(0.5 * d, 0.0, mode=flat), Knot(d, -0.3, mode=flat)], d))
        style = style.with_sample(name, sample)
    return style


def test_preview_equals_the_reference_preview() -> None:
    """The planner's contact preview (timings, footholds, polygons) along a G1 walk under a ramping command with
    its goal, time scaling and step adjustments, with heel/toe rolling edges and a toe trim, and without a goal."""
    from engine.gait.offline_plan import planner_for
    from engine.gait.planner import PlannerFeedback
    from engine.gait.style import StyleContext, load_style, styles_dir
    from engine.robot.model import load_robot

    robot = load_robot("g1")
    rng = np.random.default_rng(41)
    compared, edges = 0, []
    for with_goal, style in ((True, _rolling_style()), (False, load_style(styles_dir("g1") / "neutral.json"))):
        planner = planner_for(robot, style, StyleContext.for_robot("g1"))
        planner.preview_margin_m, planner.preview_toe_trim_m, planner.path_follows_feet = 0.01, 0.03, 0.5
        command, goal = np.zeros(3), np.array([0.4, 0.1, 0.3])
        for k in range(700):
            if k % 150 == 0:
                goal = rng.uniform([-0.3, -0.2, -0.6], [0.5, 0.2, 0.6])
            command = command + np.clip(goal - command, -0.01, 0.01)
            kappa = float(rng.uniform(0.7, 1.4))
            fb = PlannerFeedback(kappa, rng.normal(0.0, 0.02, 2) if k % 3 else None,
                                 goal if with_goal else None, np.array([0.5, 0.5, 1.0]) if with_goal else None)
            ref = planner.step(0.008, command, fb)
            want = preview_reference(planner, kappa, edges_seen=edges)
            assert len(ref.preview) == len(want)
            for got_phase, want_phase in zip(ref.preview, want):
                assert (got_phase.t_start_s, got_phase.t_end_s) == (want_phase.t_start_s, want_phase.t_end_s)
                assert got_phase.footholds == want_phase.footholds
                np.testing.assert_array_equal(got_phase.polygon, want_phase.polygon)
                compared += 1
    assert compared > 5000 and edges.count("heel") > 100 and edges.count("toe") > 100  # soles on their edge strips


def _deadband_reference(x, width):  # noqa: ANN001, ANN202
    norm = math.sqrt(float(x.dot(x)))
    if norm <= width:
        return np.zeros(x.shape)
    return x * (1.0 - width / norm)


def gait_feedback_update_reference(fb, dt_s, com_xy, com_vel_xy, ref_com_xy, ref_com_vel_xy,  # noqa: ANN001, ANN201
                                   com_height_m, path_yaw_rad, stance_xy, next_xy, single_support):
    """GaitFeedback.update before the speed-up (2-vector numpy expressions)."""
    from engine.control.gait_feedback import GRAVITY_MPS2, FeedbackOutput
    g = fb.gains
    e = np.asarray(com_xy, dtype=float) - np.asarray(ref_com_xy, dtype=float)
    ed = np.asarray(com_vel_xy, dtype=float) - np.asarray(ref_com_vel_xy, dtype=float)
    if not fb.enabled or not all(math.isfinite(v) for v in (*e.tolist(), *ed.tolist())):
        fb.last = FeedbackOutput(np.zeros(2), np.zeros(2), 1.0, 0.0, 0.0, np.where(np.isfinite(e), e, 0.0))
        return fb.last
    raw = _deadband_reference(g.velocity_kp_per_s * e + g.velocity_kd * ed, g.velocity_deadband_mps)
    alpha = 1.0 - math.exp(-2.0 * math.pi * g.velocity_cutoff_hz * dt_s)
    fb.velocity_adjust += alpha * (raw - fb.velocity_adjust)
    norm = math.sqrt(float(fb.velocity_adjust.dot(fb.velocity_adjust)))
    if norm > g.velocity_max_mps:
        fb.velocity_adjust *= g.velocity_max_mps / norm
    c, s = math.cos(path_yaw_rad), math.sin(path_yaw_rad)
    vel_path = np.array([c * fb.velocity_adjust[0] + s * fb.velocity_adjust[1],
                         -s * fb.velocity_adjust[0] + c * fb.velocity_adjust[1]])
    omega = math.sqrt(GRAVITY_MPS2 / max(com_height_m, 0.2))
    step = _deadband_reference(g.step_gain * (e + ed / omega), g.step_deadband_m)
    norm = math.sqrt(float(step.dot(step)))
    if norm > g.step_max_m:
        step *= g.step_max_m / norm
    eps = eps_rate = 0.0
    if stance_xy is not None and next_xy is not None:
        axis = np.asarray(next_xy, dtype=float) - np.asarray(stance_xy, dtype=float)
        length = math.sqrt(float(axis.dot(axis)))
        if length > 1e-3:
            u = axis / length
            eps, eps_rate = float(e @ u), float(ed @ u)
    lo, hi = g.kappa_single if single_support else g.kappa_double
    kappa = min(max(math.exp(min(max(g.time_kp_per_m * eps + g.time_kd_s_per_m * eps_rate, -5.0), 5.0)), lo), hi)
    fb.last = FeedbackOutput(vel_path, step, kappa, eps, eps_rate, e)
    return fb.last


def test_gait_feedback_on_floats_equals_the_numpy_version() -> None:
    from engine.control.gait_feedback import GaitFeedback
    rng = np.random.default_rng(12)
    new, old = GaitFeedback(), GaitFeedback()
    for k in range(4000):
        scale = 10.0 ** rng.uniform(-4.0, 0.5)  # within and beyond the deadbands and limits
        args = (0.008, rng.standard_normal(2) * scale, rng.standard_normal(2) * scale, rng.standard_normal(2) * scale,
                rng.standard_normal(2) * scale, float(rng.uniform(0.4, 1.0)), float(rng.uniform(-4.0, 4.0)),
                None if k % 7 == 0 else rng.standard_normal(2) * 0.3, rng.standard_normal(2) * 0.3 * (k % 5 != 0),
                bool(k % 2))
        if k % 97 == 0:
            args[1][k % 2] = np.nan
        got, want = new.update(*args), gait_feedback_update_reference(old, *args)
        for name in ("velocity_adjust_mps", "step_adjust_m", "error_m"):
            w = getattr(want, name)
            assert_equal_to_rounding(getattr(got, name), w, scale=4 * scale, err_msg=name)  # errors of size ``scale``
        # ε and its rate are dot products of errors of size ``scale`` with a unit vector
        assert_equal_to_rounding([got.epsilon_m, got.epsilon_rate_mps], [want.epsilon_m, want.epsilon_rate_mps],
                                 scale=4 * scale)
        assert_equal_to_rounding(got.kappa, want.kappa, scale=want.kappa * 10.0)  # exp of gains × ε
        assert_equal_to_rounding(new.velocity_adjust, old.velocity_adjust, scale=4 * scale)


def reachable_steps_reference(self, fb):  # noqa: ANN001, ANN201
    """StepAdjustment.reachable_steps (formerly WalkingController._reachable_steps) before the speed-up (2-vector numpy expressions), with the legs' reach
    from the stance foot bounding an adjustment beyond max_step_adjust_m (issues 13/14)."""
    import dataclasses

    from engine.constants import GRAVITY_MPS2
    from engine.geometry.vector import vector_norm
    from engine.gait.style import SIDES
    planner, plan = self.planner, self.plan
    if plan is None:
        return fb
    adjust = fb.step_adjust_m.copy()
    z = self._com_z if self._com_z is not None else self.robot.q_standing[2] + self.com_offset_m
    omega = math.sqrt(GRAVITY_MPS2 / max(z, 0.2))
    c, s_ = math.cos(planner.path.yaw), math.sin(planner.path.yaw)
    forward, left = np.array([c, s_]), np.array([-s_, c])
    # Where the robot is off the plan, its ξ runs away from the plan's as e^{ωt} under the
    # same CoP (the whole-body controller's corrections slow that: the growth is capped).
    pos_now, vel_now, _ = plan.com_at(planner.t_s)
    com, com_vel = self._com_state()
    dcm_error = (com + com_vel / omega) - (pos_now + vel_now / omega)
    err = vector_norm(dcm_error)  # ordinary tracking error is the MPC's to handle
    dcm_error *= max(err - self.params.dcm_error_deadband_m, 0.0) / err if err > 0.0 else 0.0
    steps = self.step_adjustment
    if self.observer.force_n.any():
        steps.pushed_at_s = planner.t_s
    from_stance = (self.params.capture_from_stance_foot
                   and planner.t_s - steps.pushed_at_s < self.params.stance_capture_after_push_s)
    reach_bounded = from_stance
    for side in SIDES:
        t_td = planner.time_to_touchdown_s(side, fb.kappa)
        if t_td is None:
            continue
        nominal = planner.nominal_target(side)
        pos, vel, _ = plan.com_at(planner.t_s + t_td)
        growth = min(math.exp(omega * t_td), self.params.dcm_error_growth_cap)
        dcm = pos + vel / omega + growth * dcm_error - self._mpc_shift  # ξ against the real soles
        if from_stance:  # pushed: where the stance foot says ξ goes, whatever the plan says
            dcm = steps.xi_at_touchdown(side, com, com_vel, omega, t_td, self._mpc_shift)
        rel = np.array([nominal.x, nominal.y]) + adjust - dcm
        ahead = float(rel @ forward)
        # Under a push the CoP must hold ξ against it for the whole step: land with ξ near
        # the sole's middle (margin both ways), not at the edge of the CoP's reach.
        share = self.params.pushed_reach_share if self.observer.force_n.any() else 1.0
        back, fwd = share * steps.reach_back_m, share * steps.reach_forward_m
        if ahead > back:
            adjust -= (ahead - back) * forward
        elif ahead < -fwd:
            adjust += (-fwd - ahead) * forward
        outward = float(rel @ left) * (1.0 if side == "left" else -1.0)  # foot beyond ξ, outward
        if outward < self.params.lateral_xi_inset_m:
            adjust += (self.params.lateral_xi_inset_m - outward) * (left if side == "left" else -left)
        elif outward > self.params.lateral_xi_max_out_m:  # ξ runs toward the other foot: land near it
            adjust -= (outward - self.params.lateral_xi_max_out_m) * (left if side == "left" else -left)
        if from_stance or (self.params.capture_from_stance_foot
                           and vector_norm(adjust) > self.params.max_step_adjust_m):  # within the legs' reach
            reach_bounded = True
            stance = planner.latched["right" if side == "left" else "left"]
            rel = np.array([nominal.x - stance.x, nominal.y - stance.y]) + adjust
            along, lateral = float(rel @ forward), float(rel @ left)
            sign = 1.0 if side == "left" else -1.0
            along_c = min(max(along, -self.params.max_step_length_m), self.params.max_step_length_m)
            lateral_c = sign * min(sign * lateral, self.params.max_step_width_m)
            adjust += (along_c - along) * forward + (lateral_c - lateral) * left
    norm = vector_norm(adjust)
    if norm > self.params.max_step_adjust_m and not reach_bounded:  # within the legs' reach
        adjust *= self.params.max_step_adjust_m / norm
    if bool((adjust == fb.step_adjust_m).all()):  # np.array_equal of two (2,) arrays
        return fb
    return dataclasses.replace(fb, step_adjust_m=adjust)


def test_reachable_steps_on_floats_equals_the_numpy_version() -> None:
    """Random states around a G1 walk: plan tracking, pushes (reach share, capture from the stance foot)."""
    import dataclasses

    from engine.control.walking_controller import WalkingController
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import Simulation

    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    c = WalkingController(robot, style)
    sim = Simulation(robot, c)
    c.set_command(np.array([0.4, 0.05, 0.2]))
    rng = np.random.default_rng(7)
    checked = changed = beyond = 0
    for k in range(500):
        sim.step()
        if k < 150 or k % 4:
            continue
        fb = c.feedback.last
        for trial in range(6):
            com, vel = c._com_now
            c._com_now = (com + np.r_[rng.normal(0.0, 0.03, 2), 0.0], vel + np.r_[rng.normal(0.0, 0.2, 2), 0.0])
            pushed = trial % 3 == 2
            c.observer.force_n = rng.normal(0.0, 40.0, c.observer.force_n.shape) if pushed else \
                np.zeros(c.observer.force_n.shape)
            c._mpc_shift = rng.normal(0.0, 0.01, 2) if trial % 2 else np.zeros(2)
            # trials 3-5: adjustments beyond max_step_adjust_m (a nominal foothold run away from the robot)
            f = dataclasses.replace(fb, step_adjust_m=rng.normal(0.0, 0.05 if trial < 3 else 0.3, 2) * (trial != 0))
            c.params = dataclasses.replace(c.params, capture_from_stance_foot=trial % 3 != 1)
            saved = c.step_adjustment.pushed_at_s
            pos_now, vel_now, _ = c.plan.com_at(c.planner.t_s)
            got = c.step_adjustment.reachable_steps(f, c.params, c.plan, (pos_now, vel_now, *c._com_state()), c._com_z,
                                                    c._mpc_shift, c.observer.force_n)
            got_pushed_at = c.step_adjustment.pushed_at_s
            c.step_adjustment.pushed_at_s = saved
            want = reachable_steps_reference(c, f)
            # differences of world positions: rounding at the size of where the robot is
            assert_equal_to_rounding(got.step_adjust_m, want.step_adjust_m, scale=4 * (1.0 + float(np.abs(com).max())))
            assert (got is f) == (want is f)
            assert got_pushed_at == c.step_adjustment.pushed_at_s
            c._com_now = (com, vel)
            checked += 1
            changed += got is not f
            beyond += bool(np.hypot(*got.step_adjust_m) > c.params.max_step_adjust_m + 1e-9) and not pushed
        c.observer.force_n = np.zeros(c.observer.force_n.shape)
        c._mpc_shift = np.zeros(2)
    assert checked > 300 and changed > 100 and beyond > 3, (checked, changed, beyond)  # the bounds did act


def hurry_beyond_reference(self, com, com_vel, z, outer):  # noqa: ANN001, ANN201
    """The distance of ξ beyond the outer sole edge in StepAdjustment.hurry_when_thrown_out before the speed-up."""
    from engine.constants import GRAVITY_MPS2
    planner = self.planner
    omega = math.sqrt(GRAVITY_MPS2 / max(z, 0.2))
    xi = com + com_vel / omega - self._mpc_shift
    c, s_ = math.cos(planner.path.yaw), math.sin(planner.path.yaw)
    outward = np.array([-s_, c]) * (1.0 if outer == "left" else -1.0)
    foot = planner.latched[outer]
    return float((xi - np.array([foot.x, foot.y])) @ outward) - self.step_adjustment.half_sole_width_m


def test_hurry_when_thrown_out_on_floats_equals_the_numpy_version() -> None:
    """The hurry decision flips where the numpy version's distance crosses the margin (to rounding)."""
    import dataclasses

    from engine.control.walking_controller import WalkingController
    from engine.gait.footsteps import Foothold
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot

    robot = load_robot("g1")
    c = WalkingController(robot, load_style(styles_dir("g1") / "neutral.json"))
    c.observer.force_n = np.zeros(c.observer.force_n.shape)
    rng = np.random.default_rng(3)
    fb = c.feedback.last
    hurried = 0
    for k in range(3000):
        c.planner.path.yaw = float(rng.uniform(-4.0, 4.0))
        outer = "left" if k % 2 else "right"
        c.planner.latched[outer] = Foothold(*rng.normal(0.0, 0.2, 3).tolist())
        c._mpc_shift = rng.normal(0.0, 0.01, 2) if k % 3 else np.zeros(2)
        com, com_vel, z = rng.normal(0.0, 0.2, 2), rng.normal(0.0, 0.5, 2), float(rng.uniform(0.5, 0.9))
        beyond = hurry_beyond_reference(c, com, com_vel, z, outer)
        margin = c.params.lateral_capture_margin_m
        if k % 5 < 2:  # the margin just above or just below the distance: the decision flips right there
            band = ROUNDING_ULP * np.finfo(float).eps * 4.0  # rounding of the distance (its terms are < 4 m here)
            at = beyond + band if k % 5 == 0 else beyond - band
            c.params = dataclasses.replace(c.params, lateral_capture_margin_m=at)
        got = c.step_adjustment.hurry_when_thrown_out(fb, c.params, com, com_vel, z, outer, bool(k % 4), c._mpc_shift,
                                                      c.observer.force_n)
        want_hurry = beyond > c.params.lateral_capture_margin_m
        assert (got is fb) == (not want_hurry)
        hurried += want_hurry
        c.params = dataclasses.replace(c.params, lateral_capture_margin_m=margin)
    assert 300 < hurried < 2700


def feet_feedforward_reference(ref, prev, limit: float, dt_s: float) -> tuple[np.ndarray, np.ndarray]:  # noqa: ANN001
    """WalkingController._feet_feedforward on the (2, 3) arrays, before it ran on floats."""
    with np.errstate(invalid="ignore", over="ignore"):  # (inf − inf is NaN, as on floats)
        acc = np.minimum(np.maximum((ref.foot_lin_vel - prev.foot_lin_vel) / dt_s, -limit), limit)
        ang = (ref.foot_ang_vel - prev.foot_ang_vel) / dt_s
    for i, in_contact in enumerate(ref.contact.tolist()):
        if in_contact:
            acc[i] = 0.0
            ang[i] = 0.0
    return acc, ang


def test_feet_feedforward_on_floats_equals_the_array_version() -> None:
    """Every planner tick of G1 and TALOS sweeps (swings, touchdowns, the clip at a low limit too) and reference rates
    with NaN, ±inf and −0.0 put in: the same arrays bit for bit (NaN where the arrays have NaN)."""
    import dataclasses
    from types import SimpleNamespace

    from engine.control.walking_controller import PLAN_DT_S
    from tests.neutral_sweeps import neutral_sweep_ticks

    rng = np.random.default_rng(5)
    compared = clipped = 0
    prev = None
    for k, controller, sim in neutral_sweep_ticks(1200):
        if k == 0:
            prev = None
        ref = controller.ref
        if prev is None or ref is prev:
            prev = ref
            continue
        for limit in (controller.params.swing_feedforward_limit_mps2, 0.05):
            want = feet_feedforward_reference(ref, prev, limit, PLAN_DT_S)
            saved = controller.params
            controller.params, controller.ref = dataclasses.replace(saved, swing_feedforward_limit_mps2=limit), prev
            controller._feet_feedforward(ref)
            controller.params, controller.ref = saved, ref
            np.testing.assert_array_equal(controller._foot_acc, want[0])
            np.testing.assert_array_equal(controller._foot_ang_acc, want[1])
            assert np.array_equal(np.signbit(controller._foot_acc), np.signbit(want[0]))
            clipped += bool((np.abs(want[0]) == limit).any())
            compared += 1
        prev = ref
    odd = [math.nan, math.inf, -math.inf, -0.0, 0.0, 1e300]
    for _ in range(300):
        lin, lin_prev, ang, ang_prev = (rng.normal(0.0, 1.0, (2, 3)) for _ in range(4))
        for a in (lin, lin_prev, ang, ang_prev):
            a[rng.random((2, 3)) < 0.2] = rng.choice(odd)
        ref = SimpleNamespace(foot_lin_vel=lin, foot_ang_vel=ang, contact=rng.random(2) < 0.5)
        prev = SimpleNamespace(foot_lin_vel=lin_prev, foot_ang_vel=ang_prev)
        controller.ref = prev
        controller._feet_feedforward(ref)  # type: ignore[arg-type]
        want = feet_feedforward_reference(ref, prev, controller.params.swing_feedforward_limit_mps2, PLAN_DT_S)
        np.testing.assert_array_equal(controller._foot_acc, want[0])
        np.testing.assert_array_equal(controller._foot_ang_acc, want[1])
        assert np.array_equal(np.signbit(controller._foot_acc), np.signbit(want[0]))
    assert compared > 1000 and clipped > 100, (compared, clipped)
