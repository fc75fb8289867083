"""How well a tracked motion does: the TMR score C(α) (STMR Eq. 15) and the tracking figures of §VIII-C.

C(α) = −d_b − d_E + w_c · IoU − w_α · mean(log2 α)² − fall penalty, where d_b is the mean L1 distance of the
base position (m), d_E the mean L1 distance of the base Euler angles (rad, wrapped), IoU the contact IoU of the
rollout against the deformed schedule; the α term is the paper's "regularise extreme values of the temporal
parameters" (§VI) — it makes a motion that every α tracks equally well keep its timing.

A replay that falls (ours: the paper's score has none) is scored by how far it got, smoothly: its tracking terms
are measured over the frames *before* the fall only (what the robot did lying on the floor says nothing about α),
squashed to (−C, C) by C·tanh(·/C), and the penalty is P₀ + P₁ · (share of the motion left). So (i) a fall always
scores below a standing replay whose score is above C − P₀ (−0.75: mean errors of the order of a metre), (ii)
of two falls with the same pre-fall tracking the later one scores higher, and (iii) a fall more than 2C/P₁
(25 %) of the motion later scores higher whatever the tracking — among α that all fall the search climbs towards
the one that gets furthest, and the GP sees a score that varies with the fall time rather than a step.

``dtw_keypoint_l1_pct``: the keypoint trajectories aligned by dynamic time warping (so a re-timed motion is not
penalised for its timing), the mean per-keypoint L1 distance along the warping path as a percentage of the mean
keypoint path length of the reference (the paper's "normalised keypoint L1 distance with DTW"); NaN when the
reference hardly moves (mean keypoint path under 1 cm). It *is* ``engine.retarget.metrics.dtw_keypoint_l1_percent``:
one definition for UVM, SMR and STMR.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from engine.retarget.metrics import MIN_PATH_LENGTH_M, dtw_keypoint_l1_percent

FALL_PENALTY = 1.0  # P₀: any fall
FALL_PENALTY_PER_SHARE_LEFT = 2.0  # P₁: per share of the motion left after the fall
FALLEN_TRACKING_BOUND = 0.25  # C: a fallen replay's pre-fall tracking terms are squashed to (−C, C)
__all__ = ["MIN_PATH_LENGTH_M", "dtw_keypoint_l1_pct", "keypoint_l1_m", "tmr_score", "tracking_error_mm", "contact_iou"]


def _euler(quat_wxyz: np.ndarray) -> np.ndarray:
    q = np.asarray(quat_wxyz, dtype=float)
    return Rotation.from_quat(q[:, [1, 2, 3, 0]]).as_euler("xyz")


def base_position_l1_m(qpos: np.ndarray, qpos_ref: np.ndarray) -> float:
    return float(np.mean(np.sum(np.abs(qpos[:, 0:3] - qpos_ref[:, 0:3]), axis=1)))


def base_euler_l1_rad(qpos: np.ndarray, qpos_ref: np.ndarray) -> float:
    d = _euler(qpos[:, 3:7]) - _euler(qpos_ref[:, 3:7])
    d = (d + np.pi) % (2 * np.pi) - np.pi
    return float(np.mean(np.sum(np.abs(d), axis=1)))


def contact_iou(contact: np.ndarray, contact_ref: np.ndarray) -> float:
    a, b = np.asarray(contact, bool), np.asarray(contact_ref, bool)
    union = np.sum(a | b)
    return float(np.sum(a & b) / union) if union else 1.0


def tracking_error_mm(keypoints: np.ndarray, keypoints_ref: np.ndarray) -> float:
    """Mean Euclidean keypoint error per frame and keypoint (mm), time-aligned."""
    return float(np.mean(np.linalg.norm(keypoints - keypoints_ref, axis=-1)) * 1e3)


def keypoint_l1_m(keypoints: np.ndarray, keypoints_ref: np.ndarray) -> float:
    """Mean per-keypoint L1 distance (m), time-aligned."""
    return float(np.mean(np.sum(np.abs(np.asarray(keypoints) - np.asarray(keypoints_ref)), axis=-1)))


def tmr_score(qpos: np.ndarray, contact: np.ndarray, qpos_ref: np.ndarray, contact_ref: np.ndarray,
              log2_alpha: np.ndarray, fell: bool, w_contact: float = 0.2, w_alpha: float = 0.05,
              fall_fraction: float = 0.0, keypoints: np.ndarray | None = None,
              keypoints_ref: np.ndarray | None = None, w_keypoints: float = 0.0) -> dict:
    """``fall_fraction``: share of the motion done before the first fall (only used when ``fell``): the tracking
    terms are then measured over the frames up to the fall and the score is shaped as the module says.
    ``w_keypoints`` > 0 adds −w_k · d_k, d_k the mean per-keypoint L1 distance (m) of the rollout to the
    deformed target (ours: Eq. 15 scores the base only; the keypoints are what the DTW figure measures)."""
    f = float(np.clip(fall_fraction, 0.0, 1.0)) if fell else 1.0
    if fell:  # the frames up to the fall (at least the first two)
        n = min(len(qpos), max(2, int(round(f * (len(qpos) - 1))) + 1))
        qpos, contact, qpos_ref, contact_ref = qpos[:n], contact[:n], qpos_ref[:n], contact_ref[:n]
        if keypoints is not None and keypoints_ref is not None:
            keypoints, keypoints_ref = keypoints[:n], keypoints_ref[:n]
    d_b = base_position_l1_m(qpos, qpos_ref)
    d_e = base_euler_l1_rad(qpos, qpos_ref)
    d_k = keypoint_l1_m(keypoints, keypoints_ref) if keypoints is not None and keypoints_ref is not None else 0.0
    iou = contact_iou(contact, contact_ref)
    reg = float(np.mean(np.square(log2_alpha)))
    tracking = -d_b - d_e - w_keypoints * d_k + w_contact * iou - w_alpha * reg
    if fell:
        fall = FALL_PENALTY + FALL_PENALTY_PER_SHARE_LEFT * (1.0 - f)
        score = FALLEN_TRACKING_BOUND * float(np.tanh(tracking / FALLEN_TRACKING_BOUND)) - fall
    else:
        fall, score = 0.0, tracking
    return {"score": score, "d_b_m": d_b, "d_E_rad": d_e, "d_k_m": d_k, "contact_iou": iou,
            "alpha_penalty": w_alpha * reg, "fall_penalty": fall, "measured_share": f}


def dtw_keypoint_l1_pct(keypoints: np.ndarray, keypoints_ref: np.ndarray) -> float:
    """DTW-normalised keypoint L1 distance (%): ``engine.retarget.metrics.dtw_keypoint_l1_percent``, the one
    definition the spatial stage's figures use too."""
    return dtw_keypoint_l1_percent(keypoints, keypoints_ref)
