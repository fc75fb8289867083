"""The compiled whole-body QP kernels (engine/control/wbc/kernels.py) compute the numbers of the numpy
code they replace (``TaskSpaceInverseDynamics(kernels="numpy")``), to rounding."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from engine.control.controller import RobotState
from engine.control.wbc import TaskSpaceInverseDynamics, WbcGains
from engine.control.wbc.kernels import log3
from engine.control.wbc.qp import DaqpQpSolver
from engine.robot.model import load_robot

PATTERNS = (
    [[1, 1, 1, 1], [1, 1, 1, 1]],
    [[1, 1, 1, 1], [0, 0, 0, 0]],
    [[0, 0, 1, 1], [1, 1, 0, 0]],
)


def _state(robot, seed: int) -> RobotState:
    rng = np.random.default_rng(seed)
    q = robot.q_standing.copy()
    q[7:] += rng.normal(0.0, 0.05, robot.n_joints)
    q[3:7] = pin.Quaternion(pin.exp3(rng.normal(0.0, 0.1, 3))).coeffs()
    return RobotState(0.0, q, rng.normal(0.0, 0.3, robot.pin_model.nv))


@pytest.mark.parametrize("robot_name", ["g1", "talos"])
def test_compiled_assembly_equals_numpy(robot_name: str) -> None:
    robot = load_robot(robot_name)
    # a swing-foot rotation weight unlike the position weight: the compiled rows must weigh them apart
    gains = replace(WbcGains.for_robot(robot), com_z_weight=20.0 if robot_name == "talos" else 0.0,
                    swing_foot_rotation_weight=7.0)
    ours = TaskSpaceInverseDynamics(robot, gains)
    reference = TaskSpaceInverseDynamics(robot, gains, kernels="numpy")
    assert ours.kernels == "numba"
    for seed in range(6):
        state = _state(robot, seed)
        rng = np.random.default_rng(seed + 50)
        ref = reference.hold_reference(robot.q_standing)
        ref = replace(ref, contact=np.array(PATTERNS[seed % len(PATTERNS)], dtype=bool),
                      com_xy_acc_mps2=rng.normal(0.0, 1.0, 2), foot_pos_m=ref.foot_pos_m + rng.normal(0.0, 0.02, (2, 3)),
                      external_wrench=rng.normal(0.0, 5.0, 6) if seed % 2 else None,
                      foot_rotation=np.array([pin.exp3(rng.normal(0.0, 0.1, 3)) for _ in range(2)]),
                      foot_lin_vel_mps=rng.normal(0.0, 0.3, (2, 3)), foot_ang_vel_radps=rng.normal(0.0, 0.3, (2, 3)),
                      foot_lin_acc_mps2=rng.normal(0.0, 1.0, (2, 3)) if seed % 3 else None,
                      foot_ang_acc_radps2=rng.normal(0.0, 1.0, (2, 3)) if seed % 3 else None,
                      pelvis_rotation=pin.exp3(rng.normal(0.0, 0.1, 3)), pelvis_ang_vel_radps=rng.normal(0.0, 0.2, 3),
                      upper_body_qd_radps=rng.normal(0.0, 0.2, ref.upper_body_q_rad.size),
                      com_z_m=0.7 if seed % 2 else None)
        for wbc in (ours, reference):
            wbc.reset(state)
        cmd_a, cmd_b = ours.compute(state, ref), reference.compute(state, ref)
        assert ours.diagnostics.ok and reference.diagnostics.ok
        qa, qb = ours.qp, reference.qp
        assert qa is not None and qb is not None
        for field in ("p_qq", "c_q", "r_rr", "a_h", "g_rho", "b", "qdd_joint_lo", "qdd_joint_up", "rho_up",
                      "tau_qdd", "tau_rho", "tau_bias", "tau_lo", "tau_up"):
            a, b = getattr(qa, field), getattr(qb, field)
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-9 * max(1.0, float(np.abs(b).max())), err_msg=field)
        np.testing.assert_allclose(ours._jac, reference._jac, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(ours._rhs, reference._rhs, rtol=1e-12, atol=1e-9)
        np.testing.assert_array_equal(ours._w, reference._w)
        np.testing.assert_allclose(ours._basis, reference._basis, atol=1e-14)
        np.testing.assert_allclose(ours._corners_m, reference._corners_m, atol=1e-14)
        np.testing.assert_allclose(ours._tau_map, reference._tau_map, rtol=1e-12, atol=1e-10)
        np.testing.assert_allclose(cmd_a.tau_ff, cmd_b.tau_ff, atol=1e-7)
        np.testing.assert_allclose(cmd_a.q_des, cmd_b.q_des, atol=1e-12)


@pytest.mark.parametrize("pattern", range(len(PATTERNS)))
def test_compiled_daqp_form_equals_numpy(pattern: int) -> None:
    """Every corner in contact: the same form bit for bit; fewer: the form over the active corners'
    ρ only, with the same solution as the full form (inactive corners at 0)."""
    robot = load_robot("g1")
    wbc = TaskSpaceInverseDynamics(robot, kernels="numpy")
    state = _state(robot, 3)
    wbc.reset(state)
    ref = replace(wbc.hold_reference(robot.q_standing), contact=np.array(PATTERNS[pattern], dtype=bool))
    wbc.compute(state, ref)
    qp = wbc.qp
    assert qp is not None
    compiled = DaqpQpSolver(wbc.nv, wbc.n_rho, wbc.n_joints, compiled=True)
    numpy_form = DaqpQpSolver(wbc.nv, wbc.n_rho, wbc.n_joints)
    sol_a, sol_b = compiled.solve(qp), numpy_form.solve(qp)
    assert sol_a is not None and sol_b is not None
    active = np.flatnonzero(qp.rho_up > 0.0)
    ws = compiled._workspaces[active.size]
    keep = np.concatenate([np.arange(wbc.nv), wbc.nv + active])
    rows = np.concatenate([keep, wbc.nv + wbc.n_rho + np.arange(6 + wbc.n_joints)])
    np.testing.assert_array_equal(ws.h, numpy_form._h[np.ix_(keep, keep)])
    np.testing.assert_array_equal(ws.f, numpy_form._f[keep])
    np.testing.assert_array_equal(ws.a, numpy_form._a[:, keep])
    np.testing.assert_array_equal(ws.lo, numpy_form._lo[rows])
    np.testing.assert_array_equal(ws.up, numpy_form._up[rows])
    np.testing.assert_allclose(sol_a[0], sol_b[0], atol=1e-8)
    np.testing.assert_allclose(sol_a[1], sol_b[1], atol=1e-8)
    assert np.all(sol_a[1][qp.rho_up == 0.0] == 0.0)


def test_log3_equals_pinocchio() -> None:
    rng = np.random.default_rng(0)
    vectors = [rng.normal(0.0, 1.0, 3) * scale for scale in (1e-9, 1e-6, 1e-3, 0.1, 1.0) for _ in range(20)]
    vectors += [axis / np.linalg.norm(axis) * angle for axis in rng.normal(0.0, 1.0, (20, 3))
                for angle in (np.pi - 1e-3, np.pi - 2e-2, np.pi)]
    for vec in vectors:
        rot = pin.exp3(vec)
        np.testing.assert_allclose(log3(rot), pin.log3(rot), atol=1e-12)


@pytest.mark.parametrize("positive_definite", [True, False])
def test_torques_kernel_equals_numpy(positive_definite: bool) -> None:
    from engine.control.wbc.kernels import torques

    rng = np.random.default_rng(1)
    nv, n_rho = 12, 8
    half = rng.normal(size=(nv, nv))
    mass = half @ half.T + nv * np.eye(nv)
    if not positive_definite:  # a base block that is not positive definite: the LU fallback
        mass[:6, :6] = np.diag([1.0, -1.0, 2.0, 3.0, 1.0, 1.0])
    nle, tau_map, rho = rng.normal(size=nv), rng.normal(size=(nv, n_rho)), rng.uniform(0, 1, n_rho)
    qdd, damping = rng.normal(size=nv), rng.normal(size=nv - 6)
    gen = tau_map @ rho
    expected_qdd = qdd.copy()
    expected_qdd[:6] = np.linalg.solve(mass[:6, :6], -(mass[:6, 6:] @ qdd[6:]) - nle[:6] - gen[:6])
    expected_tau = mass[6:] @ expected_qdd + nle[6:] + gen[6:] + damping
    tau, rhs, gen_out = torques(mass, nle, tau_map, rho, qdd, damping)
    np.testing.assert_allclose(gen_out, gen, rtol=1e-12, atol=1e-12)
    if not positive_definite:  # the caller's LU fallback
        assert tau.size == 0
        qdd[:6] = np.linalg.solve(mass[:6, :6], rhs)
        tau = mass[6:] @ qdd + nle[6:] + gen_out[6:] + damping
    np.testing.assert_allclose(qdd, expected_qdd, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(tau, expected_tau, rtol=1e-12, atol=1e-11)


def test_warm_up_compiles_every_kernel() -> None:
    """``make setup``'s warm-up runs (a whole-body tick that solves, a hull)."""
    from engine.compiled_kernels import warm_up
    from engine.control import reference_kernels
    from engine.control.wbc import kernels
    from engine.geometry import polygon

    warm_up()
    # (task_rows, assemble_qp, qp_bounds, torques and horizontal_force are compiled inside build_qp and finish_tick)
    for kernel in (kernels.build_qp, kernels.finish_tick, kernels.fill_daqp, polygon._hull_compiled,
                   reference_kernels.interpolate_reference):
        assert kernel.signatures, kernel
