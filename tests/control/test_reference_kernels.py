"""The compiled whole-body reference between planner ticks (engine/control/reference_kernels.py) computes the
same numbers, bit for bit, as the Python it replaced in WalkingController._wbc_reference."""

from __future__ import annotations

from dataclasses import fields

import numpy as np

from engine.control.reference_kernels import interpolate_reference
from engine.control.walking_controller import WalkingController
from engine.control.wbc import WbcReference
from engine.gait.command_schedule import preset
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


def test_wbc_reference_matches_the_python_it_replaced() -> None:
    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    schedule = preset("sweep", style.velocities)
    controller = WalkingController(robot, style)
    sim = Simulation(robot, controller)
    dt = float(sim.model.opt.timestep)
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
