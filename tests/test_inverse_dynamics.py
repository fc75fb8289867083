"""Task-space inverse dynamics (paper Appendix "ID"): QP physics checked independently with
pinocchio, closed-loop balance of G1 in MuJoCo, garbage-in safety, and placo's peer."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from engine.control.controller import RobotState
from engine.constants import GRAVITY_MPS2, SIDES
from engine.control.wbc import (
    TaskSpaceInverseDynamics,
    TrackingController,
    WbcGains,
    WbcReference,
    friction_basis,
)
from engine.robot.model import load_robot
from engine.sim import Simulation

pytestmark = pytest.mark.timeout(120)

# Contact patterns (left corners, right corners): FL, FR, BR, BL per foot.
PATTERNS = {
    "double": [[1, 1, 1, 1], [1, 1, 1, 1]],
    "left_only": [[1, 1, 1, 1], [0, 0, 0, 0]],
    "right_toe": [[1, 1, 1, 1], [1, 1, 0, 0]],
    "heels": [[0, 0, 1, 1], [0, 0, 1, 1]],
}


@pytest.fixture(scope="module")
def g1():
    return load_robot("g1")


def random_state(robot, seed: int) -> RobotState:
    """A standing-ish state: joints and base tilt perturbed, random velocities."""
    rng = np.random.default_rng(seed)
    q = robot.q_standing.copy()
    q[7:] += rng.normal(0.0, 0.05, robot.n_joints)
    rot = pin.exp3(rng.normal(0.0, 0.05, 3))
    q[3:7] = pin.Quaternion(rot).coeffs()
    v = rng.normal(0.0, 0.3, robot.pin_model.nv)
    return RobotState(0.0, q, v)


def solve_once(robot, seed: int, pattern: str, backend: str = "dense"):
    wbc = TaskSpaceInverseDynamics(robot, qp_backend=backend)
    state = random_state(robot, seed)
    ref = wbc.hold_reference(robot.q_standing)
    rng = np.random.default_rng(seed + 100)
    ref = replace(ref, contact=np.array(PATTERNS[pattern], dtype=bool),
                  com_xy_acc_mps2=rng.normal(0.0, 1.0, 2), com_xy_m=ref.com_xy_m + rng.normal(0.0, 0.02, 2))
    cmd = wbc.compute(state, ref)
    return wbc, state, ref, cmd


def corner_jacobians(robot, q):
    model = robot.pin_model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    jacs, points = [], []
    for side in SIDES:
        for c in range(4):
            fid = model.getFrameId(f"{side}_foot_c{c}")
            jacs.append(pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3])
            points.append(data.oMf[fid].translation.copy())
    return np.array(jacs).reshape(2, 4, 3, -1), np.array(points).reshape(2, 4, 3)


CASES = [(seed, pattern) for seed in range(3) for pattern in PATTERNS]


@pytest.mark.parametrize("backend", ["dense", "osqp"])
@pytest.mark.parametrize(("seed", "pattern"), CASES)
def test_solution_satisfies_rigid_body_dynamics(g1, seed, pattern, backend):
    """M q̈ + h = Sᵀτ + Σ J_cᵀ f_c, with J_c from pinocchio's corner frames (independent of the QP)."""
    wbc, state, _, cmd = solve_once(g1, seed, pattern, backend)
    diag = wbc.diagnostics
    assert diag.ok, diag.status
    model, data = g1.pin_model, g1.pin_model.createData()
    mass = pin.crba(model, data, state.q)
    bias = pin.nonLinearEffects(model, data, state.q, state.v)
    jacs, _ = corner_jacobians(g1, state.q)
    generalized_contact = np.einsum("fcki,fck->i", jacs, diag.contact_forces_n)
    lhs = mass @ diag.qdd + bias
    rhs = np.concatenate([np.zeros(6), diag.tau_nm]) + generalized_contact
    assert np.max(np.abs(lhs - rhs)) < 1e-6
    assert np.array_equal(cmd.tau_ff, diag.tau_nm)


@pytest.mark.parametrize(("seed", "pattern"), CASES)
def test_contact_forces_in_friction_cone_and_zero_when_inactive(g1, seed, pattern):
    wbc, state, ref, _ = solve_once(g1, seed, pattern)
    forces = wbc.diagnostics.contact_forces_n
    active = np.asarray(ref.contact, dtype=bool)
    mu = wbc.gains.friction_mu
    assert np.all(forces[~active] == 0.0)
    fz = forces[..., 2]
    assert np.all(fz >= -1e-9)
    assert np.all(np.linalg.norm(forces[..., :2], axis=-1) <= mu * fz + 1e-9)
    # The robot's weight is carried (it is not free-falling) and the CoP lies in the active corners' hull.
    assert fz.sum() > 0.3 * g1.mass_kg * GRAVITY_MPS2
    corners = corner_jacobians(g1, state.q)[1][active][:, :2]
    cop = wbc.diagnostics.cop_m
    assert corners[:, 0].min() - 1e-9 <= cop[0] <= corners[:, 0].max() + 1e-9
    assert corners[:, 1].min() - 1e-9 <= cop[1] <= corners[:, 1].max() + 1e-9


def test_friction_pyramid_edges_lie_in_the_cone(g1):
    wbc, state, _, _ = solve_once(g1, 0, "double")
    mu = wbc.gains.friction_mu
    data = wbc.model.createData()  # the feet at the solved state (the compiled tick does not update wbc.data.oMf)
    pin.framesForwardKinematics(wbc.model, data, state.q)
    for i, fid in enumerate(wbc.foot_frame_ids):
        heading = data.oMf[fid].rotation[:, 0]
        expected = friction_basis(np.array([0.0, 0.0, 1.0]), heading, mu)
        assert np.allclose(wbc._basis[i], expected, atol=1e-12)
        edges = expected.T
        assert np.allclose(np.linalg.norm(edges, axis=1), 1.0)
        assert np.allclose(np.linalg.norm(edges[:, :2], axis=1), mu * edges[:, 2])  # on the cone's surface


@pytest.mark.parametrize(("seed", "pattern"), CASES)
def test_centroidal_momentum_equality(g1, seed, pattern):
    """A_h q̈ + Ȧ_h q̇ = Σ_c [f_c; (p_c − c) × f_c] + [m g; 0] (Eq. 21), recomputed with pinocchio."""
    wbc, state, _, _ = solve_once(g1, seed, pattern)
    diag = wbc.diagnostics
    model, data = g1.pin_model, g1.pin_model.createData()
    pin.computeCentroidalMapTimeVariation(model, data, state.q, state.v)
    com = pin.centerOfMass(model, data, state.q)
    hdot = data.Ag @ diag.qdd + data.dAg @ state.v
    _, points = corner_jacobians(g1, state.q)
    f = diag.contact_forces_n.reshape(-1, 3)
    wrench = np.concatenate([f.sum(0), np.cross(points.reshape(-1, 3) - com, f).sum(0)])
    wrench[2] -= g1.mass_kg * GRAVITY_MPS2
    assert np.max(np.abs(hdot - wrench)) < 1e-6


@pytest.mark.parametrize(("seed", "pattern"), CASES)
def test_dense_and_osqp_backends_reach_the_same_optimum(g1, seed, pattern):
    """The exact active-set solver and OSQP (fixed sparsity) on the same QP: equal optimal cost,
    the dense one never worse; both feasible (checked above)."""
    dense, *_ = solve_once(g1, seed, pattern, "dense")
    sparse, *_ = solve_once(g1, seed, pattern, "osqp")
    assert dense.diagnostics.backend == "dense" and sparse.diagnostics.backend == "osqp"
    qp = dense.qp
    cost_dense = qp.objective(dense.diagnostics.qdd, dense.diagnostics.rho)
    cost_osqp = qp.objective(sparse.diagnostics.qdd, sparse.diagnostics.rho)
    scale = abs(cost_dense) + 1.0
    assert cost_dense <= cost_osqp + 1e-6 * scale
    assert cost_osqp - cost_dense < 1e-3 * scale


@pytest.mark.parametrize("backend", ["dense", "osqp"])
def test_soft_joint_limits_bound_the_acceleration(g1, backend):
    """A joint at its upper limit moving outward must decelerate (Eq. 23): the bound is active."""
    wbc = TaskSpaceInverseDynamics(g1, qp_backend=backend)
    state = random_state(g1, 7)
    j = g1.joint_names.index("waist_roll_joint")
    state.q[7 + j] = g1.joint_upper[j]
    state.v[6 + j] = 1.0
    ref = wbc.hold_reference(g1.q_standing)
    ref.upper_body_q_rad[wbc.upper_body_joints.index("waist_roll_joint")] = g1.joint_upper[j] + 0.3
    wbc.compute(state, ref)
    assert wbc.diagnostics.ok
    g = wbc.gains
    bound = g.joint_limit_kl * (g1.joint_upper[j] - state.q[7 + j]) - g.joint_limit_bl * state.v[6 + j]
    tolerance = 1e-6 if backend == "dense" else 1e-2  # exact active set vs OSQP's ADMM tolerance
    assert wbc.diagnostics.qdd[6 + j] <= bound + tolerance
    assert wbc.diagnostics.qdd[6 + j] >= bound - 1.0  # pressed against it, not far inside
    if backend == "dense":
        assert wbc.dense_solver.fixed_up[6 + j]


# ----------------------------------------------------------------------------- closed loop


def foot_sites(sim):
    return np.array([sim.data.site_xpos[sim.model.site(f"{s}_foot").id].copy() for s in SIDES])


def run(sim, seconds, reference, on_tick=None):
    """Step ``seconds``; returns per-tick CoM error (m, horizontal) against ``reference(state)``."""
    errors = []
    data = sim.robot.pin_model.createData()
    for _ in range(int(round(seconds / 0.002))):
        sim.step()
        if on_tick is not None:
            on_tick()
        state = sim.state()
        com = pin.centerOfMass(sim.robot.pin_model, data, state.q)
        errors.append(float(np.linalg.norm(com[:2] - reference(state).com_xy_m)))
        if sim.fallen:
            break
    return np.array(errors)


@pytest.mark.slow
def test_g1_stands_five_seconds_on_the_qp(g1):
    wbc = TaskSpaceInverseDynamics(g1)
    ref = wbc.hold_reference(g1.q_standing)
    sim = Simulation(g1, TrackingController(wbc, lambda _s: ref))
    feet0 = foot_sites(sim)
    statuses = set()
    errors = run(sim, 5.0, lambda _s: ref, lambda: statuses.add(wbc.diagnostics.status))
    assert not sim.fallen
    assert statuses == {"solved"}
    assert errors.max() < 3e-3  # CoM within 3 mm of its target throughout
    slip = np.linalg.norm((foot_sites(sim) - feet0)[:, :2], axis=1)
    assert slip.max() < 1e-3


def push_reference(sim, wbc, base: WbcReference):
    """Standing reference with an ideal external-wrench estimate (the applied push, about the CoM)."""

    def reference(state: RobotState) -> WbcReference:
        if not sim.pushes:
            return base
        force = sum(p.force_n for p in sim.pushes)
        com = wbc.data.com[0]
        arm = sim.data.xpos[sim.root_body_id] - com
        return replace(base, external_wrench=np.concatenate([force, np.cross(arm, force)]))

    return reference


@pytest.mark.slow
@pytest.mark.parametrize(("direction", "n_per_kg"), [((0.0, 1.0, 0.0), 1.5), ((1.0, 0.0, 0.0), 1.0),
                                                      ((-1.0, 0.0, 0.0), 1.0)])
def test_g1_survives_a_one_second_push_standing(g1, direction, n_per_kg):
    """Pelvis push for 1 s, feet in place. 1.5 N/kg from the side; from the front/back the 17 cm
    sole only allows ~1 N/kg without stepping (the CoP must move F·h/(m g) ≈ 12 cm at 1.5 N/kg)."""
    wbc = TaskSpaceInverseDynamics(g1)
    base = wbc.hold_reference(g1.q_standing)
    sim = Simulation(g1)
    reference = push_reference(sim, wbc, base)
    sim.set_controller(TrackingController(wbc, reference))
    run(sim, 0.5, reference)
    feet0 = foot_sites(sim)
    sim.push(np.asarray(direction) * n_per_kg * g1.mass_kg, 1.0)
    errors = run(sim, 2.5, reference)
    assert not sim.fallen
    assert errors[-250:].max() < 5e-3  # back on its CoM target after the push
    slip = np.linalg.norm((foot_sites(sim) - feet0)[:, :2], axis=1)
    assert slip.max() < 1e-2  # no step; MuJoCo's soft friction lets the soles creep a few mm


def min_jerk(s: float) -> tuple[float, float, float]:
    s = min(max(s, 0.0), 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s), 30 * s * s * (1 - s) ** 2, 60 * s * (1 - s) * (1 - 2 * s)


@pytest.mark.slow
def test_g1_balances_on_one_foot(g1):
    """Shift the CoM over the left sole (1.5 s), lift the right foot 5 cm, hold 2 s on one foot."""
    wbc = TaskSpaceInverseDynamics(g1)
    base = wbc.hold_reference(g1.q_standing)
    shift_s, lift_s, lift_m = 1.5, 0.4, 0.05
    start = base.com_xy_m.copy()
    delta = base.foot_pos_m[0, :2] - start

    def reference(state: RobotState) -> WbcReference:
        t = state.t_s
        p, dp, ddp = min_jerk(t / shift_s)
        ref = replace(base, com_xy_m=start + p * delta, com_xy_vel_mps=dp / shift_s * delta,
                      com_xy_acc_mps2=ddp / shift_s**2 * delta)
        if t < shift_s + 0.1:
            return ref
        h, dh, ddh = min_jerk((t - shift_s - 0.1) / lift_s)
        feet = base.foot_pos_m.copy()
        feet[1, 2] += lift_m * h
        vel = np.zeros((2, 3))
        vel[1, 2] = lift_m * dh / lift_s
        acc = np.zeros((2, 3))
        acc[1, 2] = lift_m * ddh / lift_s**2
        return replace(ref, foot_pos_m=feet, foot_lin_vel_mps=vel, foot_lin_acc_mps2=acc,
                       contact=np.array([[True] * 4, [False] * 4]))

    sim = Simulation(g1, TrackingController(wbc, reference))
    feet0 = foot_sites(sim)
    run(sim, shift_s + 0.1 + lift_s, reference)
    errors = run(sim, 2.0, reference)
    assert not sim.fallen
    assert errors.max() < 1e-2
    feet = foot_sites(sim)
    assert abs(feet[1, 2] - feet0[1, 2] - lift_m) < 1e-2  # the right foot is up
    assert np.linalg.norm((feet - feet0)[0, :2]) < 2e-3  # the stance foot stayed put
    assert np.all(wbc.diagnostics.contact_forces_n[1] == 0.0)


@pytest.mark.slow
def test_talos_stands_on_the_qp():
    """The second target (90 kg, joint damping and Coulomb friction in its MuJoCo model)."""
    talos = load_robot("talos")
    wbc = TaskSpaceInverseDynamics(talos)
    ref = wbc.hold_reference(talos.q_standing)
    sim = Simulation(talos, TrackingController(wbc, lambda _s: ref))
    feet0 = foot_sites(sim)
    errors = run(sim, 2.0, lambda _s: ref)
    assert not sim.fallen
    assert errors.max() < 1e-2  # the unmodelled 1 N·m joint friction leaves a few mm
    assert np.linalg.norm((foot_sites(sim) - feet0)[:, :2], axis=1).max() < 2e-3


# ----------------------------------------------------------------------------- garbage in


def test_garbage_in_gives_finite_fallback_and_recovers(g1):
    wbc = TaskSpaceInverseDynamics(g1)
    state = RobotState(0.0, g1.q_standing.copy(), np.zeros(g1.pin_model.nv))
    ref = wbc.hold_reference(g1.q_standing)
    good = wbc.compute(state, ref)
    assert wbc.diagnostics.status == "solved"
    nan_com = replace(ref, com_xy_m=np.array([np.nan, 0.0]))
    inf_foot = replace(ref, foot_pos_m=np.full((2, 3), np.inf))
    no_contact = replace(ref, contact=np.zeros((2, 4), dtype=bool))
    huge = replace(ref, com_xy_acc_mps2=np.array([1e300, -1e300]))
    bad_state = RobotState(0.0, np.full_like(state.q, np.nan), state.v)
    cases = [(state, nan_com, "fallback_invalid_reference"), (state, inf_foot, "fallback_invalid_reference"),
             (state, no_contact, "fallback_no_contact"), (bad_state, ref, "fallback_invalid_state"),
             (state, huge, None)]
    for st, r, expected in cases:
        cmd = wbc.compute(st, r)
        for arr in (cmd.q_des, cmd.qd_des, cmd.tau_ff, cmd.kp, cmd.kd):
            assert arr.shape == (g1.n_joints,) and np.all(np.isfinite(arr))
        if expected is not None:
            assert wbc.diagnostics.status == expected
            assert not wbc.diagnostics.ok
            # Fallback: the last good feed-forward, decaying, under a stiff PD hold.
            assert np.all(np.abs(cmd.tau_ff) <= np.abs(good.tau_ff) + 1e-12)
            assert np.array_equal(cmd.kp, g1.kp)
    wbc.compute(state, ref)
    assert wbc.diagnostics.status == "solved"


@pytest.mark.slow
def test_g1_survives_a_burst_of_garbage_references(g1):
    """0.2 s of NaN references mid-stance: the fallback holds the robot, the QP takes over again."""
    wbc = TaskSpaceInverseDynamics(g1)
    ref = wbc.hold_reference(g1.q_standing)
    broken = replace(ref, pelvis_rotation=np.full((3, 3), np.nan))
    sim = Simulation(g1, TrackingController(wbc, lambda s: broken if 0.5 <= s.t_s < 0.7 else ref))
    statuses = []
    run(sim, 1.5, lambda _s: ref, lambda: statuses.append(wbc.diagnostics.status))
    assert not sim.fallen
    assert "fallback_invalid_reference" in statuses and statuses[-1] == "solved"


# ----------------------------------------------------------------------------- placo peer


@pytest.mark.slow
def test_placo_wrapper_holds_g1_standing(g1):
    from engine.control.wbc.placo_peer import PlacoWbc

    ours = TaskSpaceInverseDynamics(g1)
    ref = ours.hold_reference(g1.q_standing)
    peer = PlacoWbc(g1)
    sim = Simulation(g1, TrackingController(peer, lambda _s: ref))
    feet0 = foot_sites(sim)
    statuses = set()
    errors = run(sim, 2.0, lambda _s: ref, lambda: statuses.add(peer.diagnostics.status))
    assert not sim.fallen
    assert statuses == {"solved"}
    assert errors.max() < 5e-3
    assert np.linalg.norm((foot_sites(sim) - feet0)[:, :2], axis=1).max() < 1e-3


@pytest.mark.parametrize("backend", ["dense", "osqp"])
@pytest.mark.parametrize("pattern", ["left_only", "right_toe"])
def test_actuator_torque_limits_hold_and_backends_agree(g1, backend, pattern):
    """With limits low enough to bind (a third of the URDF effort), the solution's torques stay
    within them, the dynamics still hold exactly, and both backends find the same optimum."""
    gains = replace(WbcGains.for_robot(g1), torque_limit_fraction=0.3)
    results = {}
    for name in ("dense", "osqp"):
        wbc = TaskSpaceInverseDynamics(g1, gains=gains, qp_backend=name)
        state = random_state(g1, 11)
        ref = wbc.hold_reference(g1.q_standing)
        ref = replace(ref, contact=np.array(PATTERNS[pattern], dtype=bool),
                      com_xy_acc_mps2=np.array([1.5, -1.0]))
        wbc.compute(state, ref)
        assert wbc.diagnostics.ok, wbc.diagnostics.status
        results[name] = wbc
    wbc = results[backend]
    limit = 0.3 * np.asarray(g1.effort_limits, dtype=float)
    tau = wbc.diagnostics.tau_nm
    tolerance = 1e-6 if backend == "dense" else 0.05 * limit.max() * 1e-2 + 1e-2
    assert np.all(np.abs(tau) <= limit + tolerance)
    # The limits are binding: without them the same QP asks for more torque somewhere.
    free = TaskSpaceInverseDynamics(g1, gains=replace(gains, torque_limit_fraction=1e3), qp_backend="dense")
    free.compute(random_state(g1, 11), replace(free.hold_reference(g1.q_standing),
                                               contact=np.array(PATTERNS[pattern], dtype=bool),
                                               com_xy_acc_mps2=np.array([1.5, -1.0])))
    assert np.any(np.abs(free.diagnostics.tau_nm) > limit + 1e-3)
    # Dynamics consistency on the limited solution.
    model, data = g1.pin_model, g1.pin_model.createData()
    state = random_state(g1, 11)
    jacs, _ = corner_jacobians(g1, state.q)
    lhs = pin.crba(model, data, state.q) @ wbc.diagnostics.qdd + pin.nonLinearEffects(model, data, state.q, state.v)
    rhs = np.concatenate([np.zeros(6), tau]) + np.einsum("fcki,fck->i", jacs, wbc.diagnostics.contact_forces_n)
    assert np.max(np.abs(lhs - rhs)) < 1e-6
    dense, sparse = results["dense"], results["osqp"]
    cost_dense = dense.qp.objective(dense.diagnostics.qdd, dense.diagnostics.rho)
    cost_osqp = dense.qp.objective(sparse.diagnostics.qdd, sparse.diagnostics.rho)
    scale = abs(cost_dense) + 1.0
    assert cost_dense <= cost_osqp + 1e-6 * scale
    assert cost_osqp - cost_dense < 1e-2 * scale


def test_snapshot_jacobians_come_from_crba() -> None:
    """DynamicsSnapshot skips computeJointJacobians: pinocchio's CRBA (WORLD convention) fills data.J.
    The frame Jacobians and drifts equal those of a data that ran it."""
    import pinocchio as pin

    from engine.control.wbc.tasks import DynamicsSnapshot

    robot = load_robot("g1")
    model = robot.pin_model
    rng = np.random.default_rng(3)
    q = robot.q_standing.copy()
    q[7:] += rng.normal(0.0, 0.1, robot.n_joints)
    v = rng.normal(0.0, 0.5, model.nv)
    fids = [model.getFrameId(f"{s}_foot") for s in SIDES]
    snap = DynamicsSnapshot.compute(model, model.createData(), q, v, fids)
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.computeCentroidalMomentumTimeVariation(model, data, q, v, np.zeros(model.nv))
    for i, fid in enumerate(fids):
        np.testing.assert_allclose(snap.frame_jacobian[i], pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED), atol=1e-12)
        np.testing.assert_allclose(snap.frame_drift[i], pin.getFrameClassicalAcceleration(
            model, data, fid, pin.LOCAL_WORLD_ALIGNED).vector, atol=1e-9)
