"""BVH reader: hierarchy, channel conventions (checked with scipy's Euler angles), one-line errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from engine.retarget.humanoid_arm import sources
from engine.retarget.humanoid_arm.pose15 import bvh_points, check_pose15, pose15_from_bvh
from engine.retarget.importers.bvh import BvhError, load_bvh, parse_bvh

TINY = """HIERARCHY
ROOT Hips
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Chest
  {
    OFFSET 0 10 0
    CHANNELS 3 Zrotation Yrotation Xrotation
    End Site
    {
      OFFSET 0 5 0
    }
  }
  JOINT Leg
  {
    OFFSET 2 -1 0
    CHANNELS 3 Xrotation Yrotation Zrotation
  }
}
MOTION
Frames: 2
Frame Time: 0.04
1 2 3 10 20 30 40 50 60 70 80 90
0 0 0 0 0 0 0 0 0 0 0 0
"""


def _fk_reference(motion, frame: int):
    """Independent forward kinematics with scipy (intrinsic Euler in channel order)."""
    out = {}
    for ji, j in enumerate(motion.joints):
        vals = motion.values[frame, j.channel_start:j.channel_start + len(j.channels)]
        rot_axes = "".join(c[0] for c, v in zip(j.channels, vals) if c.endswith("rotation"))
        rot_vals = [v for c, v in zip(j.channels, vals) if c.endswith("rotation")]
        local_r = Rotation.from_euler(rot_axes.upper(), rot_vals, degrees=True) if rot_axes else Rotation.identity()
        pos_ch = {c[0]: v for c, v in zip(j.channels, vals) if c.endswith("position")}
        t = j.offset.copy() if not pos_ch else np.array([pos_ch["X"], pos_ch["Y"], pos_ch["Z"]])
        if j.parent < 0:
            out[ji] = (local_r, t)
        else:
            pr, pt = out[j.parent]
            out[ji] = (pr * local_r, pt + pr.apply(t))
    return out


def test_tiny_file_matches_scipy_forward_kinematics():
    m = parse_bvh(TINY, "tiny.bvh")
    assert m.joint_names == ["Hips", "Chest", "Chest_End", "Leg"]
    assert [j.parent for j in m.joints] == [-1, 0, 1, 0]
    assert m.n_frames == 2 and m.fps == pytest.approx(25.0)
    pos, rot = m.global_poses()
    ref = _fk_reference(m, 0)
    for ji in range(4):
        np.testing.assert_allclose(pos[0, ji], ref[ji][1], atol=1e-9)
        np.testing.assert_allclose(rot[0, ji], ref[ji][0].as_matrix(), atol=1e-9)
    np.testing.assert_allclose(pos[1, 2], [0, 15, 0])


@pytest.mark.parametrize("text, expected", [
    (TINY[: TINY.index("0 0 0 0 0 0 0")], "truncated"),
    (TINY.replace("JOINT Chest", "JOINT").replace("{\n    OFFSET 0 10 0", "{\n    OFFSET 0 10 0"), "expected"),
    (TINY.replace("Frame Time: 0.04", "Frame Time: 0"), "Frame Time"),
    (TINY.replace("70 80 90", "70 nan 90"), "finite"),
    (TINY.replace("CHANNELS 3 Zrotation", "CHANNELS 3 Qrotation"), "CHANNELS"),
    ("", "HIERARCHY"),
])
def test_malformed_files_give_one_line_errors(text, expected):
    with pytest.raises(BvhError) as err:
        parse_bvh(text, "bad.bvh")
    msg = str(err.value)
    assert "\n" not in msg and msg.startswith("bad.bvh:") and expected.lower() in msg.lower()


def test_missing_arm_joints_is_one_line():
    m = parse_bvh(TINY, "noarms.bvh")
    with pytest.raises(BvhError, match="no arm joints") as err:
        pose15_from_bvh(m)
    assert "\n" not in str(err.value)


def _shared_clips():
    root = sources.shared_dir()
    if root is None:
        pytest.skip("shared data folder absent (set MOTION_STUDIO_SHARED)")
    clips = [root / "mocap-src/cmu/131_01.bvh", root / "mocap-src/cmu/141_16.bvh",
             root / "mocap-src/bandai_namco_dataset1/dataset-1_bye_normal_001.bvh"]
    if not all(c.is_file() for c in clips):
        pytest.skip("mocap clips absent from the shared folder")
    return clips


def test_shared_clips_parse_and_match_reference_kinematics():
    for path in _shared_clips():
        m = load_bvh(path)
        pos, rot = m.global_poses()
        for frame in (0, m.n_frames // 2, m.n_frames - 1):
            ref = _fk_reference(m, frame)
            for ji in range(len(m.joints)):
                np.testing.assert_allclose(pos[frame, ji], ref[ji][1], atol=1e-6 * max(1.0, np.abs(ref[ji][1]).max()))
        # y-up sources: the head is above the hips in every frame
        head = m.index("Head")
        hips = m.index("Hips")
        assert np.all(pos[:, head, 1] > pos[:, hips, 1])


def test_pose15_of_shared_clips_is_unit_and_upright():
    expected = {"131_01.bvh": "cmu-3dsmax", "141_16.bvh": "cmu-motionbuilder", "dataset-1_bye_normal_001.bvh": "bandai-namco"}
    for path in _shared_clips():
        pts = bvh_points(load_bvh(path))
        assert pts.skeleton == expected[path.name]
        p15 = check_pose15(pts.pose15(), path.name)
        spine = p15[:, 0:3]
        assert np.median(spine[:, 2]) > 0.9  # hip→neck points up in the body frame
        # the right shoulder is on the body's right (−y): right shoulder→left shoulder goes +y
        d = pts.shoulder[:, 1] - pts.shoulder[:, 0]
        local = np.einsum("fji,fj->fi", pts.frame, d)
        assert np.all(local[:, 1] > 0)
