"""The compiled whole-body reference between planner ticks (engine/control/reference_kernels.py) computes the
same numbers, bit for bit, as the Python it replaced in WalkingController._wbc_reference."""

from __future__ import annotations

from dataclasses import fields

import numpy as np
import pytest

from engine.control import walking_controller
from engine.control.reference_kernels import interpolate_reference, interpolate_references
from engine.control.walking_controller import TICKS_PER_PLAN, WalkingController
from engine.control.wbc import WbcReference
from engine.gait.command_schedule import CommandSchedule, preset
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot
from engine.sim import Simulation
from tests.control.test_glue_speed_references import rotate_reference as _rotate  # = walking_controller._rotate, bit for bit


def wbc_reference_before(controller: WalkingController, dt_since: float) -> WbcReference:
    """WalkingController._wbc_reference before the compiled call (commit a952e5f), its tables inlined."""
    ref, plan = controller.ref, controller.plan
    assert ref is not None and plan is not None
    t = ref.t_s + dt_since
    com, com_vel, com_acc = plan.com_at(t)
    foot_pos = ref.foot_pos + ref.foot_lin_vel * dt_since
    contact = ref.corner_contact & ref.contact[:, None]
    turning = [(i, omega) for i, omega in enumerate(ref.foot_ang_vel.tolist())
               if omega[0] != 0.0 or omega[1] != 0.0 or omega[2] != 0.0]
    foot_rot = ref.foot_rot.copy()
    if dt_since != 0.0:
        for i, omega in turning:
            foot_rot[i] = _rotate(foot_rot[i], omega, dt_since)
    return WbcReference(
        com_xy_m=com, com_xy_vel_mps=com_vel, com_xy_acc_mps2=com_acc,
        pelvis_height_m=ref.pelvis_z + ref.pelvis_z_rate * dt_since, pelvis_height_rate_mps=ref.pelvis_z_rate,
        pelvis_rotation=_rotate(ref.pelvis_rot, ref.pelvis_ang_vel.tolist(), dt_since),
        pelvis_ang_vel_radps=ref.pelvis_ang_vel, foot_pos_m=foot_pos, foot_rotation=foot_rot,
        foot_lin_vel_mps=ref.foot_lin_vel, foot_ang_vel_radps=ref.foot_ang_vel, contact=contact,
        upper_body_q_rad=ref.upper_q + ref.upper_qd * dt_since, upper_body_qd_radps=ref.upper_qd,
        foot_lin_acc_mps2=controller._foot_acc, foot_ang_acc_radps2=controller._foot_ang_acc,
    )


def _neutral_sweep() -> tuple[WalkingController, Simulation, CommandSchedule, float]:
    """G1's neutral style in closed loop, with the sweep's command schedule and the simulation's time step."""
    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    controller = WalkingController(robot, style)
    sim = Simulation(robot, controller)
    return controller, sim, preset("sweep", style.velocities), float(sim.model.opt.timestep)


def test_wbc_reference_matches_the_python_it_replaced() -> None:
    controller, sim, schedule, dt = _neutral_sweep()
    feet_turned = compared = 0
    for k in range(1500):  # 3 s of the sweep: standing, walking, turning
        controller.set_command(schedule(k * dt))
        sim.step()
        assert not sim.fallen
        if k % 7:
            continue
        ref = controller.ref
        assert ref is not None
        for dt_since in (0.0, 0.002, 0.004, 0.006):
            now, before = controller._wbc_reference(dt_since), wbc_reference_before(controller, dt_since)
            for f in fields(WbcReference):
                a, b = getattr(now, f.name), getattr(before, f.name)
                if b is None:
                    assert a is None, f.name
                else:
                    np.testing.assert_array_equal(a, b, err_msg=f"{f.name} at tick {k}, {dt_since} s after")
            if dt_since == 0.0:
                assert now.pelvis_rotation is ref.pelvis_rot  # a pelvis that does not move keeps the planner's array
            compared += 1
        feet_turned += bool(np.abs(ref.foot_ang_vel).max() > 0.0)
    assert compared > 800 and feet_turned > 10  # the feet's rotations were exercised (the pelvis: the test below)


def test_rotations_match_rotate_on_random_rates() -> None:
    """The pelvis' and the feet's rotations against walking_controller._rotate (random rotations and rates, among
    them a zero rate, one below the 1e-12 rad angle and dt = 0, where the input array itself comes back)."""
    rng = np.random.default_rng(12)
    times = np.array([0.0, 0.1, 0.3])
    points = rng.standard_normal((3, 2))
    for trial in range(300):
        q, _ = np.linalg.qr(rng.standard_normal((3, 3, 3)))
        pelvis, feet = q[0], np.ascontiguousarray(q[1:])
        omegas = rng.standard_normal((3, 3)) * rng.choice([0.0, 1e-15, 1.0, 5.0], size=(3, 1))
        dt = float(rng.choice([0.0, 0.002, 0.004, 0.006]))
        _, _, rot, pelvis_rot, _ = interpolate_reference(
            dt, 0.05, times, points, points, points, 3.5, np.zeros((2, 3)), np.zeros((2, 3)), feet, omegas[1:],
            pelvis, omegas[0], np.zeros(3), np.zeros(3))
        np.testing.assert_array_equal(pelvis_rot, _rotate(pelvis, omegas[0].tolist(), dt))
        if dt == 0.0 or np.sqrt(((omegas[0] * dt) ** 2).sum()) < 1e-12:
            assert pelvis_rot is pelvis
        for i in range(2):
            turning = bool((omegas[1 + i] != 0.0).any())
            expected = _rotate(feet[i], omegas[1 + i].tolist(), dt) if turning and dt != 0.0 else feet[i]
            np.testing.assert_array_equal(rot[i], expected)


def test_interpolate_references_equals_one_call_per_tick() -> None:
    """The references of the ticks until the planner's next one in one call (interpolate_references, what
    WalkingController._wbc_reference reads) against interpolate_reference at each tick, bit for bit, on random plans,
    rotations and rates (among them zero rates and angles below 1e-12 rad), including whether the pelvis turned
    (where interpolate_reference hands back the planner's array itself)."""
    rng = np.random.default_rng(11)
    period = 0.002
    pelvis_still = pelvis_turned = 0
    for trial in range(300):
        n_wp = int(rng.integers(2, 8))
        times = np.cumsum(rng.uniform(0.01, 0.2, n_wp)) - 0.1
        wps, coms, vels = (rng.standard_normal((n_wp, 2)) for _ in range(3))
        omega = float(rng.uniform(2.0, 5.0))
        q, _ = np.linalg.qr(rng.standard_normal((3, 3, 3)))
        pelvis, feet = q[0], np.ascontiguousarray(q[1:])
        omegas = rng.standard_normal((3, 3)) * rng.choice([0.0, 1e-15, 1.0, 5.0], size=(3, 1))
        foot_pos, foot_vel = rng.standard_normal((2, 3)), rng.standard_normal((2, 3))
        n_upper = int(rng.integers(0, 9))
        upper_q, upper_qd = rng.standard_normal(n_upper), rng.standard_normal(n_upper)
        t0 = float(rng.uniform(times[0] - 0.05, times[-1] + 0.05))  # before, inside and after the waypoints
        args = (times, wps, coms, vels, omega, foot_pos, foot_vel, feet, omegas[1:], pelvis, omegas[0], upper_q, upper_qd)
        n = TICKS_PER_PLAN
        coms_k, pos_k, rot_k, pelvis_k, turned_k, upper_k = out = (
            np.empty((n, 3, 2)), np.empty((n, 2, 3)), np.empty((n, 2, 3, 3)), np.empty((n, 3, 3)),
            np.empty(n, dtype=np.bool_), np.empty((n, n_upper)))
        interpolate_references(period, t0, *args, *out)
        for k in range(TICKS_PER_PLAN):
            dt = k * period  # as WalkingController.compute's dt_since
            com, pos, rot, pelvis_rot, upper = interpolate_reference(dt, t0 + dt, *args)
            np.testing.assert_array_equal(coms_k[k], com)
            np.testing.assert_array_equal(pos_k[k], pos)
            np.testing.assert_array_equal(rot_k[k], rot)
            np.testing.assert_array_equal(pelvis_k[k], pelvis_rot)
            np.testing.assert_array_equal(upper_k[k], upper)
            assert bool(turned_k[k]) == (pelvis_rot is not pelvis)
            pelvis_still += pelvis_rot is pelvis
            pelvis_turned += pelvis_rot is not pelvis
    assert pelvis_still > 100 and pelvis_turned > 100


def test_wbc_reference_of_a_control_tick_equals_the_one_call_version(monkeypatch: pytest.MonkeyPatch) -> None:
    """WalkingController._wbc_reference at each control tick's dt_since (the batch of interpolate_references) against
    the same controller's one-call path (interpolate_reference, taken when dt_since is no control tick's) on a sweep,
    every field bit for bit, and the pelvis' identity where it does not turn."""
    controller, sim, schedule, dt = _neutral_sweep()
    compared = 0
    for k in range(1200):
        controller.set_command(schedule(k * dt))
        sim.step()
        if k % 5:
            continue
        ref, plan = controller.ref, controller.plan
        assert ref is not None and plan is not None
        for j in range(TICKS_PER_PLAN):
            dt_since = j * 0.002
            got = controller._wbc_reference(dt_since)
            assert controller._reference_batch[0] is ref and controller._reference_batch[1] is plan
            with monkeypatch.context() as patch:  # no time is a control tick's: the one-call path
                patch.setattr(walking_controller, "_TICK_OF_DT", {})
                want = controller._wbc_reference(dt_since)
            for f in fields(WbcReference):
                a, b = getattr(got, f.name), getattr(want, f.name)
                if b is None:
                    assert a is None, f.name
                else:
                    np.testing.assert_array_equal(a, b, err_msg=f"{f.name} at tick {k}, {dt_since} s after")
            assert (got.pelvis_rotation is ref.pelvis_rot) == (want.pelvis_rotation is ref.pelvis_rot)
            compared += 1
    assert compared > 900 and not sim.fallen
