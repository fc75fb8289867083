"""The paper's 15-d pose (§V): five normalised bone vectors in a body frame.

Order: hip→neck, right shoulder→elbow, right elbow→hand, left shoulder→elbow, left elbow→hand.
"Neck" is the midpoint of the two shoulder joints (robots have no neck joint; the same definition on
both sides keeps the domains comparable). The body frame is heading-only: z up, y from the right to
the left hip (projected on the ground), x = y × z forward — so a leaning torso shows in the hip→neck
vector, while walking direction and root yaw do not matter.

Sources:
- BVH clips (y-up): the CMU skeletons in both cgspeed namings (MotionBuilder-friendly as 141_16, 3dsMax-
  friendly as 131_01), Bandai Namco's, and a generic fallback; :func:`skeleton_map` picks by names.
- The ``human`` model of example-robot-data (synthetic poses, z-up after the loader's rotation).
- Robot poses (:class:`UpperBody`): pelvis frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engine.retarget.importers.bvh import BvhError, BvhMotion

BONES = ("spine", "right_upper_arm", "right_forearm", "left_upper_arm", "left_forearm")


@dataclass(frozen=True)
class SkeletonMap:
    """Joint names of one mocap naming scheme (right, left pairs)."""

    name: str
    hips: str
    shoulder: tuple[str, str]
    elbow: tuple[str, str]
    hand: tuple[str, str]
    up_leg: tuple[str, str]

    def required(self) -> list[str]:
        return [self.hips, *self.shoulder, *self.elbow, *self.hand, *self.up_leg]


SKELETONS = (
    SkeletonMap("cmu-motionbuilder", "Hips", ("RightArm", "LeftArm"), ("RightForeArm", "LeftForeArm"),
                ("RightHand", "LeftHand"), ("RightUpLeg", "LeftUpLeg")),
    SkeletonMap("cmu-3dsmax", "Hips", ("RightShoulder", "LeftShoulder"), ("RightElbow", "LeftElbow"),
                ("RightWrist", "LeftWrist"), ("RightHip", "LeftHip")),
    SkeletonMap("bandai-namco", "Hips", ("UpperArm_R", "UpperArm_L"), ("LowerArm_R", "LowerArm_L"),
                ("Hand_R", "Hand_L"), ("UpperLeg_R", "UpperLeg_L")),
)


def skeleton_map(motion: BvhMotion) -> SkeletonMap:
    """The naming scheme whose joints all exist in ``motion`` (checked in order: a 3dsMax file also has
    'RightShoulder' but no 'RightForeArm'); one-line BvhError naming what is missing otherwise."""
    for sk in SKELETONS:
        if all(motion.has(n) for n in sk.required()):
            return sk
    best = max(SKELETONS, key=lambda sk: sum(motion.has(n) for n in sk.required()))
    missing = [n for n in best.required() if not motion.has(n)]
    from pathlib import Path

    raise BvhError(f"{Path(motion.path).name}: no arm joints: expected a hips, shoulder, elbow, hand and upper-leg "
                   f"joint per side (closest naming: {best.name}, missing {', '.join(missing)})")


def body_frame(hips: np.ndarray, right_hip: np.ndarray, left_hip: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation whose columns are the body axes (x forward, y left, z up) in the source frame."""
    up = np.broadcast_to(up / np.linalg.norm(up), hips.shape)
    left = left_hip - right_hip
    left = left - np.sum(left * up, axis=-1, keepdims=True) * up
    left = left / np.maximum(np.linalg.norm(left, axis=-1, keepdims=True), 1e-9)
    fwd = np.cross(left, up)
    return np.stack([fwd, left, up], axis=-1)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-9)


def pose15_from_points(hips, shoulder, elbow, hand, frame) -> np.ndarray:
    """(..., 15) from points (..., 3) / pairs (..., 2, 3) ordered (right, left) and the body frame (..., 3, 3)."""
    neck = shoulder.mean(axis=-2)
    bones = [neck - hips,
             elbow[..., 0, :] - shoulder[..., 0, :], hand[..., 0, :] - elbow[..., 0, :],
             elbow[..., 1, :] - shoulder[..., 1, :], hand[..., 1, :] - elbow[..., 1, :]]
    local = [np.einsum("...ji,...j->...i", frame, _unit(b)) for b in bones]  # R^T v
    return np.concatenate(local, axis=-1)


@dataclass
class MocapPoints:
    """Per-frame key points of a mocap clip in the source's units: hips (F,3), shoulder/elbow/hand (F,2,3)
    ordered (right, left), and the body frame (F,3,3)."""

    hips: np.ndarray
    shoulder: np.ndarray
    elbow: np.ndarray
    hand: np.ndarray
    frame: np.ndarray
    fps: float
    skeleton: str
    up_leg: np.ndarray | None = None  # (F, 2, 3) hip joints (right, left)

    def pose15(self) -> np.ndarray:
        return pose15_from_points(self.hips, self.shoulder, self.elbow, self.hand, self.frame)


def bvh_points(motion: BvhMotion, up_axis: str = "y") -> MocapPoints:
    sk = skeleton_map(motion)
    pos = motion.global_positions()
    g = lambda n: pos[:, motion.index(n)]  # noqa: E731
    pair = lambda names: np.stack([g(names[0]), g(names[1])], axis=1)  # noqa: E731
    up = np.eye(3)["xyz".index(up_axis)]
    frame = body_frame(g(sk.hips), g(sk.up_leg[0]), g(sk.up_leg[1]), up)
    return MocapPoints(g(sk.hips), pair(sk.shoulder), pair(sk.elbow), pair(sk.hand), frame, motion.fps, sk.name,
                       pair(sk.up_leg))


def pose15_from_bvh(motion: BvhMotion, up_axis: str = "y") -> np.ndarray:
    """(F, 15) for every frame of a BVH clip."""
    return bvh_points(motion, up_axis).pose15()


def pose15_from_robot(upper_body, x: np.ndarray) -> np.ndarray:
    """15-d pose of a robot configuration (driven joints ``x``) in its pelvis frame."""
    p = upper_body.points(x)
    return pose15_from_points(p["pelvis"], p["shoulder"], p["elbow"], p["hand"], np.eye(3))


def degenerate_frame(poses: np.ndarray) -> int | None:
    """The first frame of (F, 15) poses whose bones are not five unit vectors (coincident joints give zero
    bones, overflowing coordinates NaN), or None when every frame is a skeleton."""
    n = np.sqrt((np.asarray(poses, dtype=float).reshape(len(poses), 5, 3) ** 2).sum(axis=2))
    bad = ~np.all(np.isfinite(n) & (np.abs(n - 1.0) <= 0.05), axis=1)
    return int(np.argmax(bad)) if bad.any() else None


def check_pose15(v: np.ndarray, what: str = "pose") -> np.ndarray:
    """Validate a (15,) or (N, 15) array: finite, five unit vectors (±5 %). ValueError with one line."""
    v = np.asarray(v, dtype=float)
    if v.shape == (15,):  # the per-frame case, in a few operations (same checks as below)
        n2 = (v * v).reshape(5, 3).sum(axis=1)  # NaN/inf propagate into n2 and fail the range test
        if np.all((n2 >= 0.95 ** 2) & (n2 <= 1.05 ** 2)):
            return v
    if v.shape[-1] != 15:
        raise ValueError(f"{what}: expected 15 values (5 unit bone vectors), got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{what}: expected finite numbers, got NaN/inf")
    norms = np.linalg.norm(v.reshape(*v.shape[:-1], 5, 3), axis=-1)
    if np.any(np.abs(norms - 1.0) > 0.05):
        raise ValueError(f"{what}: expected 5 unit bone vectors, got norms {np.round(norms.reshape(-1, 5)[0], 3).tolist()}")
    return v


class HumanModelSource:
    """Synthetic mocap: random poses of example-robot-data's ``human`` skeleton (within its joint limits)."""

    HIP = "middle_pelvis"
    POINTS = {"shoulder": ("right_upperarm", "left_upperarm"), "elbow": ("right_lowerarm", "left_lowerarm"),
              "hand": ("right_hand", "left_hand"), "up_leg": ("right_upperleg", "left_upperleg")}

    def __init__(self):
        import pinocchio as pin

        from engine.robot.model import load_robot

        self.pin = pin
        self.model = load_robot("human")
        self.pm = self.model.pin_model
        self.data = self.pm.createData()
        self.fid = {n: self.pm.getFrameId(n) for pair in self.POINTS.values() for n in pair}
        self.fid[self.HIP] = self.pm.getFrameId(self.HIP)
        names = self.model.joint_names
        self.arm_idx = np.array([i for i, n in enumerate(names)
                                 if any(k in n for k in ("shoulder", "elbow", "lumbar", "thoracic", "clavicle"))])
        lo = self.pm.lowerPositionLimit[7 + self.arm_idx]
        hi = self.pm.upperPositionLimit[7 + self.arm_idx]
        spine = np.array(["lumbar" in names[i] or "thoracic" in names[i] for i in self.arm_idx])
        # spine within ±0.25 rad (people rarely bend far while gesturing), arms within their limits (±2.5 rad)
        self.lo = np.where(spine, np.maximum(lo, -0.25), np.maximum(lo, -2.5))
        self.hi = np.where(spine, np.minimum(hi, 0.25), np.minimum(hi, 2.5))

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 15) poses: spine joints within ±0.25 rad, clavicles and arms uniform within their limits."""
        pm = self.pm
        out = np.empty((n, 15))
        q = self.model.q_standing.copy()
        for k in range(n):
            qq = q.copy()
            idx = self.arm_idx
            qq[7 + idx] = rng.uniform(self.lo, self.hi)
            self.pin.framesForwardKinematics(pm, self.data, qq)
            p = {k2: self.data.oMf[self.fid[k2]].translation.copy() for k2 in self.fid}
            pair = lambda key: np.stack([p[self.POINTS[key][0]], p[self.POINTS[key][1]]])  # noqa: E731
            frame = body_frame(p[self.HIP], p[self.POINTS["up_leg"][0]], p[self.POINTS["up_leg"][1]], np.array([0, 0, 1.0]))
            out[k] = pose15_from_points(p[self.HIP], pair("shoulder"), pair("elbow"), pair("hand"), frame)
        return out


__all__ = ["BONES", "SKELETONS", "SkeletonMap", "skeleton_map", "body_frame", "pose15_from_points", "MocapPoints",
           "bvh_points", "pose15_from_bvh", "pose15_from_robot", "check_pose15", "HumanModelSource"]
