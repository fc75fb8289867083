"""Contact schedules: estimated from foot height and speed, and their IoU.

``estimate_contacts`` (importers whose source has no labels): a foot is in contact when it is within
``height_m`` of the ground (the clip's lowest foot level, or a given height) and moves slower than
``speed_m_s`` horizontally; contact and swing segments shorter than ``min_segment_s`` are absorbed by their
neighbours, so one noisy frame never splits a stance.

``detect_stance``: the same two signals with hysteresis — a foot touches down below ``height_m`` and
``speed_fraction`` of the clip's swing speed, and lifts off only above ``release_height_m`` or
``release_speed_fraction`` of it — so a foot that slips a little at the edges of its stance is not cut into
flickers. Heights are above the clip's own ground level (a low percentile of all its feet); speeds are 3-D
(a foot still descending onto the ground has not touched down) and relative to the clip's swing speed (95th
percentile of foot speed), so a clip slowed down in time (the STMR clips: ×2.4) reads as at its real pace.

``clean_schedule`` (the schedule SMR follows, for every clip): a source's contact labels plus the frames its
feet are measured planted (``detect_stance``), then segments shorter than ``min_segment_s`` absorbed. Why: the
STMR mocap contact files under-label — trot0 marks its feet down 6–52 % of the frames, one foot down in 70 %
of them — while the feet stand still in diagonal pairs; the robot cannot balance the labelled schedule
(README, issue 10). Labels are only added to, never removed: an animator's complete schedule (hopturn) is
kept as it is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


#: The stance schedules SMR can follow (engine.retarget.quadruped.pipeline.RetargetOptions.contacts): the labels
#: plus the measured stance (``clean_schedule``), the measured stance alone (``detect_stance``), the labels as
#: they are.
CONTACT_SCHEDULES = ("cleaned", "detected", "source")


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
    vel = foot_speeds(feet, fps)
    contact = (height < thresholds.height_m) & (vel < thresholds.speed_m_s)
    return _absorb_short_segments(contact, thresholds.min_segment_s, fps)


@dataclass(frozen=True)
class StanceDetection:
    """Thresholds of ``detect_stance``: heights in metres above the clip's ground, speeds as fractions of
    its swing speed (never below ``min_swing_speed_m_s``, so a standing clip reads all stance)."""

    height_m: float = 0.05
    release_height_m: float = 0.07
    speed_fraction: float = 0.25
    release_speed_fraction: float = 0.4
    min_swing_speed_m_s: float = 0.2
    min_segment_s: float = 0.1
    ground_percentile: float = 5.0
    swing_speed_percentile: float = 95.0


def foot_speeds(feet: np.ndarray, fps: float, dims: int = 2) -> np.ndarray:
    """(T, F) foot speed (m/s), horizontal (``dims`` 2) or 3-D (3): the slower of the two neighbouring finite
    differences, so a planted foot is still on its first and last stance frames too."""
    feet = np.asarray(feet, dtype=float)
    vel = np.zeros(feet.shape[:2])
    if len(feet) > 1:
        d = np.linalg.norm(np.diff(feet[:, :, :dims], axis=0), axis=2) * fps
        vel[1:-1] = np.minimum(d[1:], d[:-1])
        vel[0], vel[-1] = d[0], d[-1]
    return vel


def detect_stance(feet: np.ndarray, fps: float, params: StanceDetection = StanceDetection()) -> np.ndarray:
    """(T, F) stance booleans from foot positions ``feet`` (T, F, 3), with hysteresis and a minimum
    segment length (interior segments shorter than ``min_segment_s`` are absorbed; see the module doc)."""
    feet = np.asarray(feet, dtype=float)
    if feet.ndim != 3 or feet.shape[2] != 3 or len(feet) == 0:
        raise ValueError(f"feet: expected (T, F, 3) positions with T ≥ 1, got shape {feet.shape}")
    if not np.all(np.isfinite(feet)):
        raise ValueError("feet: expected finite positions")
    z = feet[:, :, 2]
    height = z - float(np.percentile(z, params.ground_percentile))
    speed = foot_speeds(feet, fps, dims=3)
    swing = max(params.min_swing_speed_m_s, float(np.percentile(speed, params.swing_speed_percentile)))
    touch = (height < params.height_m) & (speed < params.speed_fraction * swing)
    hold = (height < params.release_height_m) & (speed < params.release_speed_fraction * swing)
    n_frames, n_feet = int(feet.shape[0]), int(feet.shape[1])
    contact = np.zeros((n_frames, n_feet), dtype=bool)
    state = np.zeros(n_feet, dtype=bool)
    for k in range(n_frames):
        state = np.where(state, hold[k], touch[k])
        contact[k] = state
    return _absorb_short_segments(contact, params.min_segment_s, fps)


def clean_schedule(labels: np.ndarray, feet: np.ndarray, fps: float,
                   params: StanceDetection = StanceDetection()) -> np.ndarray:
    """(T, F) schedule: ``labels`` (T, F) or-ed with the stance measured from ``feet`` (T, F, 3), interior
    segments shorter than ``params.min_segment_s`` absorbed (see the module doc)."""
    labels = np.asarray(labels, dtype=bool)
    detected = detect_stance(feet, fps, params)
    if labels.shape != detected.shape:
        raise ValueError(f"labels: expected shape {detected.shape} (frames, feet), got {labels.shape}")
    contact = labels | detected
    return _absorb_short_segments(contact, params.min_segment_s, fps)


def _absorb_short_segments(contact: np.ndarray, min_segment_s: float, fps: float) -> np.ndarray:
    """``contact`` (T, F) with each foot's interior segments shorter than ``min_segment_s`` absorbed (in place)."""
    n_min = max(1, int(round(min_segment_s * fps)))
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
