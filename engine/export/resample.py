"""Resampling a RobotMotion to another frame rate: lerp for positions and joints, slerp for the root.

Output frame ``k`` is at ``t_k = k / fps`` for every ``t_k`` within the recording's span
``[0, (T - 1) / fps_in]`` (as BeyondMimic's ``csv_to_npz`` does: the last output frame is at or
before the last input frame). Between input frames ``i`` and ``i + 1`` with blend ``b``:
positions and joints ``(1 - b) a + b c``, the root quaternion the shortest-arc slerp (w,x,y,z),
joint/base velocities lerped, contacts from the nearer input frame. Resampling to the same rate
returns the frames unchanged.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from engine.retarget.motion import RobotMotion

MAX_FPS = 1000.0


def check_fps(fps: float) -> float:
    """A usable output rate (0 < fps ≤ 1000) or ValueError naming ``--fps``."""
    try:
        value = float(fps)
    except (TypeError, ValueError):
        raise ValueError(f"--fps: expected a number of frames per second, got {fps!r}") from None
    if not math.isfinite(value) or value <= 0 or value > MAX_FPS:
        raise ValueError(f"--fps: expected 0 < fps ≤ {MAX_FPS:g}, got {fps}")
    return value


def sample_times(frames: int, fps_in: float, fps_out: float) -> np.ndarray:
    span = (frames - 1) / fps_in
    n = int(math.floor(span * fps_out + 1e-9)) + 1
    return np.arange(n) / fps_out


def frame_blend(times: np.ndarray, frames: int, fps_in: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(index_0, index_1, blend) of each time in a recording of ``frames`` frames at ``fps_in``."""
    x = np.clip(times * fps_in, 0.0, frames - 1)
    i0 = np.floor(x + 1e-9).astype(int)
    i0 = np.minimum(i0, frames - 1)
    i1 = np.minimum(i0 + 1, frames - 1)
    blend = np.clip(x - i0, 0.0, 1.0)
    return i0, i1, blend


def slerp(q0: np.ndarray, q1: np.ndarray, blend: np.ndarray) -> np.ndarray:
    """Row-wise shortest-arc slerp of unit quaternions (any component order; w,x,y,z here)."""
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float).copy()
    dot = np.sum(q0 * q1, axis=1)
    q1[dot < 0] *= -1.0
    dot = np.abs(dot)
    b = np.asarray(blend, dtype=float)[:, None]
    theta = np.arccos(np.clip(dot, -1.0, 1.0))[:, None]
    sin = np.sin(theta)
    small = sin[:, 0] < 1e-8
    w0 = np.where(small[:, None], 1.0 - b, np.sin((1.0 - b) * theta) / np.where(small[:, None], 1.0, sin))
    w1 = np.where(small[:, None], b, np.sin(b * theta) / np.where(small[:, None], 1.0, sin))
    out = w0 * q0 + w1 * q1
    return out / np.linalg.norm(out, axis=1, keepdims=True)


def resample(motion: RobotMotion, fps: float) -> RobotMotion:
    fps = check_fps(fps)
    if abs(fps - motion.fps) < 1e-9:
        return motion
    times = sample_times(motion.frames, motion.fps, fps)
    i0, i1, b = frame_blend(times, motion.frames, motion.fps)

    def lerp(x: np.ndarray) -> np.ndarray:
        bb = b.reshape((-1,) + (1,) * (x.ndim - 1))
        return (1.0 - bb) * x[i0] + bb * x[i1]

    def lerp_optional(x: np.ndarray | None) -> np.ndarray | None:
        return None if x is None else lerp(x)

    q = motion.qpos
    qpos = (1.0 - b[:, None]) * q[i0] + b[:, None] * q[i1]
    qpos[:, 3:7] = slerp(q[i0, 3:7], q[i1, 3:7], b)
    nearest = np.where(b < 0.5, i0, i1)
    return dataclasses.replace(
        motion, fps=fps, qpos=qpos, contact=motion.contact[nearest], keypoints=lerp_optional(motion.keypoints),
        qvel=lerp_optional(motion.qvel), ctrl=lerp_optional(motion.ctrl),
        source={**motion.source, "resampled_from_fps": motion.fps},
    )
