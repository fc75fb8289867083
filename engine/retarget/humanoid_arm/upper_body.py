"""The retargeted part of a humanoid: which joints LWL2 drives, which links stand for the human's
hip, shoulders, elbows and hands, and which bodies get a capsule.

The legs stay in the robot's standing pose (the whole-body controller balances); the pelvis is the body
frame (x forward, y left, z up). Wrists are held at zero: the 15-d pose (five bone directions) does not
constrain them, and leaving them free would only add redundancy to the learned maps.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin

from engine.robot.model import RobotModel, load_robot


@dataclass(frozen=True)
class CapsuleGroup:
    """One capsule: the frame it rides on and the MuJoCo bodies whose collision meshes it wraps."""

    name: str
    frame: str
    bodies: tuple[str, ...]


@dataclass(frozen=True)
class UpperBodySpec:
    robot: str
    joints: tuple[str, ...]  # driven joints, in the order of the robot-pose vector
    pelvis_frame: str
    shoulder_frames: tuple[str, str]  # (right, left), as the 15-d pose orders its arms
    elbow_frames: tuple[str, str]
    hand_frames: tuple[str, str]
    capsules: tuple[CapsuleGroup, ...]


def _g1() -> UpperBodySpec:
    arm = ("shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow")
    caps = [CapsuleGroup("pelvis", "pelvis", ("pelvis_contour_link",)),
            CapsuleGroup("torso", "torso_link", ("torso_link", "logo_link")),
            CapsuleGroup("head", "torso_link", ("head_link",))]
    for side in ("left", "right"):
        caps += [CapsuleGroup(f"{side}_thigh", f"{side}_hip_roll_link", (f"{side}_hip_roll_link", f"{side}_hip_yaw_link")),
                 CapsuleGroup(f"{side}_shoulder", f"{side}_shoulder_roll_link", (f"{side}_shoulder_pitch_link", f"{side}_shoulder_roll_link")),
                 CapsuleGroup(f"{side}_upper_arm", f"{side}_shoulder_yaw_link", (f"{side}_shoulder_yaw_link",)),
                 CapsuleGroup(f"{side}_forearm", f"{side}_elbow_link", (f"{side}_elbow_link", f"{side}_wrist_roll_link")),
                 CapsuleGroup(f"{side}_hand", f"{side}_elbow_link", (f"{side}_wrist_pitch_link", f"{side}_wrist_yaw_link"))]
    return UpperBodySpec(
        robot="g1",
        joints=("waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
                *(f"left_{j}_joint" for j in arm), *(f"right_{j}_joint" for j in arm)),
        pelvis_frame="pelvis",
        shoulder_frames=("right_shoulder_roll_link", "left_shoulder_roll_link"),
        elbow_frames=("right_elbow_link", "left_elbow_link"),
        hand_frames=("right_wrist_yaw_link", "left_wrist_yaw_link"),
        capsules=tuple(caps),
    )


def _talos() -> UpperBodySpec:
    caps = [CapsuleGroup("pelvis", "base_link", ("base_link",)),
            CapsuleGroup("torso", "torso_2_link", ("torso_2_link",)),
            CapsuleGroup("head", "torso_2_link", ("head_1_link", "head_2_link", "rgbd_link"))]
    for side in ("left", "right"):
        grip = tuple(f"gripper_{side}_{p}" for p in ("base_link", "motor_double_link", "inner_double_link",
                                                      "fingertip_1_link", "fingertip_2_link", "motor_single_link",
                                                      "inner_single_link", "fingertip_3_link"))
        caps += [CapsuleGroup(f"{side}_thigh", f"leg_{side}_1_link", (f"leg_{side}_1_link", f"leg_{side}_2_link", f"leg_{side}_3_link")),
                 CapsuleGroup(f"{side}_shoulder", f"arm_{side}_1_link", (f"arm_{side}_1_link",)),
                 CapsuleGroup(f"{side}_upper_arm", f"arm_{side}_3_link", (f"arm_{side}_2_link", f"arm_{side}_3_link")),
                 CapsuleGroup(f"{side}_forearm", f"arm_{side}_4_link", (f"arm_{side}_4_link", f"arm_{side}_5_link")),
                 CapsuleGroup(f"{side}_hand", f"arm_{side}_4_link",
                              (f"arm_{side}_6_link", f"arm_{side}_7_link", f"wrist_{side}_ft_link", f"wrist_{side}_ft_tool_link", *grip))]
    arm = [f"arm_{{s}}_{i}_joint" for i in (1, 2, 3, 4)]
    return UpperBodySpec(
        robot="talos",
        joints=("torso_1_joint", "torso_2_joint", *(a.format(s="left") for a in arm), *(a.format(s="right") for a in arm)),
        pelvis_frame="base_link",
        shoulder_frames=("arm_right_2_link", "arm_left_2_link"),
        elbow_frames=("arm_right_4_link", "arm_left_4_link"),
        hand_frames=("arm_right_7_link", "arm_left_7_link"),
        capsules=tuple(caps),
    )


SPECS = {"g1": _g1, "talos": _talos}


class UpperBody:
    """Kinematics of the retargeted joints: full configurations, key points, limits, Jacobians."""

    def __init__(self, robot: str | RobotModel):
        self.model = load_robot(robot) if isinstance(robot, str) else robot
        if self.model.name not in SPECS:
            raise ValueError(f"no upper-body retargeting spec for robot {self.model.name!r}; robots: {', '.join(SPECS)}")
        self.spec = SPECS[self.model.name]()
        pm = self.model.pin_model
        self.pin_model = pm
        self.data = pm.createData()
        self.joint_idx = np.array([self.model.joint_names.index(j) for j in self.spec.joints])
        self.q_index = 7 + self.joint_idx  # into pinocchio q
        self.v_index = 6 + self.joint_idx  # into pinocchio v
        q0 = self.model.q_standing.copy()
        q0[0:3] = 0.0
        q0[3:7] = [0.0, 0.0, 0.0, 1.0]  # pelvis frame = world frame
        # wrists (and anything else not driven) at zero; legs stay in the standing pose
        upper = set(self.model.config.upper_body_joints) | {n for n in self.model.joint_names if "gripper" in n}
        for i, n in enumerate(self.model.joint_names):
            if n in upper and n not in self.spec.joints:
                q0[7 + i] = 0.0
        self.q_base = q0
        self.lower = self.model.joint_lower[self.joint_idx].copy()
        self.upper = self.model.joint_upper[self.joint_idx].copy()
        self.frame_ids = {name: pm.getFrameId(name) for name in
                          [self.spec.pelvis_frame, *self.spec.shoulder_frames, *self.spec.elbow_frames, *self.spec.hand_frames]}

    @property
    def n(self) -> int:
        return len(self.spec.joints)

    @property
    def joint_names(self) -> list[str]:
        return list(self.spec.joints)

    def full_q(self, x: np.ndarray) -> np.ndarray:
        q = self.q_base.copy()
        q[self.q_index] = x
        return q

    def clip(self, x: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(x, self.lower), self.upper)  # np.clip's numbers, without its wrapper's cost

    def neutral(self) -> np.ndarray:
        """The standing pose's arm angles (clipped to the limits)."""
        return self.clip(self.model.q_standing[self.q_index])

    def forward(self, x: np.ndarray) -> pin.Data:
        pin.framesForwardKinematics(self.pin_model, self.data, self.full_q(x))
        return self.data

    def points(self, x: np.ndarray) -> dict[str, np.ndarray]:
        """Pelvis, shoulders, elbows and hands in the pelvis frame, (2, 3) arrays ordered (right, left)."""
        d = self.forward(x)
        pos = lambda f: d.oMf[self.frame_ids[f]].translation.copy()  # noqa: E731
        return {"pelvis": pos(self.spec.pelvis_frame),
                "shoulder": np.stack([pos(f) for f in self.spec.shoulder_frames]),
                "elbow": np.stack([pos(f) for f in self.spec.elbow_frames]),
                "hand": np.stack([pos(f) for f in self.spec.hand_frames])}

    @cached_property
    def lengths_m(self) -> dict[str, float]:
        """Torso (pelvis → shoulder midpoint), upper arm and forearm lengths in the standing pose."""
        p = self.points(self.neutral())
        return {"torso": float(np.linalg.norm(p["shoulder"].mean(axis=0) - p["pelvis"])),
                "upper_arm": float(np.mean(np.linalg.norm(p["elbow"] - p["shoulder"], axis=1))),
                "forearm": float(np.mean(np.linalg.norm(p["hand"] - p["elbow"], axis=1)))}

    def point_jacobian(self, frame_id: int, point_world: np.ndarray) -> np.ndarray:
        """(3, n) Jacobian of a world point rigidly attached to ``frame_id`` w.r.t. the driven joints
        (call after :meth:`forward` and ``computeJointJacobians``)."""
        j6 = pin.getFrameJacobian(self.pin_model, self.data, frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        r = point_world - self.data.oMf[frame_id].translation
        w = j6[3:]
        jv = j6[:3] + np.stack([w[1] * r[2] - w[2] * r[1], w[2] * r[0] - w[0] * r[2], w[0] * r[1] - w[1] * r[0]])  # v_p = v_o + ω × r
        return jv[:, self.v_index]

    def frame_origin_jacobian(self, frame_id: int) -> np.ndarray:
        """(3, n) Jacobian of a frame's origin w.r.t. the driven joints (after :meth:`jacobians`)."""
        j6 = pin.getFrameJacobian(self.pin_model, self.data, frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        return j6[:3, self.v_index]

    def support_mask(self, frame_id: int) -> np.ndarray:
        """(n,) 1.0 for each driven joint on ``frame_id``'s kinematic chain (the joints that move it), else 0."""
        column = {int(v): c for c, v in enumerate(self.v_index)}
        mask = np.zeros(self.n)
        for j in self.pin_model.supports[self.pin_model.frames[frame_id].parentJoint]:
            c = column.get(int(self.pin_model.joints[j].idx_v)) if j > 0 else None
            if c is not None:
                mask[c] = 1.0
        return mask

    def driven_jacobian(self) -> tuple[np.ndarray, np.ndarray]:
        """(linear, angular), each (3, n): the driven joints' columns of the world-frame joint Jacobian (after
        :meth:`jacobians`). A world point p on a link that joint j moves has velocity column
        ``linear[:, j] + angular[:, j] × p`` — every point Jacobian at once, without a pinocchio call per frame."""
        j = self.data.J[:, self.v_index]
        return j[:3], j[3:]

    def jacobians(self, x: np.ndarray) -> None:
        pin.computeJointJacobians(self.pin_model, self.data, self.full_q(x))
        pin.updateFramePlacements(self.pin_model, self.data)


__all__ = ["CapsuleGroup", "UpperBodySpec", "UpperBody", "SPECS"]
