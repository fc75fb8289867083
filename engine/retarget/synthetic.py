"""A procedural source motion (no shared data needed): a quadruped's own trot as a KeypointMotion.

Used by tests, the bench's fallback and the studio's demo: the base moves forward at ``speed_m_s``, legs
in swing fold their knee sinusoidally, keypoints come from FK of ``robot``; the contact schedule is the
trot's (diagonal pairs) unless one is given.
"""

from __future__ import annotations

import numpy as np

from engine.retarget.motion import KeypointMotion
from engine.retarget.quadruped.kinematics import quadruped_kinematics


def trot_schedule(frames: int, fps: float, period_s: float = 0.6, duty: float = 0.6) -> np.ndarray:
    t = np.arange(frames) / fps
    phase = (t / period_s)[:, None] + np.array([0.0, 0.5, 0.5, 0.0])[None, :]  # FL, FR, RL, RR
    return (phase % 1.0) < duty


def synthetic_trot(robot: str = "a1", frames: int = 60, fps: float = 30.0, speed_m_s: float = 0.3,
                   contact: np.ndarray | None = None, lift_rad: float = 0.5) -> KeypointMotion:
    kin = quadruped_kinematics(robot)
    contact = trot_schedule(frames, fps) if contact is None else np.asarray(contact, dtype=bool)
    data = kin.model.createData()
    q0 = kin.robot.q_standing.copy()
    kp = np.empty((frames, 16, 3))
    base_pos = np.empty((frames, 3))
    for t in range(frames):
        q = q0.copy()
        q[0] += speed_m_s * t / fps
        for leg in range(4):
            if not contact[t, leg]:
                # progress through this swing segment
                start = t
                while start > 0 and not contact[start - 1, leg]:
                    start -= 1
                end = t
                while end < frames - 1 and not contact[end + 1, leg]:
                    end += 1
                s = (t - start + 1) / (end - start + 2)
                bend = lift_rad * np.sin(np.pi * s)
                q[kin.leg_q[leg, 1]] += 0.6 * bend
                q[kin.leg_q[leg, 2]] -= bend
        kp[t] = kin.keypoints(data, q)
        base_pos[t] = q[:3]
    ground = float(np.median(kp[:, 3::4, 2][contact])) if contact.any() else float(kp[:, 3::4, 2].min())
    kp[:, :, 2] -= ground
    base_pos[:, 2] -= ground
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (frames, 1))
    return KeypointMotion(fps=fps, keypoints=kp, contact=contact, base_pos=base_pos, base_quat=quat,
                          source={"file": f"synthetic-trot-{robot}", "format": "synthetic", "robot": robot})
