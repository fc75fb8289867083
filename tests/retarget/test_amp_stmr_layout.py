"""`studio export --format amp-json --amp-full` of an STMR result, read the way STMR_RL's AMPLoader slices a frame
(rsl_rl/datasets/motion_loader.py at terry97-guel/STMR_RL dfc490f: root pos 0:3, root quat x,y,z,w 3:7, joints
7:19, toe positions in the base frame 19:31, base linear velocity 31:34, angular velocity 34:37, joint velocities
37:49, toe velocities 49:61; its pybullet → Isaac reorder is commented out, so the file must already be in Isaac
leg order FL, FR, RL, RR: ``--amp-leg-order isaac``)."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from tests.conftest import run_studio

POS, ROT, JOINTS, TOES, LIN, ANG, JVEL, TVEL = (slice(0, 3), slice(3, 7), slice(7, 19), slice(19, 31), slice(31, 34),
                                                slice(34, 37), slice(37, 49), slice(49, 61))


@pytest.fixture(scope="module")
def stmr_file(tmp_path_factory):  # noqa: ANN201
    from engine.retarget.quadruped.tmr import kinematic_clips
    from engine.retarget.quadruped.tmr.tmr import TMRSettings, temporal_retarget
    from engine.robot.model import load_robot

    clip = kinematic_clips.trot(load_robot("go1"), duration_s=0.4, settle_s=0.1)
    result = temporal_retarget(clip, TMRSettings(budget=1, init_points=1))
    path = tmp_path_factory.mktemp("amp") / "trot_stmr.npz"
    result.motion.save(path)
    return path


@pytest.mark.slow  # `studio export` processes; the layout in process: tests/retarget/test_motion_and_export.py
@pytest.mark.parametrize("order, legs", [("isaac", ("FL", "FR", "RL", "RR")), ("pybullet", ("FR", "FL", "RR", "RL"))])
def test_stmr_result_in_the_amp_loaders_61_value_layout(stmr_file, tmp_path, order, legs) -> None:  # noqa: ANN001
    from engine.retarget.motion import RobotMotion
    from engine.retarget.quadruped.kinematics import quadruped_kinematics

    out = tmp_path / f"trot_{order}.json"
    res = run_studio("export", str(stmr_file), "--format", "amp-json", "--amp-full", "--amp-leg-order", order,
                     "--out", str(out), timeout=300)
    assert res.returncode == 0, res.stderr
    doc = json.loads(out.read_text())
    motion = RobotMotion.load(stmr_file)
    f = np.array(doc["Frames"])
    assert f.shape == (motion.frames, 61) and doc["FrameDuration"] == pytest.approx(1.0 / motion.fps)
    assert [n[:2] for n in doc["JointNames"][::3]] == list(legs)
    # joints: the STMR replay's joints, by name, in the file's leg order
    cols = [motion.joint_names.index(n) for n in doc["JointNames"]]
    np.testing.assert_allclose(f[:, JOINTS], motion.qpos[:, 7:][:, cols], atol=1e-6)
    np.testing.assert_allclose(f[:, POS], motion.qpos[:, :3], atol=1e-6)
    np.testing.assert_allclose(f[:, ROT], motion.qpos[:, [4, 5, 6, 3]], atol=1e-6)  # x,y,z,w
    # toes in the base frame, legs in the file's order: left legs (FL, RL) have y > 0
    kin = quadruped_kinematics("go1")
    data = kin.model.createData()
    engine_legs = ("FL", "FR", "RL", "RR")
    for k in (0, motion.frames // 2, motion.frames - 1):
        from engine.export.amp_json import _mj_qpos  # noqa: PLC2701

        qp = kin.robot.pin_q_from_mj(_mj_qpos(kin, motion, motion.qpos[k]))
        feet = kin.feet(data, qp)
        R = pin.Quaternion(qp[3:7]).toRotationMatrix()
        local = (feet - qp[:3]) @ R
        expected = np.concatenate([local[engine_legs.index(leg)] for leg in legs])
        np.testing.assert_allclose(f[k, TOES], expected, atol=1e-5)
        assert all((f[k, TOES][3 * i + 1] > 0) == leg.endswith("L") for i, leg in enumerate(legs))
    # velocities: forward differences in the base frame, as preprocess_FD_motion.py makes them
    dt = doc["FrameDuration"]
    k = motion.frames // 2
    R = pin.Quaternion(f[k, 6], *f[k, 3:6]).toRotationMatrix()
    np.testing.assert_allclose(f[k, LIN], R.T @ (f[k + 1, POS] - f[k, POS]) / dt, atol=1e-3)
    R1 = pin.Quaternion(f[k + 1, 6], *f[k + 1, 3:6]).toRotationMatrix()
    np.testing.assert_allclose(f[k, ANG], pin.log3(R.T @ R1) / dt, atol=1e-3)
    np.testing.assert_allclose(f[k, JVEL], (f[k + 1, JOINTS] - f[k, JOINTS]) / dt, atol=1e-3)
    np.testing.assert_allclose(f[k, TVEL], (f[k + 1, TOES] - f[k, TOES]) / dt, atol=1e-3)


@pytest.mark.slow  # its fixture is a TMR run
def test_leg_order_needs_amp_full(stmr_file, tmp_path) -> None:  # noqa: ANN001
    res = run_studio("export", str(stmr_file), "--format", "amp-json", "--amp-leg-order", "isaac",
                     "--out", str(tmp_path / "x.json"), timeout=120)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1 and "--amp-leg-order: only with --amp-full" in lines[0]
    assert not (tmp_path / "x.json").exists()
