"""Contact schedules: estimated from foot height and speed when a source has none, and their IoU.

A foot is in contact when it is within ``height_m`` of the ground (the clip's lowest foot level, or a
given height) and moves slower than ``speed_m_s`` horizontally; contact and swing segments shorter than
``min_segment_s`` are absorbed by their neighbours, so one noisy frame never splits a stance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ContactThresholds:
    height_m: float = 0.03
    speed_m_s: float = 0.6
    min_segment_s: float = 0.1


def estimate_contacts(feet: np.ndarray, fps: float, ground_z_m: float | np.ndarray | None = None,
                      thresholds: ContactThresholds = ContactThresholds()) -> np.ndarray:
    """(T, F) contact booleans from foot positions ``feet`` (T, F, 3)."""
    feet = np.asarray(feet, dtype=float)
    z = feet[:, :, 2]
    if ground_z_m is None:
        ground_z_m = float(np.percentile(z, 2))
    height = z - ground_z_m
    vel = np.zeros(z.shape)
    if len(feet) > 1:
        # a planted foot is still with respect to at least one neighbouring frame (its first and last stance frames too)
        d = np.linalg.norm(np.diff(feet[:, :, :2], axis=0), axis=2) * fps
        vel[1:-1] = np.minimum(d[1:], d[:-1])
        vel[0], vel[-1] = d[0], d[-1]
    contact = (height < thresholds.height_m) & (vel < thresholds.speed_m_s)
    n_min = max(1, int(round(thresholds.min_segment_s * fps)))
    for j in range(contact.shape[1]):
        contact[:, j] = _absorb_short(contact[:, j], n_min)
    return contact


def _absorb_short(c: np.ndarray, n_min: int) -> np.ndarray:
    """Flip interior segments shorter than n_min (swing gaps first, then contact blips)."""
    c = c.copy()
    for value in (False, True):
        for start, end, v in segments(c):
            if v == value and end - start < n_min and start > 0 and end < len(c):
                c[start:end] = not value
    return c


def segments(c: np.ndarray) -> list[tuple[int, int, bool]]:
    """Runs of equal values: (start, end exclusive, value)."""
    c = np.asarray(c, dtype=bool)
    if len(c) == 0:
        return []
    edges = np.flatnonzero(np.diff(c.astype(np.int8))) + 1
    starts = np.concatenate(([0], edges))
    ends = np.concatenate((edges, [len(c)]))
    return [(int(s), int(e), bool(c[s])) for s, e in zip(starts, ends)]


def contact_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two contact schedules (T, F); 1.0 when both are empty."""
    a = np.asarray(a, dtype=bool)
    b = np.asarray(b, dtype=bool)
    union = np.logical_or(a, b).sum()
    return 1.0 if union == 0 else float(np.logical_and(a, b).sum() / union)
