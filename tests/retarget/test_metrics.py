"""The paper's metrics on hand-made motions (§VIII-C/D/E)."""

from __future__ import annotations

import numpy as np

from engine.retarget.contacts import contact_iou, estimate_contacts
from engine.retarget.metrics import (detect_contacts, dtw_keypoint_l1_percent, foot_slide_mm, penetration_mm,
                                     recovery_rate_percent, travel_distance_m)
from engine.retarget.heightmap import Box, HeightMap


def test_foot_slide_counts_only_segments_longer_than_half_a_second():
    fps = 10.0
    feet = np.zeros((20, 1, 3))
    feet[:, 0, 0] = np.linspace(0, 0.019, 20)  # 1 mm per frame
    contact = np.zeros((20, 1), bool)
    contact[0:8, 0] = True  # 0.8 s: counted, L1 from frame 0 to 7 = 7 mm
    contact[10:14, 0] = True  # 0.4 s: not counted
    out = foot_slide_mm(feet, contact, fps)
    assert out["segments"] == 1 and abs(out["mean"] - 7.0) < 1e-9


def test_iou_penetration_and_detection():
    a = np.array([[1, 0], [1, 1], [0, 1]], bool)
    b = np.array([[1, 0], [0, 1], [0, 1]], bool)
    assert contact_iou(a, b) == 3 / 4 and contact_iou(a, a) == 1.0
    hm = HeightMap(0.0, (Box(1.0, 0.0, 0.5, 0.5, 0.1),))
    feet = np.array([[[0.0, 0.0, 0.02], [1.0, 0.0, 0.11]], [[0.0, 0.0, 0.05], [1.0, 0.0, 0.125]]])
    radius = np.array([0.02, 0.02])
    assert abs(penetration_mm(feet, radius, hm) - 10.0) < 1e-9  # second foot 1 cm into the box top
    assert detect_contacts(feet, radius, 10.0, hm).tolist() == [[True, True], [False, True]]


def test_estimated_contacts_absorb_short_blips():
    fps = 20.0
    z = np.r_[np.zeros(10), 0.05 * np.ones(10), np.zeros(10)]
    z[4] = 0.05  # a one-frame blip inside a stance
    feet = np.stack([np.zeros(30), np.zeros(30), z], axis=1)[:, None, :]
    c = estimate_contacts(feet, fps, 0.0)[:, 0]
    assert c[:10].all() and not c[10:20].any() and c[20:].all()


def test_dtw_is_zero_for_a_time_warped_copy_and_travel():
    t = np.linspace(0, 1, 40)
    traj = np.stack([np.stack([t, np.sin(3 * t), 0 * t], axis=1)] * 16, axis=1)
    warped = traj[np.r_[0, 0, 1:39, 39, 39]]  # same path, a few frames held
    assert dtw_keypoint_l1_percent(warped, traj) < 1e-9
    assert dtw_keypoint_l1_percent(traj + 0.01, traj) > 0
    base = np.stack([t, 0 * t, 0 * t], axis=1)
    assert abs(travel_distance_m(base) - 1.0) < 1e-12 and recovery_rate_percent(0.75, 1.0) == 75.0
