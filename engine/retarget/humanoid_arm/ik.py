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
import pinocchio as pin

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
        # The residual as linear maps (the vectorised kernel, one pass per Gauss–Newton step): with the key
        # points P = (pelvis, shoulder R, shoulder L, elbow R, elbow L, hand R, hand L) (7, 3) and the bone
        # directions v (5, 3), r = C P − B v row by row (neck, elbow R, hand R, elbow L, hand L):
        #   neck: NECK_WEIGHT (½(sh_R + sh_L) − pelvis − L_torso v0); elbow: el − sh − L_upper v;
        #   hand: ha − sh − L_upper v_upper − L_fore v_fore (= the targets of :func:`arm_targets`).
        self._points = [self._f["pelvis"], *self._f["shoulder"], *self._f["elbow"], *self._f["hand"]]
        w = NECK_WEIGHT
        self._c = np.array([[-w, 0.5 * w, 0.5 * w, 0, 0, 0, 0],
                            [0, -1, 0, 1, 0, 0, 0], [0, -1, 0, 0, 0, 1, 0],
                            [0, 0, -1, 0, 1, 0, 0], [0, 0, -1, 0, 0, 0, 1]], dtype=float)
        lt, lu, lf = ub.lengths_m["torso"], ub.lengths_m["upper_arm"], ub.lengths_m["forearm"]
        self._b = np.array([[w * lt, 0, 0, 0, 0], [0, lu, 0, 0, 0], [0, lu, lf, 0, 0],
                            [0, 0, 0, lu, 0], [0, 0, 0, lu, lf]])
        # Jacobian: the key points' Jacobians from the world joint Jacobian (linear, angular), P_k moving by
        # mask_k ⊙ (linear − skew(P_k) angular), all seven as one (21, 3) @ (3, n) product, then J = (C ⊗ I3) Y
        self._masks = np.array([ub.support_mask(f) for f in self._points])[:, None, :]  # (7, 1, n)
        skew = np.zeros((3, 3, 3))  # skew(p)[r, c] = Σ_i p_i skew[i, r, c]
        skew[0, 2, 1], skew[0, 1, 2], skew[1, 0, 2], skew[1, 2, 0], skew[2, 1, 0], skew[2, 0, 1] = 1, -1, 1, -1, 1, -1
        self._skew = skew.reshape(3, 9)
        self._c3 = np.kron(self._c, np.eye(3))  # (15, 21)
        self._q = ub.q_base.copy()
        # views of the key frames' positions inside ub.data (pinocchio updates them in place; ub.data is never
        # replaced): one array construction reads all seven
        self._point_views = [ub.data.oMf[f].translation for f in self._points]
        self._damped_eye = (damping + regularisation) * self._eye

    def residual(self, x: np.ndarray, pose15: np.ndarray, with_jacobian: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """The stacked residual (15,) — neck (weighted), right elbow, right hand, left elbow, left hand, each
        relative to the robot's own shoulder — and its (15, n) Jacobian w.r.t. the driven joints."""
        ub, q = self.ub, self._q
        q[ub.q_index] = x
        if with_jacobian:
            pin.computeJointJacobians(ub.pin_model, ub.data, q)
            pin.updateFramePlacements(ub.pin_model, ub.data)
        else:
            pin.framesForwardKinematics(ub.pin_model, ub.data, q)
        p = np.array(self._point_views)  # (7, 3)
        r = (self._c @ p - self._b @ pose15.reshape(5, 3)).ravel()
        if not with_jacobian:
            return r, None
        lin, ang = ub.driven_jacobian()
        y = self._masks * (lin - ((p @ self._skew).reshape(21, 3) @ ang).reshape(7, 3, ub.n))  # (7, 3, n)
        return r, self._c3 @ y.reshape(21, ub.n)

    def gauss_newton(self, pose15: np.ndarray, x0: np.ndarray | None = None, iters: int | None = None,
                     tolerance_rad: float = 1e-4) -> np.ndarray:
        """Damped Gauss–Newton steps from ``x0`` (default: the standing pose) until the largest joint step is
        below ``tolerance_rad`` or ``iters`` steps (default: the solver's cap) were taken; clipped to the limits."""
        ub = self.ub
        x = ub.clip(ub.neutral() if x0 is None else np.asarray(x0, dtype=float).copy())
        xn = self._neutral
        for _ in range(self.iters if iters is None else iters):
            r, jm = self.residual(x, pose15, True)
            assert jm is not None
            h = jm.T @ jm + self._damped_eye
            g = jm.T @ r + self.reg * (x - xn)
            dx = -np.linalg.solve(h, g)
            x = ub.clip(x + dx)
            if np.abs(dx).max() < tolerance_rad:
                break
        return x

    def solve(self, pose15: np.ndarray, x0: np.ndarray | None = None, fix: bool = True,
              iters: int | None = None) -> tuple[np.ndarray, bool]:
        """Joint angles for one 15-d pose; (x, collision_free): Gauss–Newton converged to 1e-4 rad (at most
        ``iters`` steps, default 30), then the capsule fixer."""
        x = self.gauss_newton(pose15, x0, iters)
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
