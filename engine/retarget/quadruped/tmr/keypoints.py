"""The paper's 16 keypoints (§IV-A) on a MuJoCo quadruped: per leg FL, FR, RL, RR the hip, thigh and knee joint
centres and the foot (the centre of the contact sphere), with their positional Jacobians.

Legs are the robot config's ``[feet]`` in order (the engine's FL, FR, RL, RR; ANYmal's LF, RF, LH, RH are the same
legs); a leg's three joints are found by walking up the kinematic tree from its foot, so every robot of the
library works without a per-robot table.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

KEYPOINT_KINDS = ("hip", "thigh", "knee", "foot")
LEGS = ("FL", "FR", "RL", "RR")


@dataclass
class KeypointSet:
    """Where the 16 keypoints live in a MuJoCo model: (body id, local offset) per keypoint, or a joint anchor."""

    body: np.ndarray  # (16,) body id carrying the point
    joint: np.ndarray  # (16,) joint id whose anchor is the point, or -1 (a point fixed in ``body``)
    offset: np.ndarray  # (16, 3) local offset when joint == -1
    foot_geoms: list[int]  # contact sphere geom of each leg (4)
    foot_body: np.ndarray  # (4,) body of each foot

    @classmethod
    def for_robot(cls, robot) -> "KeypointSet":  # noqa: ANN001 - engine.robot.model.RobotModel
        m = robot.mj_model
        bodies, joints, offsets, geoms, feet = [], [], [], [], []
        for foot in robot.config.feet:
            fb = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, foot.link)
            if fb < 0:
                raise ValueError(f"{robot.name}: foot link {foot.link!r} is not a MuJoCo body")
            chain: list[tuple[int, int]] = []  # (body, joint)  # hinge joints from the foot up: knee, thigh, hip
            b = fb
            while b > 0 and len(chain) < 3:
                for j in range(int(m.body_jntadr[b]), int(m.body_jntadr[b] + m.body_jntnum[b])):
                    if m.jnt_type[j] == mujoco.mjtJoint.mjJNT_HINGE:
                        chain.append((b, j))
                b = int(m.body_parentid[b])
            if len(chain) < 3:
                raise ValueError(f"{robot.name}: leg {foot.name} has fewer than three hinge joints")
            for b_j in reversed(chain[:3]):  # hip, thigh, knee
                bodies.append(b_j[0])
                joints.append(b_j[1])
                offsets.append(np.zeros(3))
            bodies.append(fb)
            joints.append(-1)
            offsets.append(np.asarray(foot.offset, dtype=float))
            feet.append(fb)
            sphere = [g for g in robot.contact_geom_ids if int(m.geom_bodyid[g]) == fb]
            geoms.append(sphere[0] if sphere else -1)
        return cls(np.array(bodies), np.array(joints), np.array(offsets), geoms, np.array(feet))

    def positions(self, data: mujoco.MjData) -> np.ndarray:
        """(16, 3) world positions (needs the data's kinematics)."""
        out = np.empty((len(self.body), 3))
        for i, (b, j) in enumerate(zip(self.body, self.joint)):
            if j >= 0:
                out[i] = data.xanchor[j]
            else:
                out[i] = data.xpos[b] + data.xmat[b].reshape(3, 3) @ self.offset[i]
        return out

    def jacobians(self, model: mujoco.MjModel, data: mujoco.MjData, points: np.ndarray | None = None) -> np.ndarray:
        """(16, 3, nv) d p / d qvel (needs kinematics and com positions, e.g. after mj_forward)."""
        points = self.positions(data) if points is None else points
        jac = np.zeros((len(self.body), 3, model.nv))
        for i, b in enumerate(self.body):
            mujoco.mj_jac(model, data, jac[i], None, points[i], int(b))
        return jac

    @property
    def foot_index(self) -> list[int]:
        return [4 * leg + 3 for leg in range(4)]


def keypoint_trajectory(robot, qpos: np.ndarray, keypoints: KeypointSet | None = None) -> np.ndarray:  # noqa: ANN001
    """FK of a qpos sequence (T, nq) → (T, 16, 3)."""
    keypoints = keypoints or KeypointSet.for_robot(robot)
    m = robot.mj_model
    d = mujoco.MjData(m)
    out = np.empty((len(qpos), len(keypoints.body), 3))
    for k, q in enumerate(qpos):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        out[k] = keypoints.positions(d)
    return out
