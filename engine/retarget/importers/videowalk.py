"""STMR's video keypoints (``videowalk{0,1}/raw.json``): thigh and foot of each leg per frame, no base.

``{"<frame>": {"FR_thigh": [x,y,z], …, "RL_foot": [x,y,z], "cam_R": 3×3, "cam_p": [x,y,z]}}``. The points are
body-relative (they do not travel) in the reconstruction's own units, x forward, z up; they are scaled to
metres by a nominal dog leg (thigh→foot 0.3 m on average) and placed with the lowest feet on z = 0. Hip and
knee keypoints are missing (``known`` false): the target's kinematics supply them (see UVM). The video's
frame rate is not in the file: 30 fps is assumed. Contacts are estimated; the clip is baseless by nature.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.retarget.contacts import ContactThresholds, estimate_contacts
from engine.retarget.importers import ImportFormatError, read_json
from engine.retarget.motion import LEGS, KeypointMotion

FPS = 30.0
LEG_LENGTH_M = 0.3


def import_videowalk(path: Path) -> KeypointMotion:
    data = read_json(path)
    name = path.name
    if not isinstance(data, dict) or not data:
        raise ImportFormatError(f"{name}: expected an object of frames {{\"0\": {{\"FR_thigh\": [x,y,z], …}}}}")
    try:
        keys = sorted(data, key=int)
    except ValueError:
        raise ImportFormatError(f"{name}: expected frame numbers as keys") from None
    if len(keys) < 2:
        raise ImportFormatError(f"{name}: expected at least 2 frames, got {len(keys)}")
    kp = np.zeros((len(keys), 16, 3))
    for t, key in enumerate(keys):
        frame = data[key]
        for leg_i, leg in enumerate(LEGS):
            for slot, part in ((1, "thigh"), (3, "foot")):
                value = frame.get(f"{leg}_{part}") if isinstance(frame, dict) else None
                try:
                    arr = np.asarray(value, dtype=float) if isinstance(value, list) else None
                except (TypeError, ValueError, OverflowError):  # text, nested lists, a 400-digit integer
                    arr = None
                if arr is None or arr.shape != (3,) or not np.all(np.isfinite(arr)):
                    raise ImportFormatError(f"{name}: {key}.{leg}_{part}: expected [x, y, z]")
                kp[t, 4 * leg_i + slot] = arr
    thigh, foot = kp[:, 1::4], kp[:, 3::4]
    scale = LEG_LENGTH_M / float(np.mean(np.linalg.norm(foot - thigh, axis=2)))
    kp *= scale
    kp[:, 0::4] = kp[:, 1::4]  # hips: at the thighs until the target supplies them
    kp[:, 2::4] = 0.5 * (kp[:, 1::4] + kp[:, 3::4])  # knees: placeholders, not used (known false)
    ground = float(np.percentile(kp[:, 3::4, 2], 2))
    kp[:, :, 2] -= ground
    # body-relative points: a planted foot moves backward at the walking speed, so height alone decides,
    # each foot against its own lowest level (monocular depth differs per foot)
    feet = kp[:, 3::4]
    contact = estimate_contacts(feet, FPS, np.percentile(feet[:, :, 2], 5, axis=0),
                                ContactThresholds(height_m=0.02, speed_m_s=np.inf, min_segment_s=0.1))
    known = np.tile([False, True, False, True], 4)
    return KeypointMotion(
        fps=FPS, keypoints=kp, contact=contact, known=known,
        source={"file": name, "format": "videowalk", "contact_from": "estimated", "scale_m_per_unit": scale,
                "fps_assumed": True, "baseless": True, "licence": "non-commercial test data (STMR_RL)"},
    )
