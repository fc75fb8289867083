"""Issue 12 (speed12c): the planner tick's CoM MPC glue gives the numbers it gave before, bit for bit.

- the preview's supports packed by the compiled :func:`engine.gait.planner_kernels.pack_supports` are the table and
  points ``ComMpc._solve_window`` built from the contact phases (kept below as the reference), and a solve given them
  (``ComMpc.solve``'s ``packed``) is the solve that packs them itself;
- the plan's CoP and final capture point as floats are the numbers of the arrays they replaced;
- the last support's vertex mean on floats is ``polygon.mean(axis=0)``, the capture-point miss the norm of the
  array difference;
- the touchdown tracker's contact tables on Python bools are ``corner_contact & contact[:, None]``.
"""

from __future__ import annotations

import math

import numpy as np

from engine.control.mpc import ComMpc
from engine.control.walking_controller import _distance, _vertex_mean
from engine.geometry.vector import vector_norm
from engine.gait.planner_kernels import pack_supports
from tests.neutral_sweeps import neutral_sweep_ticks


def packed_reference(supports: list) -> tuple[np.ndarray, np.ndarray]:
    """ComMpc._solve_window's packing of the supports before speed12c: from the phases, per solve."""
    polygons = [s.polygon for s in supports]
    table = np.array([(s.t_start_s, s.t_end_s, len(p)) for s, p in zip(supports, polygons)], dtype=float)
    return table, np.concatenate(polygons, casting="no")


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _same_solution(a: object, b: object) -> None:
    for name in ("waypoint_times_s", "waypoints_xy_m", "waypoint_com_xy_m", "waypoint_com_vel_xy_mps",
                 "region_centroids_xy_m", "qp_final_state"):
        assert _same(getattr(a, name), getattr(b, name)), name
    for name in ("com_height_m", "status", "message", "osqp_iterations"):
        assert getattr(a, name) == getattr(b, name), name


def test_packed_preview_and_the_solve_given_it_equal_the_packing_from_the_phases() -> None:
    """Every planner tick of 2.5 s G1 and TALOS sweeps: the planner's packing equals the phases' (bit for bit), and
    a twin MPC fed the same calls without the packing returns the same plans (two twins in lockstep, as the
    controller's MPC: the warm starts follow the same solves)."""
    twins: dict[int, tuple[ComMpc, ComMpc]] = {}
    compared = 0
    for k, controller, _ in neutral_sweep_ticks(1250):
        if controller.tick % 4 != 1:  # right after a planner tick
            continue
        ref, planner = controller.ref, controller.planner
        packed = planner.packed_supports(ref.preview)
        assert packed is not None and planner.packed_supports(list(ref.preview)) is None
        table, points = packed
        want_table, want_points = packed_reference(ref.preview)
        assert _same(table, want_table) and _same(points, want_points), k
        given, rebuilt = twins.setdefault(id(controller), (ComMpc(preview_s=controller.mpc.preview_s),
                                                            ComMpc(preview_s=controller.mpc.preview_s)))
        plan = controller.plan
        t = float(ref.t_s)
        com, vel, _ = plan.com_at(t)
        cop = plan.cop_at(t)
        z = plan.com_height_m
        a = given.solve(t, com, vel, cop, z, ref.preview, packed)
        b = rebuilt.solve(t, com, vel, cop, z, ref.preview)
        _same_solution(a, b)
        compared += 1
    assert compared > 500


def test_pack_supports_on_odd_previews() -> None:
    """One interval, polygons of 3..8 vertices, negative and huge times: the phases' packing."""
    rng = np.random.default_rng(12)
    for trial in range(300):
        n = int(rng.integers(1, 17))
        counts = rng.integers(3, 9, n)
        times = np.sort(rng.uniform(-1.0, 3.0, (n, 2)), axis=1)
        rows = np.zeros((n, 5), dtype=np.int64)
        rows[:, 4] = counts
        polygons = rng.standard_normal((n, 8, 2)) * rng.choice([1e-3, 1.0, 1e3])
        t_s = float(rng.choice([0.0, 1e-9, 12.345, 1e6, -3.0]))
        table, points = pack_supports(t_s, times, rows, polygons)
        phases = [type("Phase", (), {"t_start_s": t_s + t0, "t_end_s": t_s + t1, "polygon": polygons[i, :m]})()
                  for i, ((t0, t1), m) in enumerate(zip(times.tolist(), counts.tolist()))]
        want_table, want_points = packed_reference(phases)
        assert _same(table, want_table) and _same(points, want_points), trial


def test_a_malformed_packing_is_rebuilt_from_the_supports() -> None:
    """A packing of the wrong form is not used: the solve packs the supports itself (the same plan)."""
    from engine.control.mpc import SupportInterval

    left = np.array([[-0.1, 0.06], [0.1, 0.06], [0.1, 0.14], [-0.1, 0.14]])
    both = np.array([[-0.1, -0.14], [0.1, -0.14], [0.1, 0.14], [-0.1, 0.14]])
    supports = [SupportInterval(0.0, 0.2, both), SupportInterval(0.2, 0.6, left), SupportInterval(0.6, 2.5, both)]
    table, points = packed_reference(supports)
    state = (0.0, np.zeros(2), np.array([0.0, 0.1]), np.zeros(2), 0.6, supports)
    want = ComMpc().solve(*state)
    for bad in ((table,), (table[:, :2], points), (table, points.astype(np.float32)), (table, points.T.copy().T[:, :1]),
                (table.tolist(), points), "packed"):
        _same_solution(ComMpc().solve(*state, bad), want)
    _same_solution(ComMpc().solve(*state, (table, points)), want)


def test_cop_and_final_capture_point_as_floats_equal_the_arrays() -> None:
    """On the closed-loop plans: at waypoint times, between them, before and after the window, and the array path
    (NaN, non-float times)."""
    checked = 0
    for k, controller, _ in neutral_sweep_ticks(600):
        if k % 8:
            continue
        plan = controller.plan
        fx, fy = plan.final_capture_point_floats()
        want = plan.final_capture_point_xy_m
        assert np.float64(fx).tobytes() == want[0].tobytes() and np.float64(fy).tobytes() == want[1].tobytes()
        times = plan.waypoint_times_s.tolist()
        for t in [*times, *(0.5 * (a + b) for a, b in zip(times, times[1:])), times[0] - 0.01, times[-1] + 0.3,
                  float(controller.ref.t_s)]:
            got, want = plan.cop_at_floats(t), plan.cop_at(t)
            assert np.array(got).tobytes() == want.tobytes(), (k, t)
            checked += 1
        for t in (math.nan, np.float32(times[1]), int(times[0])):
            got = plan.cop_at_floats(t)
            want = plan.cop_at(t)
            assert np.array_equal(np.array(got), want, equal_nan=True)
    assert checked > 1000


def test_vertex_mean_and_distance_equal_the_array_expressions() -> None:
    rng = np.random.default_rng(7)
    for trial in range(20000):
        m = int(rng.integers(1, 17))
        # views into a padded table, as the preview's polygons are
        table = rng.standard_normal((3, 17, 2)) * rng.choice([1e-3, 0.1, 1.0, 1e3]) + rng.standard_normal(2)
        polygon = table[int(rng.integers(3))][:m]
        gx, gy = _vertex_mean(polygon)
        want = polygon.sum(axis=0) / len(polygon)
        assert np.float64(gx).tobytes() == want[0].tobytes() and np.float64(gy).tobytes() == want[1].tobytes()
        point = tuple(rng.standard_normal(2) * rng.choice([1e-4, 0.1, 10.0]))
        assert _distance(point, gx, gy) == vector_norm(np.array(point) - want)
    assert math.isnan(_vertex_mean(np.zeros((0, 2)))[0])


def test_contact_tables_equal_the_array_expression() -> None:
    """TouchdownTracker.reference_tables on every planner tick of the sweeps: the corners in contact (the array's
    dtype, shape and bytes) and the landing candidates of the former array expressions."""
    compared = 0
    for _, controller, _ in neutral_sweep_ticks(1000):
        ref, touchdown = controller.ref, controller.touchdown
        if touchdown.contact_ref is not ref:
            continue
        want = ref.corner_contact & ref.contact[:, None]
        flags, up = want.tolist(), ref.foot_lin_vel[:, 2].tolist()
        assert _same(touchdown.ref_contact, want)
        assert touchdown.landing_candidates == [i for i in range(2) if not any(flags[i]) and up[i] <= 0.0]
        compared += 1
    assert compared > 400
