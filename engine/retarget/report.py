"""The figures a retargeting run reports (``studio retarget --json``, the bench, the studio's panel)."""

from __future__ import annotations

import numpy as np

from engine.retarget import metrics as M
from engine.retarget.motion import KeypointMotion
from engine.retarget.heightmap import HeightMap
from engine.retarget.quadruped.kinematics import quadruped_kinematics

DTW_MAX_FRAMES = 400


def summary(source: KeypointMotion, result, heightmap: HeightMap) -> dict:
    """``result`` is a RetargetOutput (motion, target keypoints, wall time)."""
    motion = result.motion
    kin = quadruped_kinematics(motion.robot)
    feet = motion.keypoints[:, 3::4]
    slide = M.foot_slide_mm(feet, source.contact, motion.fps)
    target = result.target_keypoints
    result_kp = motion.keypoints
    if motion.source.get("baseless"):
        # the target has no base motion by construction: compare the keypoints relative to the base
        hips_t = np.nanmean(target[:, 0::4], axis=1, keepdims=True)
        target = target - hips_t
        result_kp = result_kp - result_kp[:, 0::4].mean(axis=1, keepdims=True)
    step = max(1, int(np.ceil(len(target) / DTW_MAX_FRAMES)))
    enforced = motion.source.get("contact_enforced")
    figures = {
        "robot": motion.robot, "method": motion.method, "baseless": bool(motion.source.get("baseless")),
        "frames": motion.frames, "fps": motion.fps,
        "foot_slide_mm": None if slide["mean"] is None else round(slide["mean"], 4),
        "foot_slide_max_mm": None if slide["max"] is None else round(slide["max"], 4),
        "slide_segments": slide["segments"],
        "contact_iou": round(M.contact_iou(source.contact, motion.contact), 4),
        "penetration_mm": round(M.penetration_mm(feet, kin.foot_radius_m, heightmap), 3),
        "keypoint_error_mm": round(M.keypoint_error_mm(result_kp, target), 2),
        "dtw_keypoint_l1_percent": round(M.dtw_keypoint_l1_percent(result_kp[::step], target[::step]), 3),
        "travel_m": round(M.travel_distance_m(motion.base_pos), 4),
        "frames_per_s": round(motion.frames / max(result.wall_time_s, 1e-9), 1),
        "frames_per_cpu_s": round(motion.frames / max(result.cpu_time_s, 1e-9), 1),
        "wall_time_s": round(result.wall_time_s, 4),
    }
    for key in ("qp_failures", "joint_limit_relaxed", "flight_frames"):
        if key in motion.source:
            figures[key] = motion.source[key]
    if enforced is not None:
        figures["contact_iou_enforced"] = round(M.contact_iou(source.contact, np.array(enforced, dtype=bool)), 4)
    return figures
