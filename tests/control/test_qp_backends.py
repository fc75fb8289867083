"""The maintained QP backends solve the controllers' QPs to the hand-written solvers' optimum."""

from __future__ import annotations

import numpy as np
import pytest

from engine.bench.mpc_problems import closed_loop_like_problems
from engine.control.mpc import ComMpc
from engine.control.qp_backends import QpProblem, solve


def test_backends_agree_on_a_small_qp() -> None:
    h = np.array([[2.0, 0.5], [0.5, 1.0]])
    problem = QpProblem(h, np.array([-1.0, -1.0]), lb=np.array([0.0, 0.0]), ub=np.array([0.4, 10.0]),
                        a_eq=np.array([[1.0, 1.0]]), b_eq=np.array([1.0]),
                        c=np.array([[1.0, -1.0]]), c_lo=np.array([-np.inf]), c_up=np.array([0.5]))
    xs = {b: solve(problem, b) for b in ("daqp", "proxsuite", "quadprog", "osqp")}
    assert all(r.ok for r in xs.values()), {b: r.status for b, r in xs.items()}
    for r in xs.values():
        np.testing.assert_allclose(r.x, xs["daqp"].x, atol=1e-5)
        assert problem.violation(r.x) < 1e-5


def test_unknown_backend_is_refused() -> None:
    with pytest.raises(ValueError, match="qp backend"):
        solve(QpProblem(np.eye(1), np.zeros(1)), "nosuch")


@pytest.mark.parametrize("backend", ["daqp", "quadprog"])
def test_mpc_backends_match_the_active_set(backend: str) -> None:
    calls = closed_loop_like_problems(30, seed=4)
    ours, theirs = ComMpc(), ComMpc(solver=backend)
    for args, _ in calls:
        a, b = ours.solve(*args), theirs.solve(*args)
        assert a.ok and b.ok
        np.testing.assert_allclose(b.waypoints_xy_m, a.waypoints_xy_m, atol=1e-6)


def test_wbc_daqp_backend_matches_the_dense_solver() -> None:
    from tests.test_stack_golden import GOLDEN  # the recorded whole-body QP inputs
    from engine.control.controller import RobotState
    from engine.control.wbc import TaskSpaceInverseDynamics
    from engine.robot.model import load_robot

    robot = load_robot("g1")
    dense, daqp = TaskSpaceInverseDynamics(robot), TaskSpaceInverseDynamics(robot, qp_backend="daqp")
    with np.load(GOLDEN, allow_pickle=False) as z:
        q, v = z["id_q"][0], z["id_v"][0]
    state = RobotState(0.0, q, v)
    ref = dense.hold_reference(q)
    for ctrl in (dense, daqp):
        ctrl.reset(state)
        ctrl.compute(state, ref)
        assert ctrl.diagnostics.ok, ctrl.diagnostics.message
    np.testing.assert_allclose(daqp.diagnostics.qdd, dense.diagnostics.qdd, atol=1e-6)
    np.testing.assert_allclose(daqp.diagnostics.tau_nm, dense.diagnostics.tau_nm, atol=1e-5)
