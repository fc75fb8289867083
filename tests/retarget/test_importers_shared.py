"""Importers on the shared source clips (skipped when ../shared is absent): layouts and leg-order traps
checked numerically, contact estimates against the STMR contact files, flights and boxes on real clips."""

from __future__ import annotations

import numpy as np
import pytest

from engine.retarget.contacts import contact_iou, estimate_contacts
from engine.retarget.importers import detect_format, import_source
from engine.retarget.motion import LEGS
from engine.retarget.heightmap import Box, HeightMap
from engine.retarget.quadruped.pipeline import RetargetOptions, retarget_detailed
from engine.retarget.report import summary
from tests.retarget.shared import shared_file, stmr_clip


def left_of_body(m) -> np.ndarray:
    """Per leg: fraction of frames with the hip on the body's left (y in the heading frame > 0)."""
    hips = m.keypoints[:, 0::4]
    centre = hips.mean(axis=1, keepdims=True)
    fwd = hips[:, :2].mean(axis=1) - hips[:, 2:].mean(axis=1)
    left = np.cross([0.0, 0.0, 1.0], fwd)
    return (np.einsum("tlk,tk->tl", hips - centre, left) > 0).mean(axis=0)


@pytest.mark.parametrize("clip", ["trot0", "trot1", "pace0", "pace1", "sidesteps", "hopturn"])
def test_stmr_keypoints_legs_and_contacts(clip):
    m = import_source(stmr_clip(clip))
    assert m.keypoint_names[0] == "FL_hip" and m.foot_names == list(LEGS)
    assert np.allclose(left_of_body(m), [1, 0, 1, 0])  # FL, FR, RL, RR: left, right, left, right
    feet_z = m.feet[:, :, 2]
    assert feet_z[m.contact].mean() < feet_z[~m.contact].mean()  # labelled contacts are the low feet
    est = estimate_contacts(m.feet, m.fps)
    assert contact_iou(est, m.contact) > 0.3


def test_stmr_raw_trot_is_the_amp_clip_with_legs_swapped():
    """PROVENANCE's trap, measured: the AMP 61-value file's toes say FR first; the STMR raw trot is FL first."""
    amp = import_source(shared_file("stmr_rl", "datasets", "trot0", "trot0_raw_FL.txt"))
    raw = import_source(shared_file("stmr_rl", "datasets", "trot0", "trot0_raw.txt"))
    assert amp.source["leg_order"] == "FR,FL,RR,RL" and "toe" in amp.source["leg_order_from"]
    assert raw.source["leg_order"] == "FL,FR,RL,RR"
    assert np.abs(amp.keypoints - raw.keypoints).max() < 1e-6  # the same physical motion


def test_amp_for_hardware_and_hopturn_frames():
    m = import_source(shared_file("amp_for_hardware", "datasets", "mocap_motions", "pace1.txt"))
    assert m.frames == 492 and m.fps == pytest.approx(1 / 0.021, rel=1e-4)
    assert np.allclose(left_of_body(m), [1, 0, 1, 0])


def test_dog_keypoints_and_videowalk():
    dog = import_source(shared_file("motion_imitation", "retarget_keypoints", "dog_trot_joint_pos.txt"))
    assert dog.frames == 33 and dog.fps == 60.0 and np.allclose(left_of_body(dog), [1, 0, 1, 0])
    assert 0.2 < dog.keypoints[:, 0::4, 2].mean() < 0.6  # Z up: hips above the feet
    video = import_source(shared_file("stmr_rl", "datasets", "videowalk1", "raw.json"))
    assert video.frames == 27 and not video.known[0] and video.known[3]
    motion = retarget_detailed(video, "go1", "smr", RetargetOptions(baseless=True)).motion
    assert motion.frames == 27 and np.isfinite(motion.qpos).all()


def test_format_detection():
    assert detect_format(stmr_clip("trot0")) == "stmr-keypoints"
    assert detect_format(shared_file("motion_imitation", "motions", "dog_pace.txt")) == "motion-imitation"
    assert detect_format(shared_file("mann_dog_bvh", "D1_007_KAN01_001.bvh")) == "dog-bvh"


def test_hopturn_flight_is_ballistic():
    src = import_source(stmr_clip("hopturn"))
    motion = retarget_detailed(src, "go1", "smr").motion
    enforced = np.array(motion.source["contact_enforced"], dtype=bool)
    flight = ~enforced.any(axis=1)
    z = motion.qpos[:, 2]
    acc = (z[2:] - 2 * z[1:-1] + z[:-2]) * motion.fps ** 2
    inside = flight[2:] & flight[1:-1] & flight[:-2]
    assert inside.sum() >= 5
    assert np.abs(acc[inside] + 9.81).max() < 0.5


def test_box_in_the_path_feet_land_on_top():
    src = import_source(stmr_clip("pace0"))
    box = Box(0.45, 0.0, 0.3, 0.8, 0.05)
    hm = HeightMap(0.0, (box,))
    out = retarget_detailed(src, "go1", "smr", RetargetOptions(heightmap=hm))
    figures = summary(src, out, hm)
    assert figures["penetration_mm"] == 0.0
    feet = out.motion.keypoints[:, 3::4]
    enforced = np.array(out.motion.source["contact_enforced"], dtype=bool)
    on_box = np.array([[box.contains(*feet[t, leg, :2]) for leg in range(4)] for t in range(len(feet))]) & enforced
    assert on_box.sum() > 5  # some stance feet stand on the box ...
    assert np.allclose(feet[on_box][:, 2], 0.05 + 0.02, atol=1e-4)  # ... on its top


def test_dog_bvh_fk_matches_the_keypoint_file():
    """Our dog-BVH FK reproduces motion_imitation's 27 points of the same clip (D1_007 = dog_walk00)."""
    from engine.retarget.importers.dog_bvh import forward_kinematics, parse_bvh
    from engine.retarget.importers.dog_keypoints import read_rows

    bvh = parse_bvh(shared_file("mann_dog_bvh", "D1_007_KAN01_001.bvh"))
    points = forward_kinematics(bvh) * 0.01
    points[:, :, [0, 2]] -= points[0, 0, [0, 2]]  # the keypoint file starts at the root's ground position
    ref = read_rows(shared_file("motion_imitation", "retarget_keypoints", "dog_walk00_joint_pos.txt"), 81).reshape(-1, 27, 3)
    assert np.abs(points - ref).max() < 1e-4
    m = import_source(shared_file("mann_dog_bvh", "D1_007_KAN01_001.bvh"))
    assert m.frames == 593 and m.fps == pytest.approx(60.0, rel=1e-3) and np.allclose(left_of_body(m), [1, 0, 1, 0])


def test_dog_bvh_with_a_missing_joint_is_one_line(tmp_path, capsys):
    from studio.cli import main

    text = shared_file("mann_dog_bvh", "D1_007_KAN01_001.bvh").read_text().replace("JOINT LeftForeArm", "JOINT LeftForeArmX")
    (tmp_path / "dog.bvh").write_text(text)
    code = main(["import", str(tmp_path / "dog.bvh"), "--out", str(tmp_path / "dog.npz")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "dog.bvh" in err[0] and "'LeftForeArm' is missing" in err[0]
    assert not (tmp_path / "dog.npz").exists()


@pytest.mark.parametrize("clip", ["sidesteps.txt", "hopturn.txt", "dog_pace.txt", "dog_backwards_trot.txt"])
def test_laikago_clips(clip):
    """Peng's Laikago frames: toes on the ground when standing, left legs on the left, same gait as STMR's A1 copy."""
    m = import_source(shared_file("motion_imitation", "motions", clip))
    assert np.allclose(left_of_body(m), [1, 0, 1, 0])
    assert m.source["robot"].startswith("laikago") and m.contact.mean() > 0.3
    if clip == "sidesteps.txt":  # the same animation as STMR's sidesteps (A1): foot lifts correlate leg for leg
        a1 = import_source(stmr_clip("sidesteps"))
        corr = np.corrcoef(m.feet[:, :, 2].T, a1.feet[:, :, 2].T)[:4, 4:]
        assert (np.diag(corr) > 0.95).all()


DOG_CLIPS = {  # frames per PROVENANCE.md (mann_dog_bvh, motion_imitation/retarget_keypoints)
    ("mann_dog_bvh", "D1_001_KAN01_001.bvh"): 1531, ("mann_dog_bvh", "D1_007_KAN01_001.bvh"): 593,
    ("mann_dog_bvh", "D1_009_KAN01_001.bvh"): 548, ("mann_dog_bvh", "D1_010_KAN01_001.bvh"): 567,
    ("mann_dog_bvh", "D1_047_KAN01_001.bvh"): 1079, ("mann_dog_bvh", "D1_ex04_KAN02_002.bvh"): 505,
    ("retarget_keypoints", "dog_pace_joint_pos.txt"): 39, ("retarget_keypoints", "dog_trot_joint_pos.txt"): 33,
    ("retarget_keypoints", "dog_walk00_joint_pos.txt"): 593, ("retarget_keypoints", "dog_walk03_joint_pos.txt"): 548,
    ("retarget_keypoints", "dog_run00_joint_pos.txt"): 567, ("retarget_keypoints", "dog_run04_joint_pos.txt"): 1263,
}


@pytest.mark.parametrize("folder, name", list(DOG_CLIPS), ids=[n for _, n in DOG_CLIPS])
def test_every_shared_dog_clip_imports(folder, name):
    """The strict dog readers (issue 14: bounded, one-line errors) still read every shared dog clip, legs where
    they belong."""
    path = shared_file(*(("motion_imitation", folder, name) if folder == "retarget_keypoints" else (folder, name)))
    m = import_source(path)
    assert m.frames == DOG_CLIPS[(folder, name)] and m.fps == pytest.approx(60.0, rel=1e-3)
    assert m.source["format"] == ("dog-bvh" if name.endswith(".bvh") else "dog-keypoints")
    assert np.allclose(left_of_body(m), [1, 0, 1, 0], atol=0.05)
