"""A recorded puppet span as a robot motion file (the Puppeteer workspace's *Export*).

The studio records LWL2's outputs (driven joint angles at the simulated instants the telemetry carried them,
with the source's 15-d poses). :func:`puppet_motion` turns that span into a ``robot-motion/1``
(engine/retarget/motion.py) at ``fps``: the robot standing in its standing pose (base, legs; wrists at zero
like LWL2's capsule model) with the driven joints at LWL2's output — the kinematic retargeting result, like
``studio puppet --out``. Every frame is one of LWL2's outputs held until the next one arrived (no
interpolation between them, which the capsules never checked), and is checked again by the capsules
(``collision_free``, ``min_capsule_distance_m``). Every reader of robot motions reads it (``studio export``
to Unitree CSV / BeyondMimic / AMP JSON, the Retarget tab's viewer); beside the RobotMotion keys the file
carries ``studio puppet``'s own: ``t`` (s), ``arm_joint_names`` (K), ``arm_q`` (T, K) rad, ``pose15`` (T, 15).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.retarget.humanoid_arm.capsules import CapsuleModel
from engine.retarget.humanoid_arm.upper_body import UpperBody
from engine.retarget.motion import RobotMotion, _write_npz

EXPORT_FPS = 30.0
METHOD = "lwl2-puppet"
FOOT_NAMES = ("left", "right")


def _span(t_s: np.ndarray, q: np.ndarray, n_joints: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.asarray(t_s, dtype=float).ravel()
    x = np.asarray(q, dtype=float)
    if x.ndim != 2 or x.shape[1] != n_joints or len(x) != len(t):
        raise ValueError(f"q: expected ({len(t)}, {n_joints}) driven joint angles, got {x.shape}")
    if len(t) < 2:
        raise ValueError(f"t: expected a span of at least 2 samples, got {len(t)}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(x))):
        raise ValueError("q: expected finite numbers")
    if np.any(np.diff(t) <= 0):
        raise ValueError("t: expected increasing times")
    return t, x


def puppet_motion(robot: str, t_s: np.ndarray, q: np.ndarray, pose15: np.ndarray | None = None,
                  fps: float = EXPORT_FPS, source: dict | None = None,
                  capsules: CapsuleModel | None = None) -> tuple[RobotMotion, dict[str, np.ndarray]]:
    """The span (``t_s`` (N,) simulated s, ``q`` (N, K) LWL2's driven joints, ``pose15`` (N, 15) or None) as a
    RobotMotion at ``fps`` and the extra arrays written beside it. ValueError (one line) on a bad span."""
    cm = capsules if capsules is not None and capsules.ub.model.name == robot else CapsuleModel(UpperBody(robot))
    ub = cm.ub
    t, x = _span(t_s, q, ub.n)
    if not 0 < fps <= 1000:
        raise ValueError(f"fps: expected 0 < fps ≤ 1000, got {fps}")
    frames = int(np.floor((t[-1] - t[0]) * fps + 1e-9)) + 1
    grid = t[0] + np.arange(frames) / fps
    idx = np.searchsorted(t, grid + 1e-9, side="right") - 1  # the latest output at or before each frame
    arm_q = x[idx]
    model = ub.model
    base = ub.q_base.copy()
    base[0:7] = model.q_standing[0:7]  # the standing base (height, orientation)
    qpos = np.empty((frames, model.mj_model.nq))
    for k, xk in enumerate(arm_q):
        base[ub.q_index] = xk
        qpos[k] = model.mj_qpos_from_pin(base)
    from engine.walk_recording import mujoco_joint_names

    dist = np.array([cm.min_signed_distance(xk) for xk in arm_q])
    free = dist >= 0.0
    metrics = {"frames": frames, "duration_s": round(frames / fps, 3),
               "collision_free_fraction": round(float(free.mean()), 4),
               "min_capsule_distance_mm": round(float(dist.min()) * 1000, 1)}
    motion = RobotMotion(fps=fps, qpos=qpos, joint_names=mujoco_joint_names(model),
                         contact=np.ones((frames, len(FOOT_NAMES)), dtype=bool), robot=robot, method=METHOD,
                         foot_names=list(FOOT_NAMES), source={"kind": "puppet", "robot": robot, **(source or {})},
                         metrics=metrics)
    extra = {"t": grid - grid[0], "arm_joint_names": np.array(ub.joint_names), "arm_q": arm_q,
             "collision_free": free, "min_capsule_distance_m": dist}
    if pose15 is not None:
        p = np.asarray(pose15, dtype=float)
        if p.shape != (len(t), 15):
            raise ValueError(f"pose15: expected ({len(t)}, 15), got {p.shape}")
        extra["pose15"] = p[idx]
    return motion, extra


def save_puppet_motion(path: str | Path, robot: str, t_s: np.ndarray, q: np.ndarray,
                       pose15: np.ndarray | None = None, fps: float = EXPORT_FPS, source: dict | None = None,
                       capsules: CapsuleModel | None = None) -> dict:
    """:func:`puppet_motion` written to ``path`` atomically (never half-written); returns its metrics."""
    motion, extra = puppet_motion(robot, t_s, q, pose15, fps, source, capsules)
    _write_npz(path, {**motion.arrays(), **extra})
    return {**motion.metrics, "fps": motion.fps}


__all__ = ["EXPORT_FPS", "METHOD", "puppet_motion", "save_puppet_motion"]
