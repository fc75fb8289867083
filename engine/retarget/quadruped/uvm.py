"""Unit vector method (§III-A, Eq. 1) and the keypoint IK behind it.

The source's base pose is transferred directly; each target keypoint hangs from its parent along the
source's unit vector scaled by the target's link length: trg p_j = trg p_P(j) + trg d_j · src e_j. The hip
keypoints (parent: the base) sit at the robot's own hip offsets. Keypoints the source did not measure
(``KeypointMotion.known`` false, e.g. video with thigh + foot only) come from the target's kinematics: the
hip from the base, the thigh along the robot's standing hip→thigh direction, and a missing knee is left to
the IK (weight 0), the foot being reached along the source's thigh→foot direction scaled by the target's
leg length.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import pinocchio as pin

from engine.retarget.motion import KeypointMotion
from engine.retarget.quadruped.kinematics import QuadrupedKinematics


def source_base(source: KeypointMotion) -> tuple[np.ndarray, np.ndarray]:
    """Base positions (T, 3) and rotation matrices (T, 3, 3): the source's own, else from its hips."""
    kp = source.keypoints
    if source.base_pos is not None and source.base_quat is not None:
        rot = np.array([pin.Quaternion(w, x, y, z).toRotationMatrix() for w, x, y, z in source.base_quat])
        return source.base_pos.copy(), rot
    hips = kp[:, 0::4]  # FL, FR, RL, RR
    pos = hips.mean(axis=1) if source.base_pos is None else source.base_pos.copy()
    fwd = hips[:, :2].mean(axis=1) - hips[:, 2:].mean(axis=1)
    left = hips[:, [0, 2]].mean(axis=1) - hips[:, [1, 3]].mean(axis=1)
    rot = np.empty((len(kp), 3, 3))
    for t in range(len(kp)):
        x = fwd[t] / max(np.linalg.norm(fwd[t]), 1e-9)
        y = left[t] - x * (left[t] @ x)
        y /= max(np.linalg.norm(y), 1e-9)
        rot[t] = np.column_stack([x, y, np.cross(x, y)])
    return pos, rot


def uvm_keypoints(source: KeypointMotion, kin: QuadrupedKinematics) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 1: target keypoints (T, 16, 3), IK weights (16,), base positions and rotations of the target."""
    pos, rot = source_base(source)
    src = source.keypoints.reshape(-1, 4, 4, 3)
    assert source.known is not None  # KeypointMotion.__post_init__ fills it
    known = source.known.reshape(4, 4)
    t_n = len(src)
    trg = np.empty_like(src)
    weights = np.ones((4, 4))
    std = kin.standing_local.reshape(4, 4, 3)
    for leg in range(4):
        trg[:, leg, 0] = pos + np.einsum("tij,j->ti", rot, kin.hip_offsets_b[leg])
        for k in (1, 2, 3):
            d = kin.link_lengths_m[leg, k - 1]
            if known[leg, k] and known[leg, k - 1]:
                e = src[:, leg, k] - src[:, leg, k - 1]
                n = np.linalg.norm(e, axis=1, keepdims=True)
                fallback = np.einsum("tij,j->ti", rot, std[leg, k] - std[leg, k - 1])
                fallback /= np.linalg.norm(fallback, axis=1, keepdims=True)
                e = np.where(n > 1e-6, e / np.maximum(n, 1e-9), fallback)
                trg[:, leg, k] = trg[:, leg, k - 1] + d * e
            elif k == 1:
                e = np.einsum("tij,j->ti", rot, std[leg, 1] - std[leg, 0])
                trg[:, leg, 1] = trg[:, leg, 0] + e
            elif k == 2:
                trg[:, leg, 2] = np.nan  # filled below (foot from thigh) and ignored by the IK
                weights[leg, 2] = 0.0
            else:  # foot known, knee unknown: thigh→foot direction scaled to the target's leg length
                base_k = 1 if known[leg, 1] else 0
                e = src[:, leg, 3] - src[:, leg, base_k]
                n = np.linalg.norm(e, axis=1)
                scale = 0.9 * (kin.link_lengths_m[leg, 1] + kin.link_lengths_m[leg, 2]) / max(np.percentile(n, 95), 1e-6)
                trg[:, leg, 3] = trg[:, leg, 1] + scale * e
        if not weights[leg, 2]:
            trg[:, leg, 2] = 0.5 * (trg[:, leg, 1] + trg[:, leg, 3])
    weights[:, 0] = 0.0  # hips are fixed by the transferred base
    return trg.reshape(t_n, 16, 3), weights.reshape(16), pos, rot


class KeypointIK:
    """Damped least squares on the leg joints (base given) to reach 16 weighted keypoints."""

    def __init__(self, kin: QuadrupedKinematics, weights: np.ndarray, damping: float = 1e-4, iterations: int = 8):
        self.kin = kin
        self.model = kin.model
        self.data = self.model.createData()
        self.w = np.repeat(np.asarray(weights, dtype=float), 3)
        self.damping = damping
        self.iterations = iterations
        self.lower = self.model.lowerPositionLimit[7:]
        self._damp = damping * np.eye(self.model.nv - 6)
        self.upper = self.model.upperPositionLimit[7:]

    def _fk_jac(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        model, data, kin = self.model, self.data, self.kin
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        pos = np.empty((16, 3))
        jac = np.empty((16, 3, model.nv))
        for leg in range(4):
            for k in range(3):
                jid = int(kin.joint_ids[leg, k])
                pos[4 * leg + k] = data.oMi[jid].translation
                jac[4 * leg + k] = pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED)[:3]
            fid = int(kin.foot_frames[leg])
            pos[4 * leg + 3] = data.oMf[fid].translation
            jac[4 * leg + 3] = pin.getFrameJacobian(model, data, fid, pin.LOCAL_WORLD_ALIGNED)[:3]
        return pos, jac

    def solve(self, q0: np.ndarray, target: np.ndarray) -> np.ndarray:
        q = q0.copy()
        tgt = np.nan_to_num(target.reshape(-1))
        for _ in range(self.iterations):
            pos, jac = self._fk_jac(q)
            r = (tgt - pos.reshape(-1)) * self.w
            if np.abs(r).max() < 1e-5:
                break
            j = jac.reshape(-1, self.model.nv)[:, 6:] * self.w[:, None]
            dq = np.linalg.solve(j.T @ j + self._damp, j.T @ r)
            q[7:] = np.clip(q[7:] + dq, self.lower, self.upper)
            if np.abs(dq).max() < 1e-5:
                break
        return q


def ik_trajectory(kin: QuadrupedKinematics, target: np.ndarray, weights: np.ndarray, base_pos: np.ndarray,
                  base_rot: np.ndarray, progress: Callable[[float], None] | None = None,
                  cancel=None) -> np.ndarray:
    """Pinocchio configurations (T, nq): base as given, joints by IK to the target keypoints."""
    ik = KeypointIK(kin, weights)
    q = kin.robot.q_standing.copy()
    out = np.empty((len(target), kin.nq))
    for t in range(len(target)):
        if cancel is not None and cancel.is_set():
            raise RetargetCancelled()
        q[0:3] = base_pos[t]
        q[3:7] = pin.Quaternion(base_rot[t]).coeffs()
        q = ik.solve(q, target[t])
        out[t] = q
        if progress is not None and t % 16 == 0:
            progress(t / len(target))
    return out


class RetargetCancelled(Exception):
    """Raised inside a retargeting job when its cancel event is set."""
