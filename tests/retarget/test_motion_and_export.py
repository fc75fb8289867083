"""Motion formats round-trip; exports re-read give the same motion (FK of the re-read frames within 1 mm)."""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from engine.export import export_motion
from engine.export.amp_json import read_amp_json
from engine.export.unitree_csv import read_unitree_csv
from engine.retarget.motion import KeypointMotion, MotionFormatError, RobotMotion
from engine.retarget.quadruped.kinematics import quadruped_kinematics
from engine.retarget.quadruped.pipeline import retarget
from engine.retarget.synthetic import synthetic_trot


@pytest.fixture(scope="module")
def go1_motion() -> RobotMotion:
    return retarget(synthetic_trot("a1", frames=30), "go1", "smr")


def fk_feet(robot: str, qpos: np.ndarray, joint_names: list[str]) -> np.ndarray:
    kin = quadruped_kinematics(robot)
    model = kin.robot
    data = kin.model.createData()
    out = []
    for row in qpos:
        q = np.zeros(kin.nq)
        q[:3] = row[:3]
        q[3:7] = [row[4], row[5], row[6], row[3]]
        for name, value in zip(joint_names, row[7:]):
            q[7 + model.joint_names.index(name)] = value
        out.append(kin.feet(data, q))
    return np.array(out)


def test_keypoint_motion_round_trip(tmp_path):
    src = synthetic_trot("a1", frames=20)
    src.save(tmp_path / "s.npz")
    back = KeypointMotion.load(tmp_path / "s.npz")
    assert np.allclose(back.keypoints, src.keypoints) and (back.contact == src.contact).all()
    assert back.fps == src.fps and np.allclose(back.base_quat, src.base_quat)


def test_robot_motion_round_trip_and_biped_shape(tmp_path, go1_motion):
    go1_motion.save(tmp_path / "r.npz")
    back = RobotMotion.load(tmp_path / "r.npz")
    assert np.allclose(back.qpos, go1_motion.qpos) and back.joint_names == go1_motion.joint_names
    # the format is not quadruped-specific: a biped recording with two feet and no keypoints
    biped = RobotMotion(fps=50.0, qpos=np.tile(np.r_[0, 0, 0.8, 1, 0, 0, 0, np.zeros(29)], (5, 1)),
                        joint_names=[f"j{i}" for i in range(29)], contact=np.ones((5, 2), bool), robot="g1",
                        method="walk", foot_names=["left", "right"])
    biped.save(tmp_path / "b.npz")
    assert RobotMotion.load(tmp_path / "b.npz").foot_names == ["left", "right"]
    for fmt, name in (("amp-json", "b.json"), ("unitree-csv", "b.csv")):  # the exporters take it too
        export_motion(biped, fmt, tmp_path / name)
    qpos, names, _ = read_amp_json(tmp_path / "b.json")
    assert names == biped.joint_names and np.allclose(qpos, biped.qpos)
    assert np.allclose(read_unitree_csv(tmp_path / "b.csv"), biped.qpos)


def test_validation_names_file_and_field(tmp_path):
    src = synthetic_trot("a1", frames=10)
    kp = src.keypoints.copy()
    kp[3, 5, 1] = np.nan
    with pytest.raises(MotionFormatError, match="keypoints: expected finite numbers"):
        KeypointMotion(fps=30.0, keypoints=kp, contact=src.contact, source={"file": "x.npz"})
    with pytest.raises(MotionFormatError, match=r"x.npz: keypoints: expected at least 2 frames"):
        KeypointMotion(fps=30.0, keypoints=np.zeros((0, 16, 3)), contact=np.zeros((0, 4), bool), source={"file": "x.npz"})
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04 not really")
    with pytest.raises(MotionFormatError, match="bad.npz"):
        KeypointMotion.load(tmp_path / "bad.npz")


@pytest.mark.parametrize("fmt,full", [("amp-json", False), ("amp-json", True), ("unitree-csv", False), ("npz", False)])
def test_export_reread_same_motion(tmp_path, go1_motion, fmt, full):
    path = tmp_path / {"amp-json": "m.json", "unitree-csv": "m.csv", "npz": "m.npz"}[fmt]
    export_motion(go1_motion, fmt, path, amp_full=full)
    if fmt == "amp-json":
        qpos, names, fps = read_amp_json(path)
        doc = json.loads(path.read_text())
        assert {"LoopMode", "FrameDuration", "EnableCycleOffsetPosition", "EnableCycleOffsetRotation", "MotionWeight", "Frames"} <= set(doc)
        assert len(doc["Frames"][0]) == (61 if full else 19)
        assert fps == pytest.approx(go1_motion.fps, rel=1e-4)
    elif fmt == "unitree-csv":
        qpos, names = read_unitree_csv(path), go1_motion.joint_names
        assert "," in path.read_text().splitlines()[0] and not path.read_text()[0].isalpha()  # no header
    else:
        back = RobotMotion.load(path)
        qpos, names = back.qpos, back.joint_names
    feet = fk_feet("go1", qpos, names)
    ref = fk_feet("go1", go1_motion.qpos, go1_motion.joint_names)
    assert np.abs(feet - ref).max() < 1e-3


def test_amp_full_frame_layout(tmp_path, go1_motion):
    """61 values as AMP_for_hardware's AMPLoader reads them: pybullet legs, base-frame toes, local velocities."""
    path = tmp_path / "m.json"
    export_motion(go1_motion, "amp-json", path, amp_full=True)
    doc = json.loads(path.read_text())
    f = np.array(doc["Frames"])
    assert doc["JointNames"][0].startswith("FR") and doc["JointNames"][3].startswith("FL")
    assert f[0, 20] < 0 < f[0, 23]  # first toe on the right (y < 0), second on the left
    dt = doc["FrameDuration"]
    rot = pin.Quaternion(f[3, 6], *f[3, 3:6]).toRotationMatrix()
    assert np.allclose(f[3, 31:34], rot.T @ (f[4, 0:3] - f[3, 0:3]) / dt, atol=1e-3)
    assert np.allclose(f[3, 37:49], (f[4, 7:19] - f[3, 7:19]) / dt, atol=1e-3)
    assert np.allclose(f[3, 49:61], (f[4, 19:31] - f[3, 19:31]) / dt, atol=1e-3)


def test_retarget_api_reports_progress_and_cancels():
    import threading

    from engine.retarget.quadruped.pipeline import RetargetCancelled

    seen: list[float] = []
    motion = retarget(synthetic_trot("a1", frames=40), "a1", "smr", progress=seen.append)
    assert seen[-1] == 1.0 and seen == sorted(seen) and motion.method == "smr" and motion.robot == "a1"
    cancel = threading.Event()
    cancel.set()
    with pytest.raises(RetargetCancelled):
        retarget(synthetic_trot("a1", frames=40), "a1", "smr", cancel=cancel)


def test_uvm_is_the_keypoint_ik_with_the_base_transferred():
    src = synthetic_trot("a1", frames=20)
    motion = retarget(src, "a1", "uvm")
    assert np.allclose(motion.qpos[:, :3], src.base_pos, atol=1e-9)  # base transferred directly
    assert np.abs(motion.keypoints - src.keypoints).max() < 2e-3  # a1 → a1: the same keypoints back
