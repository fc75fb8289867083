"""The per-tick glue around the control stack's stages computes the same numbers as before (issue 12).

The simulation's state read-out and joint servos, the command schedule, and the walking
controller's whole-body reference: each test keeps the implementation before the speed-up as the
reference and asserts equal results: bit for bit where the code only moves numbers, to rounding
(:mod:`tests.rounding`) where a numpy product became float arithmetic.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
import pytest

from engine.control.controller import JointCommand
from engine.robot.model import load_robot
from tests.rounding import assert_equal_to_rounding


# ----------------------------------------------------------------------------- the state read-out


def pin_q_reference(robot, qpos: np.ndarray) -> np.ndarray:  # noqa: ANN001
    """RobotModel.pin_q_from_mj before the speed-up."""
    q = np.zeros(robot.pin_model.nq)
    q[0:3] = qpos[0:3]
    q[3:6] = qpos[4:7]
    q[6] = qpos[3]
    q[7:] = qpos[robot.mj_qpos_index]
    return q


def pin_v_reference(robot, qvel: np.ndarray, qpos: np.ndarray) -> np.ndarray:  # noqa: ANN001
    """RobotModel.pin_v_from_mj before the speed-up (Rᵀ v by matmul)."""
    v = np.zeros(robot.pin_model.nv)
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, qpos[3:7])
    v[0:3] = rot.reshape(3, 3).T @ qvel[0:3]
    v[3:6] = qvel[3:6]
    v[6:] = qvel[robot.mj_dof_index]
    return v


@pytest.mark.parametrize("name", ["g1", "talos"])  # TALOS: joints out of MuJoCo's order
def test_state_read_out_equals_the_former_conversions(name: str) -> None:
    robot = load_robot(name)
    rng = np.random.default_rng(11)
    nq, nv = robot.mj_model.nq, robot.mj_model.nv
    for k in range(3000):
        qpos = rng.normal(0.0, 1.0, nq) * 10.0 ** rng.uniform(-3, 1)
        qpos[3:7] /= np.linalg.norm(qpos[3:7]) if k % 3 else 1.0  # unit and non-unit quaternions
        if k == 0:
            qpos[3:7] = (1.0, 0.0, 0.0, 0.0)  # MuJoCo's identity shortcut
        qvel = rng.normal(0.0, 1.0, nv) * 10.0 ** rng.uniform(-4, 2)
        np.testing.assert_array_equal(robot.pin_q_from_mj(qpos), pin_q_reference(robot, qpos))
        # Rᵀ v unrolled: rounds as numpy's matmul on some CPUs, an ulp off on others; the terms are |R|ᵀ|v|
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, qpos[3:7])
        terms = float((np.abs(rot.reshape(3, 3)).T @ np.abs(qvel[0:3])).max())
        assert_equal_to_rounding(robot.pin_v_from_mj(qvel, qpos), pin_v_reference(robot, qvel, qpos), scale=terms)


# ----------------------------------------------------------------------------- the joint servos


def torque_reference(cmd: JointCommand, q: np.ndarray, qd: np.ndarray, limits: np.ndarray) -> np.ndarray:
    """JointCommand.torque before the speed-up, with Simulation._apply_servos' finiteness fallback."""
    tau = cmd.kp * (cmd.q_des - q) + cmd.kd * (cmd.qd_des - qd) + cmd.tau_ff
    tau = np.clip(tau, -limits, limits)
    return np.zeros_like(tau) if not np.all(np.isfinite(tau)) else tau


def test_servo_torques_equal_the_clipped_expression() -> None:
    from engine.sim import Simulation

    robot = load_robot("g1")
    sim = Simulation(robot)
    n = robot.n_joints
    rng = np.random.default_rng(12)
    limits = np.asarray(robot.effort_limits, dtype=float)
    for k in range(2000):
        scale = 10.0 ** rng.uniform(-2, 4)
        cmd = JointCommand(rng.normal(0, 1, n), rng.normal(0, 3, n), rng.normal(0, 1, n) * scale,
                           rng.uniform(0, 500, n), rng.uniform(0, 50, n))
        q, qd = rng.normal(0, 1, n), rng.normal(0, 3, n)
        if k % 7 == 0:
            cmd.tau_ff[rng.integers(n)] = [np.nan, np.inf, -np.inf][k % 3]
        if k % 11 == 0:
            qd[rng.integers(n)] = 1e300  # finite, but Σ τ² overflows before the clip
        want = torque_reference(cmd, q, qd, limits)
        np.testing.assert_array_equal(cmd.torque(q, qd, limits), np.clip(
            cmd.kp * (cmd.q_des - q) + cmd.kd * (cmd.qd_des - qd) + cmd.tau_ff, -limits, limits))
        np.testing.assert_array_equal(cmd.torque(q, qd, limits, -limits), cmd.torque(q, qd, limits))
        sim._apply_servos(cmd, q, qd)
        np.testing.assert_array_equal(sim.data.ctrl[robot.mj_actuator_index], want)


def test_fall_check_finiteness_equals_the_sum() -> None:
    from engine.sim import _finite_sum

    rng = np.random.default_rng(13)
    for k in range(3000):
        x = rng.normal(0, 1, 36) * 10.0 ** rng.uniform(-3, 3)
        if k % 5 == 0:
            x[rng.integers(36)] = [np.nan, np.inf, -np.inf, 1e200, 1.7e308][k % 5 if k % 25 else 4]
        if k % 13 == 0:
            x[:2] = (1.7e308, 1.7e308)  # each finite, their sum is not
        assert _finite_sum(x) == math.isfinite(float(x.sum()))


# ----------------------------------------------------------------------------- the command schedule


def schedule_reference(times: np.ndarray, values: np.ndarray, t_s: float) -> np.ndarray:
    """CommandSchedule.__call__ before the speed-up (searchsorted, (3,)-array arithmetic)."""
    if t_s <= times[0]:
        return values[0].copy()
    if t_s >= times[-1]:
        return values[-1].copy()
    j = int(np.searchsorted(times, t_s, side="right")) - 1
    t0, t1 = times[j], times[j + 1]
    v0 = values[j]
    return (values[j + 1] - v0) / (t1 - t0) * (t_s - t0) + v0


def test_command_schedule_equals_the_array_interpolation() -> None:
    from engine.gait.command_schedule import CommandSchedule, from_keyframes

    rng = np.random.default_rng(14)
    for _ in range(200):
        k = int(rng.integers(1, 30))
        times = np.cumsum(rng.uniform(0.01, 3.0, k)) - 1.0
        values = rng.normal(0, 1, (k, 3))
        schedule = from_keyframes(np.column_stack([times, values]).tolist(), "test")
        samples = np.r_[times, rng.uniform(times[0] - 1, times[-1] + 1, 30), 0.002 * rng.integers(0, 5000, 20)]
        for t in samples.tolist():
            np.testing.assert_array_equal(schedule(t), schedule_reference(schedule.times_s, schedule.values, t))
        direct = CommandSchedule(times, values)  # built from arrays as well as from keyframes
        np.testing.assert_array_equal(direct(float(times[-1]) - 1e-3), schedule_reference(times, values, float(times[-1]) - 1e-3))


# ----------------------------------------------------------------------------- the walking controller


def rotate_reference(rot: np.ndarray, omega: np.ndarray, dt: float) -> np.ndarray:
    """walking_controller._rotate before the speed-up (``r @ rot``)."""
    if dt == 0.0:
        return rot
    wx, wy, wz = float(omega[0]) * dt, float(omega[1]) * dt, float(omega[2]) * dt
    angle = math.sqrt(wx * wx + wy * wy + wz * wz)
    if angle < 1e-12:
        return rot
    kx, ky, kz = wx / angle, wy / angle, wz / angle
    s, c = math.sin(angle), 1.0 - math.cos(angle)
    r = np.array([
        [1 - c * (ky * ky + kz * kz), c * kx * ky - s * kz, c * kx * kz + s * ky],
        [c * kx * ky + s * kz, 1 - c * (kx * kx + kz * kz), c * ky * kz - s * kx],
        [c * kx * kz - s * ky, c * ky * kz + s * kx, 1 - c * (kx * kx + ky * ky)],
    ])
    return r @ rot


def test_rotate_equals_the_matmul_version() -> None:
    """The compiled rotation the whole-body reference uses (reference_kernels._rotate, which replaced
    walking_controller._rotate) gives the matmul version's numbers."""
    from engine.control.reference_kernels import _rotate

    rng = np.random.default_rng(15)
    for _ in range(3000):
        rots = np.linalg.qr(rng.normal(size=(2, 3, 3)))[0]  # (2, 3, 3): rows of a stacked array, as the feet's
        omega = rng.normal(0, 3, 3)
        dt = float(rng.choice([0.0, 0.002, 0.004, 0.006]))
        np.testing.assert_array_equal(_rotate(rots[1], *omega.tolist(), dt), rotate_reference(rots[1], omega, dt))


def command_filter_reference(command: np.ndarray, filtered: np.ndarray, accel_limits: np.ndarray, dt: float,
                             adjust: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plan tick's command rate limit before the speed-up (3-vectors): (filtered, command, goal)."""
    target = np.where(np.isfinite(command), command, 0.0)
    limit = accel_limits * dt
    step = np.clip(target - filtered, -limit, limit)
    filtered = filtered + step
    out = filtered.copy()
    out[:2] += adjust
    goal = target.copy()
    goal[:2] += adjust
    return filtered, out, goal


def test_plan_tick_command_filter_equals_the_array_version() -> None:
    """Run the plan tick's command filter on a controller stub against the array expressions."""
    from engine.control.walking_controller import PLAN_DT_S

    rng = np.random.default_rng(16)
    for k in range(3000):
        command = rng.normal(0, 1, 3)
        if k % 9 == 0:
            command[rng.integers(3)] = [np.nan, np.inf, -np.inf][k % 3]
        filtered, limits, adjust = rng.normal(0, 1, 3), rng.uniform(0, 5, 3), rng.normal(0, 0.1, 2)
        want = command_filter_reference(command, filtered, limits, PLAN_DT_S, adjust)
        # the float form, as written in WalkingController._plan_tick
        target = [c if math.isfinite(c) else 0.0 for c in command.tolist()]
        lim = [a * PLAN_DT_S for a in limits.tolist()]
        new = [f + min(max(t - f, -m), m) for t, f, m in zip(target, filtered.tolist(), lim)]
        ax, ay = adjust.tolist()
        got = (np.array(new), np.array([new[0] + ax, new[1] + ay, new[2]]),
               np.array([target[0] + ax, target[1] + ay, target[2]]))
        for g, w in zip(got, want):
            np.testing.assert_array_equal(g, w)
        polygon = rng.normal(0, 1, (int(rng.integers(3, 12)), 2))
        np.testing.assert_array_equal(polygon.sum(axis=0) / len(polygon), polygon.mean(axis=0))


def wbc_reference_reference(controller, dt_since: float):  # noqa: ANN001, ANN201
    """WalkingController._wbc_reference before the speed-up."""
    from engine.control.wbc import WbcReference

    ref, plan = controller.ref, controller.plan
    t = ref.t_s + dt_since
    com, com_vel, com_acc = plan.com_at(t)
    foot_pos = ref.foot_pos + ref.foot_lin_vel * dt_since
    foot_rot = np.array([rotate_reference(ref.foot_rot[i], ref.foot_ang_vel[i], dt_since) for i in range(2)])
    contact = ref.corner_contact & ref.contact[:, None]
    return WbcReference(
        com_xy_m=com, com_xy_vel_mps=com_vel, com_xy_acc_mps2=com_acc,
        pelvis_height_m=ref.pelvis_z + ref.pelvis_z_rate * dt_since, pelvis_height_rate_mps=ref.pelvis_z_rate,
        pelvis_rotation=rotate_reference(ref.pelvis_rot, ref.pelvis_ang_vel, dt_since),
        pelvis_ang_vel_radps=ref.pelvis_ang_vel, foot_pos_m=foot_pos, foot_rotation=foot_rot,
        foot_lin_vel_mps=ref.foot_lin_vel, foot_ang_vel_radps=ref.foot_ang_vel, contact=contact,
        upper_body_q_rad=ref.upper_q + ref.upper_qd * dt_since, upper_body_qd_radps=ref.upper_qd,
        foot_lin_acc_mps2=controller._foot_acc, foot_ang_acc_radps2=controller._foot_ang_acc,
    )


def test_wbc_reference_equals_the_former_one_on_a_turning_walk() -> None:
    from dataclasses import fields

    from engine.control.walking_controller import WalkingController
    from engine.gait.command_schedule import from_keyframes
    from engine.gait.style import load_style, styles_dir
    from engine.sim import Simulation

    robot = load_robot("g1")
    controller = WalkingController(robot, load_style(styles_dir("g1") / "neutral.json"))
    sim = Simulation(robot, controller)
    schedule = from_keyframes([[0.0, 0.0, 0.0, 0.0], [0.3, 0.0, 0.0, 0.0], [0.8, 0.2, 0.05, 0.5]], "turn")
    checked = 0
    for k in range(600):
        controller.set_command(schedule(k * 0.002))
        sim.step()
        if k % 3 == 0:
            for dt in (0.0, 0.002, 0.004, 0.006):
                got, want = controller._wbc_reference(dt), wbc_reference_reference(controller, dt)
                for f in fields(want):
                    np.testing.assert_array_equal(getattr(got, f.name), getattr(want, f.name), err_msg=f.name)
                checked += 1
    assert checked == 800 and not sim.fallen
    assert np.abs(controller.ref.pelvis_ang_vel).max() > 0.1  # turning: the pelvis rotation is advanced too


def external_wrench_reference(controller, est):  # noqa: ANN001, ANN201
    """WalkingController._external_wrench before the speed-up (np.cross)."""
    f = controller.observer.force_n
    if not f.any():
        return None
    force = np.array([f[0], f[1], 0.0])
    arm = est.q[:3] - controller._com_now[0]
    return np.concatenate([force, np.cross(arm, force)])


def test_external_wrench_equals_the_cross_product_under_a_push() -> None:
    from engine.control.walking_controller import WalkingController
    from engine.gait.style import load_style, styles_dir
    from engine.sim import Simulation

    robot = load_robot("g1")
    controller = WalkingController(robot, load_style(styles_dir("g1") / "neutral.json"))
    sim = Simulation(robot, controller)
    pushed = 0
    for k in range(450):
        if k == 150:
            sim.push(np.array([40.0, 60.0, 0.0]), 0.1)
        sim.step()
        got, want = controller._external_wrench(controller.estimate), external_wrench_reference(controller, controller.estimate)
        if want is None:
            assert got is None
        else:
            np.testing.assert_array_equal(got, want)
            pushed += 1
    assert pushed > 20 and not sim.fallen  # the observer saw the push for a while


def with_early_touchdown_reference(controller, est, reference):  # noqa: ANN001, ANN201
    """TouchdownTracker.with_early_touchdown (formerly WalkingController._with_early_touchdown) before the
    per-reference tables (the flags read every tick)."""
    import pinocchio as pin

    contact = reference.contact
    flags = contact.tolist()
    params = controller.params
    corner = [reference.foot_pos_m[i, 2] + (reference.foot_rotation[i] @ controller.touchdown.corner_offsets_m[i].T)[2].min()
              for i in range(2)]  # the planned sole's lowest corner
    low = [reference.foot_pos_m[i, 2] < params.landing_height_m
           or (params.landing_corner_height_m > 0.0 and corner[i] < params.landing_corner_height_m) for i in range(2)]
    landing = [i for i in range(2) if not any(flags[i]) and low[i] and reference.foot_lin_vel_mps[i, 2] <= 0.0]
    if not landing:
        return contact
    pin.framesForwardKinematics(controller.model, controller.data, est.q)
    contact = contact.copy()
    for i in landing:
        m = controller.data.oMf[controller.touchdown.foot_frames[i]]
        heights = m.translation[2] + (m.rotation @ controller.touchdown.corner_offsets_m[i].T)[2]
        contact[i] = heights < controller.params.touchdown_height_m
    return contact


def test_early_touchdown_glue_equals_the_former_per_tick_version() -> None:
    """The landing check on the per-reference tables, the kept early-touchdown flag and the swing feed-forward's
    clip (np.minimum/np.maximum) against the former expressions, every tick of a walk with landings."""
    from engine.control.touchdown import early_touchdown
    from engine.control.walking_controller import PLAN_DT_S, TICKS_PER_PLAN, WalkingController
    from engine.gait.style import load_style, styles_dir
    from engine.sim import Simulation

    robot = load_robot("g1")
    controller = WalkingController(robot, load_style(styles_dir("g1") / "neutral.json"))
    sim = Simulation(robot, controller)
    landed_early = flagged = 0
    prev_ref = None
    for k in range(900):
        controller.set_command(np.array([0.4, 0.0, 0.2]) if k > 100 else np.zeros(3))
        early_then = controller.touchdown.early_now(controller.wbc_contact, controller.ref.contact) \
            if controller.ref is not None else None
        if early_then is not None:
            assert early_then == early_touchdown(controller.wbc_contact, controller.ref.contact)
            flagged += early_then
        sim.step()
        ref = controller.ref
        if prev_ref is not None and ref is not prev_ref:  # a planner tick: the feed-forward against np.clip
            limit = controller.params.swing_feedforward_limit_mps2
            want = np.clip((ref.foot_lin_vel - prev_ref.foot_lin_vel) / PLAN_DT_S, -limit, limit)
            for i, down in enumerate(ref.contact.tolist()):
                if down:
                    want[i] = 0.0
            np.testing.assert_array_equal(controller._foot_acc, want)
        prev_ref = ref
        reference = controller._wbc_reference(((controller.tick - 1) % TICKS_PER_PLAN) * 0.002)
        got = controller.touchdown.with_early_touchdown(controller.estimate, reference, controller.ref,
                                                        controller.params)
        want = with_early_touchdown_reference(controller, controller.estimate, reference)
        np.testing.assert_array_equal(got, want)
        landed_early += got is not reference.contact
    assert landed_early > 5 and flagged > 0 and not sim.fallen  # feet did reach the floor before their touchdown
    x = np.array([0.0, -0.0, 1.0, -2.0, math.nan, math.inf, -math.inf, 5e-324])
    limit = 1.0
    np.testing.assert_array_equal(np.minimum(np.maximum(x, -limit), limit), np.clip(x, -limit, limit))


def test_two_vector_any_on_floats_equals_the_array_method() -> None:
    from engine.control.step_adjustment import _any2

    values = [0.0, -0.0, 1e-300, -5e-324, 2.0, math.nan, math.inf, -math.inf]
    for a in values:
        for b in values:
            v = np.array([a, b])
            assert _any2(v) == bool(v.any())
