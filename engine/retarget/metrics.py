"""Retargeting metrics as STMR defines them (§VIII-C/D/E).

* foot slide (§VIII-D): for every contact segment longer than 0.5 s, the L1 distance of the foot position
  between the segment's first and last frame; reported as the mean (and max) over segments, in mm;
* contact IoU (§VIII-D): intersection over union of the source schedule and the result's contacts, the latter
  *detected* from the result's feet (foot sphere within 5 mm of the height map, or below it: a sliding foot
  is still a contact), so a method that does not keep the feet down is measured, not trusted;
* max penetration: deepest foot-sphere point below the height map, mm;
* keypoint error: mean Euclidean distance of the result's 16 keypoints to the retargeting target (the UVM
  keypoints of Eq. 1), mm;
* DTW-normalised keypoint L1 (§VIII-C): mean per-keypoint L1 distance between result and target keypoint
  trajectories after dynamic time warping, as a percentage of the target's mean keypoint path length (one
  definition for every method and stage: TMR's tracking figures use it too);
* travel distance and recovery rate (§VIII-E): horizontal base displacement, and baseless / with-base × 100.
"""

from __future__ import annotations

import numpy as np

from engine.retarget.contacts import contact_iou, segments
from engine.retarget.heightmap import HeightMap

MIN_SEGMENT_S = 0.5


def foot_slide_mm(feet: np.ndarray, contact: np.ndarray, fps: float, min_segment_s: float = MIN_SEGMENT_S) -> dict:
    slides = []
    for leg in range(contact.shape[1]):
        for start, end, value in segments(contact[:, leg]):
            if value and (end - start) / fps > min_segment_s:
                slides.append(float(np.abs(feet[end - 1, leg] - feet[start, leg]).sum()) * 1000.0)
    return {"mean": float(np.mean(slides)) if slides else None, "max": float(np.max(slides)) if slides else None,
            "segments": len(slides)}


def detect_contacts(feet: np.ndarray, radius_m: np.ndarray, fps: float, heightmap: HeightMap,
                    contact_height_m: float = 0.005) -> np.ndarray:
    """Contacts of a result motion, seen from its feet alone: the foot sphere on (or in) the height map."""
    ground = heightmap.heights(feet[:, :, :2]) + np.asarray(radius_m)[None, :]
    return feet[:, :, 2] - ground < contact_height_m


def penetration_mm(feet: np.ndarray, radius_m: np.ndarray, heightmap: HeightMap) -> float:
    ground = heightmap.heights(feet[:, :, :2])
    depth = ground - (feet[:, :, 2] - np.asarray(radius_m)[None, :])
    return max(0.0, float(depth.max()) * 1000.0)


def keypoint_error_mm(result: np.ndarray, target: np.ndarray) -> float:
    ok = np.all(np.isfinite(target), axis=-1)
    return float(np.linalg.norm(result - np.nan_to_num(target), axis=-1)[ok].mean()) * 1000.0


MIN_PATH_LENGTH_M = 0.01


def dtw_keypoint_l1_percent(result: np.ndarray, target: np.ndarray) -> float:
    """DTW-normalised keypoint L1 distance (%), the project's one definition (§VIII-C; every method, kinematic
    or tracked, is measured by this function).

    The two keypoint trajectories (T, K, 3) and (T', K, 3) — any frame rates — are aligned by dynamic time
    warping on the per-frame cost "mean over keypoints of the L1 distance"; the mean of that cost along the
    warping path (m) is divided by the mean Euclidean path length of the target's keypoints (m), × 100. Both
    terms are per keypoint and per frame, so the figure does not depend on the number of frames or keypoints
    (a 1 cm offset of a 1 m path reads 3 % at 20 fps and at 100 fps). Keypoints the target does not know (NaN in
    any frame) are left out; NaN when the target hardly moves (mean keypoint path under 1 cm)."""
    a = np.asarray(result, float).reshape(len(result), -1, 3)
    b = np.asarray(target, float).reshape(len(target), -1, 3)
    known = np.all(np.isfinite(b), axis=(0, 2))
    if not known.any():
        return float("nan")
    a, b = a[:, known], b[:, known]
    length = float(np.mean(np.sum(np.linalg.norm(np.diff(b, axis=0), axis=2), axis=0))) if len(b) > 1 else 0.0
    if length < MIN_PATH_LENGTH_M:
        return float("nan")  # a motion that hardly moves has no meaningful normalisation
    n, m = len(a), len(b)
    cost = np.empty((n, m))
    for i in range(n):  # row by row: (n, m, K, 3) at once is too large for long clips at 100 Hz
        cost[i] = np.mean(np.sum(np.abs(b - a[i]), axis=2), axis=1)
    rows = cost.tolist()
    inf = float("inf")
    prev = [0.0] + [inf] * m  # accumulated cost of row i-1 (index 0: the empty prefix)
    prev_steps = [0] * (m + 1)
    for i in range(n):
        row, row_steps = [inf] * (m + 1), [0] * (m + 1)
        ci = rows[i]
        for j in range(1, m + 1):
            diag, up, left = prev[j - 1], prev[j], row[j - 1]
            if diag <= up and diag <= left:
                best, st = diag, prev_steps[j - 1]
            elif up <= left:
                best, st = up, prev_steps[j]
            else:
                best, st = left, row_steps[j - 1]
            row[j] = ci[j - 1] + best
            row_steps[j] = st + 1
        prev, prev_steps = row, row_steps
        prev[0] = inf
    mean_l1 = prev[m] / max(prev_steps[m], 1)
    return float(100.0 * mean_l1 / length)


def travel_distance_m(base_pos: np.ndarray, axis: np.ndarray | None = None) -> float:
    d = base_pos[-1, :2] - base_pos[0, :2]
    return float(abs(d @ axis[:2])) if axis is not None else float(np.linalg.norm(d))


def recovery_rate_percent(baseless_m: float, with_base_m: float) -> float:
    return 100.0 * baseless_m / with_base_m if with_base_m > 1e-9 else float("nan")


__all__ = ["foot_slide_mm", "detect_contacts", "penetration_mm", "keypoint_error_mm", "dtw_keypoint_l1_percent",
           "travel_distance_m", "recovery_rate_percent", "contact_iou"]
