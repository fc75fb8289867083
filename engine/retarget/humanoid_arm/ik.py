"""Optimisation-based retargeting (the paper's glue data and our per-frame baseline, after Choi & Kim):
inverse kinematics on the 15-d pose's bone directions scaled to the robot, then the capsule fixer.

Targets (pelvis frame, metres), from a 15-d pose d and the robot's torso / upper-arm / forearm lengths:
- neck (shoulder midpoint) at pelvis + L_torso · d_spine;
- each elbow at its shoulder + L_upper · d_upper, each hand at shoulder + L_upper · d_upper + L_fore · d_fore.
The hand and elbow errors reported everywhere (:func:`arm_errors_m`) are the distances to these targets
("after scaling the source to the robot's arm length"), measured from the robot's own shoulders.
"""

from __future__ import annotations

import numpy as np

from engine.retarget.humanoid_arm.capsules import CapsuleModel
from engine.retarget.humanoid_arm.upper_body import UpperBody

NECK_WEIGHT = 0.5  # the torso follows the spine direction more loosely than the arms follow theirs


def arm_targets(ub: UpperBody, pose15: np.ndarray, shoulders: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Elbow and hand targets (2, 3) ordered (right, left) given the robot's shoulder positions (2, 3)."""
    v = np.asarray(pose15).reshape(5, 3)
    lu, lf = ub.lengths_m["upper_arm"], ub.lengths_m["forearm"]
    elbow = shoulders + lu * v[[1, 3]]
    hand = elbow + lf * v[[2, 4]]
    return elbow, hand


def arm_errors_m(ub: UpperBody, x: np.ndarray, pose15: np.ndarray) -> tuple[float, float]:
    """(hand, elbow) position error in metres, mean over both arms."""
    p = ub.points(x)
    elbow_t, hand_t = arm_targets(ub, pose15, p["shoulder"])
    return (float(np.mean(np.linalg.norm(p["hand"] - hand_t, axis=1))),
            float(np.mean(np.linalg.norm(p["elbow"] - elbow_t, axis=1))))


class ArmIK:
    """Damped Gauss–Newton IK with joint-limit clipping, warm-started; optional capsule fixing."""

    def __init__(self, ub: UpperBody, capsules: CapsuleModel | None = None, iters: int = 30, damping: float = 1e-3,
                 regularisation: float = 1e-3):
        self.ub, self.capsules = ub, capsules
        self.iters, self.damping, self.reg = iters, damping, regularisation
        fid = ub.frame_ids
        s = ub.spec
        self._f = {"pelvis": fid[s.pelvis_frame], "shoulder": [fid[f] for f in s.shoulder_frames],
                   "elbow": [fid[f] for f in s.elbow_frames], "hand": [fid[f] for f in s.hand_frames]}
        self._neutral = ub.neutral()
        self._eye = np.eye(ub.n)

    def _residual(self, x: np.ndarray, pose15: np.ndarray, with_jacobian: bool):
        ub = self.ub
        if with_jacobian:
            ub.jacobians(x)
        else:
            ub.forward(x)
        d = ub.data
        pos = lambda f: d.oMf[f].translation  # noqa: E731
        jac = ub.frame_origin_jacobian
        v = pose15.reshape(5, 3)
        lt = ub.lengths_m["torso"]
        sh = np.stack([pos(f) for f in self._f["shoulder"]])
        elbow_t, hand_t = arm_targets(ub, pose15, sh)
        neck = sh.mean(axis=0)
        res = [NECK_WEIGHT * (neck - pos(self._f["pelvis"]) - lt * v[0])]
        for k in range(2):
            res.append(pos(self._f["elbow"][k]) - elbow_t[k])
            res.append(pos(self._f["hand"][k]) - hand_t[k])
        r = np.concatenate(res)
        if not with_jacobian:
            return r, None
        js = [jac(f) for f in self._f["shoulder"]]
        rows = [NECK_WEIGHT * (0.5 * (js[0] + js[1]) - jac(self._f["pelvis"]))]
        for k in range(2):
            rows.append(jac(self._f["elbow"][k]) - js[k])
            rows.append(jac(self._f["hand"][k]) - js[k])
        return r, np.vstack(rows)

    def solve(self, pose15: np.ndarray, x0: np.ndarray | None = None, fix: bool = True,
              iters: int | None = None) -> tuple[np.ndarray, bool]:
        """Joint angles for one 15-d pose; (x, collision_free). ``iters`` overrides the iteration cap (LWL2's
        refinement runs a few from the LWR pose)."""
        ub = self.ub
        x = ub.clip(ub.neutral() if x0 is None else np.asarray(x0, dtype=float).copy())
        xn = self._neutral
        eye = self._eye
        for _ in range(self.iters if iters is None else iters):
            r, jm = self._residual(x, pose15, True)
            h = jm.T @ jm + (self.damping + self.reg) * eye
            g = jm.T @ r + self.reg * (x - xn)
            dx = -np.linalg.solve(h, g)
            x = ub.clip(x + dx)
            if np.max(np.abs(dx)) < 1e-4:
                break
        if fix and self.capsules is not None:
            return self.capsules.fix(x)
        return x, True if self.capsules is None else self.capsules.is_free(x)

    def solve_sequence(self, poses15: np.ndarray, fix: bool = True, progress=None) -> tuple[np.ndarray, np.ndarray]:
        """Warm-started IK over a clip: (F, n) angles and (F,) collision-free flags."""
        out = np.empty((len(poses15), self.ub.n))
        free = np.zeros(len(poses15), dtype=bool)
        x = None
        for i, p in enumerate(poses15):
            x, free[i] = self.solve(p, x, fix)
            out[i] = x
            if progress is not None:
                progress(i + 1, len(poses15))
        return out, free


__all__ = ["ArmIK", "arm_targets", "arm_errors_m", "NECK_WEIGHT"]
