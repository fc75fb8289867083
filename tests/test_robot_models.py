"""Pinocchio and MuJoCo built from one source agree: masses and every body's pose."""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from engine.robot.config import robot_names
from engine.robot.model import contact_frame_names, load_robot

ROBOTS = robot_names()


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request):
    return load_robot(request.param)


def test_total_mass_agrees(robot):
    mj_mass = float(robot.mj_model.body_mass.sum())
    assert robot.mass_kg > 1.0
    assert abs(mj_mass - robot.mass_kg) <= 1e-3 * robot.mass_kg


def test_every_body_pose_agrees_over_random_configurations(robot):
    rng = np.random.default_rng(7)
    pm = robot.pin_model
    pdata = pm.createData()
    mdata = mujoco.MjData(robot.mj_model)
    lo = np.where(np.isfinite(robot.joint_lower), robot.joint_lower, -np.pi)
    hi = np.where(np.isfinite(robot.joint_upper), robot.joint_upper, np.pi)
    checked = 0
    for _ in range(20):
        q = pin.neutral(pm)
        q[0:3] = rng.uniform(-1, 1, 3)
        quat = rng.normal(size=4)
        q[3:7] = quat / np.linalg.norm(quat)
        q[7:] = rng.uniform(lo, hi)
        pin.framesForwardKinematics(pm, pdata, q)
        mdata.qpos[:] = robot.mj_qpos_from_pin(q)
        mujoco.mj_kinematics(robot.mj_model, mdata)
        for bid, name in enumerate(robot.body_names, start=1):
            fid = pm.getFrameId(name, pin.FrameType.BODY)
            assert fid < len(pm.frames), f"{name} has no pinocchio frame"
            np.testing.assert_allclose(mdata.xpos[bid], pdata.oMf[fid].translation, atol=1e-6, err_msg=name)
            np.testing.assert_allclose(mdata.xmat[bid].reshape(3, 3), pdata.oMf[fid].rotation, atol=1e-5, err_msg=name)
            checked += 1
    assert checked >= 20 * 10


def test_configuration_maps_round_trip(robot):
    rng = np.random.default_rng(3)
    q = pin.randomConfiguration(robot.pin_model, -np.ones(robot.pin_model.nq), np.ones(robot.pin_model.nq))
    q[7:] = rng.uniform(-0.5, 0.5, robot.n_joints)
    np.testing.assert_allclose(robot.pin_q_from_mj(robot.mj_qpos_from_pin(q)), q)


def test_velocity_map_matches_pinocchio_kinematics(robot):
    """Base-frame twist conversion: the root body's world velocity agrees between both models."""
    rng = np.random.default_rng(5)
    mdata = mujoco.MjData(robot.mj_model)
    q = robot.q_standing.copy()
    mdata.qpos[:] = robot.mj_qpos_from_pin(q)
    mdata.qvel[:] = rng.normal(size=robot.mj_model.nv)
    v = robot.pin_v_from_mj(mdata.qvel, mdata.qpos)
    pdata = robot.pin_model.createData()
    pin.forwardKinematics(robot.pin_model, pdata, q, v)
    pin.updateFramePlacements(robot.pin_model, pdata)
    for name in robot.body_names[-3:]:
        fid = robot.pin_model.getFrameId(name, pin.FrameType.BODY)
        twist = pin.getFrameVelocity(robot.pin_model, pdata, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        res = np.zeros(6)
        mujoco.mj_forward(robot.mj_model, mdata)
        bid = robot.mj_model.body(name).id
        mujoco.mj_objectVelocity(robot.mj_model, mdata, mujoco.mjtObj.mjOBJ_BODY, bid, res, 0)
        # MuJoCo reports the body's velocity at its centre of mass.
        at_com = twist.linear + np.cross(twist.angular, mdata.xipos[bid] - mdata.xpos[bid])
        np.testing.assert_allclose(res[:3], twist.angular, atol=1e-5, err_msg=name)
        np.testing.assert_allclose(res[3:], at_com, atol=1e-5, err_msg=name)


def test_standing_pose_touches_the_ground(robot):
    if not robot.config.simulated:
        pytest.skip("source skeleton")
    data = mujoco.MjData(robot.mj_model)
    data.qpos[:] = robot.mj_standing_qpos()
    mujoco.mj_kinematics(robot.mj_model, data)
    assert abs(robot.lowest_contact_z(data)) < 1e-9
    assert len(robot.contact_geom_ids) == len(contact_frame_names(robot.config))


def test_browser_meshes_are_light_and_cover_the_robot(robot):
    faces = sum(len(bm.faces) for bm in robot.body_meshes)
    assert 1000 < faces <= 1.5 * robot.config.visual_face_budget
    assert {bm.body for bm in robot.body_meshes} <= set(robot.body_names)


def test_figures_match_the_package_descriptions():
    g1, talos = load_robot("g1"), load_robot("talos")
    assert g1.n_joints == 29 and abs(g1.mass_kg - 33.3) < 0.2 and abs(g1.height_m - 1.32) < 0.03
    assert talos.n_joints == 32 and abs(talos.mass_kg - 90.3) < 0.5


def test_disk_cache_reproduces_a_fresh_build(tmp_path, monkeypatch):
    from engine.robot.config import load_robot_config
    from engine.robot.model import build_robot

    monkeypatch.setenv("MOTION_STUDIO_CACHE", str(tmp_path))
    cfg = load_robot_config("go2")
    fresh = build_robot(cfg)
    cached = build_robot(cfg)
    assert list((tmp_path / "robots").iterdir())
    assert cached.mj_model.nbody == fresh.mj_model.nbody and cached.mj_model.ngeom == fresh.mj_model.ngeom
    np.testing.assert_allclose(cached.mj_model.body_mass, fresh.mj_model.body_mass)
    np.testing.assert_allclose(cached.q_standing, fresh.q_standing)
