"""motion_imitation / AMP_for_hardware JSON.

``{"LoopMode", "FrameDuration", "EnableCycleOffsetPosition", "EnableCycleOffsetRotation", "MotionWeight",
"Frames"}``; each frame is root position (3), root quaternion **x,y,z,w** (4) and the joints. Plain frames
list the joints in the robot's own order (its model's, as in ``RobotMotion.joint_names``). ``full=True``
writes AMP_for_hardware's 61-value frames, laid out as its ``AMPLoader`` reads them: joints (12) in
pybullet leg order FR, FL, RR, RL (the loader reorders pybullet → Isaac), toe positions in the base frame
(12, same order), base linear and angular velocity in the base frame (3 + 3), joint velocities (12) and
toe velocities in the base frame (12) — forward differences, the last frame repeating the one before, as in
the shipped A1 clips (checked numerically against ``datasets/mocap_motions/pace1.txt``). An extra
``JointNames`` key records the joint order used (loaders ignore it; our importer maps by it).

``leg_order="isaac"`` writes the legs FL, FR, RL, RR instead (joints, toes and their velocities): the order
STMR_RL's copy of the ``AMPLoader`` expects — its ``reorder_from_pybullet_to_isaac`` call is commented out and
its ``preprocess_FD_motion.py`` writes Isaac order — with the same 61-value slicing.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin

from engine.atomic_io import atomic_write_text
from engine.retarget.motion import RobotMotion

PYBULLET_LEGS = ("FR", "FL", "RR", "RL")
ISAAC_LEGS = ("FL", "FR", "RL", "RR")
LEG_ORDERS = {"pybullet": PYBULLET_LEGS, "isaac": ISAAC_LEGS}


def _pybullet_joint_order(motion: RobotMotion, leg_order: str = "pybullet"):
    from engine.retarget.quadruped.kinematics import quadruped_kinematics

    kin = quadruped_kinematics(motion.robot)
    names = []
    legs = ("FL", "FR", "RL", "RR")
    order = LEG_ORDERS[leg_order]
    for leg in order:
        e = legs.index(leg)
        names += [kin.model.names[int(j)] for j in kin.joint_ids[e]]
    return kin, names, [legs.index(leg) for leg in order]


def amp_frames(motion: RobotMotion, full: bool = False, leg_order: str = "pybullet") -> tuple[np.ndarray, list[str]]:
    if leg_order not in LEG_ORDERS:
        raise ValueError(f"leg_order: expected one of {', '.join(LEG_ORDERS)}, got {leg_order!r}")
    q = motion.qpos
    root = np.concatenate([q[:, 0:3], q[:, 4:7], q[:, 3:4]], axis=1)
    if not full:
        return np.concatenate([root, q[:, 7:]], axis=1), list(motion.joint_names)
    kin, names, leg_idx = _pybullet_joint_order(motion, leg_order)
    col = [motion.joint_names.index(n) for n in names]
    joints = q[:, 7:][:, col]
    dt = 1.0 / motion.fps
    t_n = len(q)
    data = kin.model.createData()
    toes = np.empty((t_n, 4, 3))
    rots = np.empty((t_n, 3, 3))
    for t in range(t_n):
        qp = kin.robot.pin_q_from_mj(_mj_qpos(kin, motion, q[t]))
        feet = kin.feet(data, qp)
        rots[t] = pin.Quaternion(qp[3:7]).toRotationMatrix()
        toes[t] = (feet[leg_idx] - qp[:3]) @ rots[t]
    def fwd(x):
        d = np.empty_like(x)
        if t_n > 1:
            d[:-1] = (x[1:] - x[:-1]) / dt
            d[-1] = d[-2]
        else:
            d[:] = 0.0
        return d
    lin = np.empty((t_n, 3))
    ang = np.empty((t_n, 3))
    for t in range(t_n):
        nxt = min(t + 1, t_n - 1)
        prv = nxt - 1 if t_n > 1 else t
        src = t if t < t_n - 1 else prv
        lin[t] = rots[src].T @ (q[src + 1 if t_n > 1 else src, :3] - q[src, :3]) / dt if t_n > 1 else 0.0
        ang[t] = pin.log3(rots[src].T @ rots[min(src + 1, t_n - 1)]) / dt if t_n > 1 else 0.0
    toe_local = toes.reshape(t_n, 12)
    frames = np.concatenate([root, joints, toe_local, lin, ang, fwd(joints), fwd(toe_local)], axis=1)
    return frames, names


def _mj_qpos(kin, motion: RobotMotion, row: np.ndarray) -> np.ndarray:
    """A RobotMotion qpos row (joints in joint_names order) as the robot's MuJoCo qpos."""
    robot = kin.robot
    qpos = np.zeros(robot.mj_model.nq)
    qpos[:7] = row[:7]
    for name, value in zip(motion.joint_names, row[7:]):
        qpos[robot.mj_qpos_index[robot.joint_names.index(name)]] = value
    return qpos


def export_amp_json(motion: RobotMotion, path: str | Path, full: bool = False, loop_mode: str = "Wrap",
                    leg_order: str = "pybullet") -> None:
    frames, names = amp_frames(motion, full, leg_order)
    doc = {
        "LoopMode": loop_mode,
        "FrameDuration": round(1.0 / motion.fps, 6),
        "EnableCycleOffsetPosition": True,
        "EnableCycleOffsetRotation": True,
        "MotionWeight": 1.0,
        "JointNames": names,
        "Frames": [[round(float(v), 6) for v in row] for row in frames],
    }
    atomic_write_text(path, json.dumps(doc, indent=1) + "\n")


def read_amp_json(path: str | Path) -> tuple[np.ndarray, list[str] | None, float]:
    """(qpos rows in MuJoCo layout with joints in the file's order, joint names if recorded, fps)."""
    doc = json.loads(Path(path).read_text())
    frames = np.asarray(doc["Frames"], dtype=float)
    n = len(doc.get("JointNames", [])) or 12
    qpos = np.concatenate([frames[:, 0:3], frames[:, 6:7], frames[:, 3:6], frames[:, 7:7 + n]], axis=1)
    return qpos, doc.get("JointNames"), 1.0 / float(doc["FrameDuration"])
