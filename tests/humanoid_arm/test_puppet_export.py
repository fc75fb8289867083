"""The Puppeteer's export: a recorded span of LWL2 outputs as a robot-motion/1 file that the project's readers
(RobotMotion, `studio export`'s formats) read, every frame one of the recorded outputs, checked by the capsules."""

from __future__ import annotations

import numpy as np
import pytest

from engine.retarget.humanoid_arm.capsules import CapsuleModel
from engine.retarget.humanoid_arm.puppet_export import METHOD, puppet_motion, save_puppet_motion
from engine.retarget.humanoid_arm.upper_body import UpperBody
from engine.retarget.motion import RobotMotion


@pytest.fixture(scope="module")
def g1_capsules():
    return CapsuleModel(UpperBody("g1"))


def _span(cm: CapsuleModel, n: int = 25):
    """Irregular times (like telemetry) and collision-free driven poses near standing."""
    rng = np.random.default_rng(4)
    t = 3.0 + np.cumsum(rng.uniform(0.01, 0.06, n))
    q = np.array([cm.fix(cm.ub.neutral() + rng.normal(0, 0.1, cm.ub.n))[0] for _ in range(n)])
    return t, q, rng.normal(size=(n, 15))


def test_an_exported_span_is_a_robot_motion_of_the_recorded_outputs(tmp_path, g1_capsules):
    cm = g1_capsules
    t, q, pose15 = _span(cm)
    path = tmp_path / "take.npz"
    summary = save_puppet_motion(path, "g1", t, q, pose15, 30.0, {"source": "clip", "clip": "x.bvh"}, cm)
    motion = RobotMotion.load(path)
    assert motion.robot == "g1" and motion.method == METHOD and motion.fps == 30.0
    assert motion.frames == summary["frames"] == int(np.floor((t[-1] - t[0]) * 30 + 1e-9)) + 1
    assert motion.source["clip"] == "x.bvh"
    with np.load(path, allow_pickle=False) as f:
        arm_q, grid, names = f["arm_q"], f["t"], [str(n) for n in f["arm_joint_names"]]
        assert f["pose15"].shape == (motion.frames, 15) and f["collision_free"].all()
    assert names == cm.ub.joint_names
    # every frame is the latest recorded output at or before its instant (held, never interpolated)
    for k, tk in enumerate(t[0] + grid):
        latest = np.flatnonzero(t <= tk + 1e-9)[-1]
        np.testing.assert_array_equal(arm_q[k], q[latest])
    # the qpos carries them on the driven joints, the standing robot elsewhere
    cols = [motion.joint_names.index(j) for j in names]
    np.testing.assert_allclose(motion.joints[:, cols], arm_q)
    standing = cm.ub.model.mj_standing_qpos()
    np.testing.assert_allclose(motion.qpos[:, 0:7], np.broadcast_to(standing[0:7], (motion.frames, 7)))
    assert summary["collision_free_fraction"] == 1.0


def test_an_exported_span_converts_to_the_learning_formats(tmp_path, g1_capsules):
    from engine.export import export_motion

    t, q, _ = _span(g1_capsules, 12)
    path = tmp_path / "take.npz"
    save_puppet_motion(path, "g1", t, q, capsules=g1_capsules)
    export_motion(RobotMotion.load(path), "unitree-csv", tmp_path / "take.csv")
    rows = np.loadtxt(tmp_path / "take.csv", delimiter=",")
    assert len(rows) == RobotMotion.load(path).frames


@pytest.mark.parametrize("change, message", [
    (lambda t, q: (t[:1], q[:1]), "at least 2 samples"),
    (lambda t, q: (t[::-1], q), "increasing times"),
    (lambda t, q: (t, q[:, :3]), "driven joint angles"),
    (lambda t, q: (t, np.where(np.arange(q.shape[1]) == 2, np.nan, q)), "finite"),
])
def test_a_bad_span_is_refused_in_one_line(change, message, g1_capsules, tmp_path):
    t, q, _ = _span(g1_capsules, 5)
    with pytest.raises(ValueError, match=message) as err:
        puppet_motion("g1", *change(t, q), capsules=g1_capsules)
    assert "\n" not in str(err.value)
