"""Dog keypoint clips (motion_imitation ``retarget_keypoints/dog_*_joint_pos.txt``): 27 points per frame.

Comma(+tab)-separated rows of 81 numbers = 27 points × (x, y, z) in metres, **Y up**, 60 fps — the MANN
dog skeleton's 21 joints + 6 end sites in BVH depth-first order (see PROVENANCE.md). Rotated to Z up by
+90° about x (as motion_imitation's REF_COORD_ROT). The robot's four keypoints per leg map to:

* front legs: hip = thigh = shoulder joint (LeftArm 7 / RightArm 12; the robot's lateral hip link has no dog
  counterpart, so the zero-length hip→thigh vector takes the robot's own direction), knee = elbow
  (ForeArm 8 / 13), foot = paw end site (10 / 15);
* hind legs: hip = thigh = hip joint (UpLeg 16 / 20), knee = stifle (Leg 17 / 21), foot = paw end (19 / 23).

No contact schedule in the source: estimated from foot height and speed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.retarget.contacts import estimate_contacts
from engine.retarget.importers import ImportFormatError
from engine.retarget.motion import KeypointMotion

FPS = 60.0
# (hip, thigh, knee, foot) point indices per leg FL, FR, RL, RR
POINTS = ((7, 7, 8, 10), (12, 12, 13, 15), (16, 16, 17, 19), (20, 20, 21, 23))
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def read_rows(path: Path, width: int) -> np.ndarray:
    rows = []
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ImportFormatError(f"{path.name}: expected comma-separated numbers (text)") from None
    for i, line in enumerate(text.splitlines()):
        if not line.strip():
            continue
        cells = [c.strip() for c in line.replace("\t", ",").split(",") if c.strip()]
        if len(cells) != width:
            raise ImportFormatError(f"{path.name}: line {i + 1}: expected {width} numbers, got {len(cells)}")
        try:
            row = [float(c) for c in cells]
        except ValueError:
            bad = next(c for c in cells if not _is_number(c))
            raise ImportFormatError(f"{path.name}: line {i + 1}: expected numbers, got {bad!r}") from None
        if not all(np.isfinite(row)):
            raise ImportFormatError(f"{path.name}: line {i + 1}: expected finite numbers")
        rows.append(row)
    if len(rows) < 2:
        raise ImportFormatError(f"{path.name}: expected at least 2 frames, got {len(rows)}")
    return np.array(rows)


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def keypoints_from_points(points: np.ndarray) -> np.ndarray:
    """(T, 27, 3) Z-up dog points → (T, 16, 3) keypoints, legs FL, FR, RL, RR."""
    return np.stack([points[:, idx] for leg in POINTS for idx in leg], axis=1)


def import_dog_keypoints(path: Path) -> KeypointMotion:
    rows = read_rows(path, 81)
    points = rows.reshape(len(rows), 27, 3) @ Y_UP_TO_Z_UP.T
    kp = keypoints_from_points(points)
    feet = kp[:, 3::4]
    ground = float(np.percentile(feet[:, :, 2], 2))
    kp[:, :, 2] -= ground
    contact = estimate_contacts(kp[:, 3::4], FPS, 0.0)
    known = np.ones(16, dtype=bool)
    return KeypointMotion(
        fps=FPS, keypoints=kp, contact=contact, known=known,
        source={"file": path.name, "format": "dog-keypoints", "contact_from": "estimated", "ground_shift_m": -ground,
                "licence": "CC BY-NC 4.0 (MANN dog mocap): test data only"},
    )
