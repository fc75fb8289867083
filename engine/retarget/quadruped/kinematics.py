"""A quadruped's 16 keypoints (§IV-A): FK and Jacobians with pinocchio, legs in the engine order FL, FR, RL, RR.

The keypoints of leg j are the origins of its three joints (hip abduction, hip flexion = "thigh", knee) and
the centre of its foot sphere (the robot config's ``[feet]`` point, frame ``foot_<name>``). They are found
by walking the kinematic tree up from each foot, so every robot in robots/ with a ``[feet]`` table works
without extra configuration; feet are mapped to FL/FR/RL/RR by name (FL or LF, RH = RR, …).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pinocchio as pin

from engine.retarget.motion import LEGS
from engine.robot.model import RobotModel, load_robot

_LEG_ALIASES = {"FL": "FL", "LF": "FL", "FR": "FR", "RF": "FR", "RL": "RL", "LH": "RL", "HL": "RL", "RR": "RR", "RH": "RR", "HR": "RR"}


class NotAQuadruped(ValueError):
    pass


@dataclass
class QuadrupedKinematics:
    robot: RobotModel
    joint_ids: np.ndarray  # (4, 3) pinocchio joint ids: hip, thigh, knee per leg (engine leg order)
    foot_frames: np.ndarray  # (4,) pinocchio frame ids of the foot-sphere centres
    foot_radius_m: np.ndarray  # (4,)
    leg_v: np.ndarray  # (4, 3) velocity (nv) indices of each leg's joints
    leg_q: np.ndarray  # (4, 3) configuration (nq) indices of each leg's joints
    link_lengths_m: np.ndarray  # (4, 3) |thigh−hip|, |knee−thigh|, |foot−knee|
    hip_offsets_b: np.ndarray  # (4, 3) hip joint origins in the base frame
    standing_local: np.ndarray  # (16, 3) keypoints at the standing pose in the base frame

    @property
    def model(self) -> pin.Model:
        return self.robot.pin_model

    @property
    def nq(self) -> int:
        return self.model.nq

    @property
    def nv(self) -> int:
        return self.model.nv

    @property
    def body_length_m(self) -> float:
        """Front-to-rear hip distance (the paper's "horizontal length" proxy for target size)."""
        return float(np.mean(self.hip_offsets_b[:2, 0]) - np.mean(self.hip_offsets_b[2:, 0]))

    def keypoints(self, data: pin.Data, q: np.ndarray, update: bool = True) -> np.ndarray:
        """(16, 3) world keypoints of pinocchio configuration q."""
        if update:
            pin.forwardKinematics(self.model, data, q)
        out = np.empty((16, 3))
        for leg in range(4):
            for k in range(3):
                out[4 * leg + k] = data.oMi[int(self.joint_ids[leg, k])].translation
            out[4 * leg + 3] = pin.updateFramePlacement(self.model, data, int(self.foot_frames[leg])).translation
        return out

    def feet(self, data: pin.Data, q: np.ndarray) -> np.ndarray:
        pin.forwardKinematics(self.model, data, q)
        return np.array([pin.updateFramePlacement(self.model, data, int(f)).translation for f in self.foot_frames])

    def foot_jacobians(self, data: pin.Data, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Foot positions (4, 3) and world-aligned translational Jacobians (4, 3, nv)."""
        pin.computeJointJacobians(self.model, data, q)
        pin.updateFramePlacements(self.model, data)
        pos = np.empty((4, 3))
        jac = np.empty((4, 3, self.nv))
        for leg, f in enumerate(self.foot_frames):
            pos[leg] = data.oMf[int(f)].translation
            jac[leg] = pin.getFrameJacobian(self.model, data, int(f), pin.LOCAL_WORLD_ALIGNED)[:3]
        return pos, jac


def leg_of(name: str) -> str | None:
    return _LEG_ALIASES.get(name.upper())


@lru_cache(maxsize=None)
def quadruped_kinematics(robot_name: str) -> QuadrupedKinematics:
    robot = load_robot(robot_name)
    return kinematics_of(robot)


def kinematics_of(robot: RobotModel) -> QuadrupedKinematics:
    cfg = robot.config
    if cfg.kind != "quadruped":
        raise NotAQuadruped(f"{robot.name} is a {cfg.kind}, expected a quadruped")
    model = robot.pin_model
    by_leg: dict[str, tuple] = {}
    for foot in cfg.feet:
        leg = leg_of(foot.name)
        if leg is None:
            raise NotAQuadruped(f"{cfg.path.name}: feet: cannot tell which leg {foot.name!r} is (expected FL/FR/RL/RR or LF/RF/LH/RH)")
        by_leg[leg] = (foot, model.getFrameId(f"foot_{foot.name}"))
    if set(by_leg) != set(LEGS):
        raise NotAQuadruped(f"{cfg.path.name}: feet: expected four feet FL, FR, RL, RR, got {sorted(by_leg)}")
    joint_ids = np.zeros((4, 3), dtype=int)
    foot_frames = np.zeros(4, dtype=int)
    radius = np.zeros(4)
    for i, leg in enumerate(LEGS):
        foot, fid = by_leg[leg]
        jid = model.frames[fid].parentJoint
        chain = []
        while jid > 1:  # 0 universe, 1 root free flyer
            chain.append(jid)
            jid = model.parents[jid]
        if len(chain) != 3:
            raise NotAQuadruped(f"{cfg.path.name}: leg {leg} has {len(chain)} joints, expected 3")
        joint_ids[i] = chain[::-1]
        foot_frames[i] = fid
        radius[i] = foot.radius_m
    leg_v = np.array([[model.joints[int(j)].idx_v for j in row] for row in joint_ids])
    leg_q = np.array([[model.joints[int(j)].idx_q for j in row] for row in joint_ids])
    kin = QuadrupedKinematics(robot, joint_ids, foot_frames, radius, leg_v, leg_q,
                              np.zeros((4, 3)), np.zeros((4, 3)), np.zeros((16, 3)))
    q = robot.q_standing.copy()
    q[:3] = 0.0
    q[3:7] = [0, 0, 0, 1]
    data = model.createData()
    local = kin.keypoints(data, q)
    kin.standing_local = local
    kin.hip_offsets_b = local[0::4].copy()
    pts = local.reshape(4, 4, 3)
    kin.link_lengths_m = np.linalg.norm(np.diff(pts, axis=1), axis=2)
    return kin
