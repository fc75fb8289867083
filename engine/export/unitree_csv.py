"""Unitree-style motion CSV: one row per frame, no header: x, y, z, qx, qy, qz, qw, joints.

The layout of Unitree's LAFAN1-retargeted clips (``LAFAN1_Retargeting_Dataset/g1/*.csv``, 30 fps),
which BeyondMimic's ``csv_to_npz.py`` reads (``motion[:, :3]`` root, ``motion[:, 3:7]`` x,y,z,w,
``motion[:, 7:]`` the 29 joints in :data:`UNITREE_G1_29` order). For a robot with a documented Unitree
order (G1: 36 columns) the joints are written in that order, mapped by NAME; a joint of that order
the motion does not have is written as 0 and listed by :func:`missing_joints`. Other robots keep the
motion's own joint order (``RobotMotion.joint_names``).

The frame rate is not stored in the file: it is the motion's fps (``studio export --fps 30`` for
Unitree's rate). Quaternions are converted from the engine's w,x,y,z at this edge.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from engine.atomic_io import atomic_write_text
from engine.retarget.motion import RobotMotion

# Unitree's G1 (29 DoF) motor order: the LAFAN1 retargeting CSVs' columns 7..35, and the joint list
# whole_body_tracking's csv_to_npz.py maps those columns by.
UNITREE_G1_29 = (
    "left_hip_pitch_joint", "left_hip_roll_joint", "left_hip_yaw_joint", "left_knee_joint",
    "left_ankle_pitch_joint", "left_ankle_roll_joint",
    "right_hip_pitch_joint", "right_hip_roll_joint", "right_hip_yaw_joint", "right_knee_joint",
    "right_ankle_pitch_joint", "right_ankle_roll_joint",
    "waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
    "left_shoulder_pitch_joint", "left_shoulder_roll_joint", "left_shoulder_yaw_joint", "left_elbow_joint",
    "left_wrist_roll_joint", "left_wrist_pitch_joint", "left_wrist_yaw_joint",
    "right_shoulder_pitch_joint", "right_shoulder_roll_joint", "right_shoulder_yaw_joint", "right_elbow_joint",
    "right_wrist_roll_joint", "right_wrist_pitch_joint", "right_wrist_yaw_joint",
)
UNITREE_ORDERS = {"g1": UNITREE_G1_29}


def joint_order(motion: RobotMotion) -> list[str]:
    """The CSV's joint columns: Unitree's documented order for its robots, else the motion's."""
    return list(UNITREE_ORDERS.get(motion.robot, motion.joint_names))


def missing_joints(motion: RobotMotion) -> list[str]:
    """Joints of the CSV's order that the motion does not have (written as 0)."""
    have = set(motion.joint_names)
    return [n for n in joint_order(motion) if n not in have]


def unitree_rows(motion: RobotMotion) -> np.ndarray:
    q = motion.qpos
    joints = np.zeros((motion.frames, len(joint_order(motion))))
    for k, name in enumerate(joint_order(motion)):
        if name in motion.joint_names:
            joints[:, k] = q[:, 7 + motion.joint_names.index(name)]
    return np.concatenate([q[:, 0:3], q[:, 4:7], q[:, 3:4], joints], axis=1)


def export_unitree_csv(motion: RobotMotion, path: str | Path) -> None:
    buf = io.StringIO()
    np.savetxt(buf, unitree_rows(motion), delimiter=",", fmt="%.8f")
    atomic_write_text(path, buf.getvalue())


def read_unitree_csv(path: str | Path) -> np.ndarray:
    """qpos (T, 7+n) in MuJoCo order from a Unitree CSV (joints in the file's column order)."""
    rows = np.loadtxt(path, delimiter=",", ndmin=2)
    return np.concatenate([rows[:, 0:3], rows[:, 6:7], rows[:, 3:6], rows[:, 7:]], axis=1)
