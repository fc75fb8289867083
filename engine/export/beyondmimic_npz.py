"""BeyondMimic (HybridRobotics/whole_body_tracking) motion npz.

The file its ``scripts/csv_to_npz.py`` writes and its ``MotionLoader`` (``tasks/tracking/mdp/commands.py``)
reads with ``np.load``:

==================  =========  ==============  ================================================
key                 dtype      shape           what
==================  =========  ==============  ================================================
fps                 int64      (1,)            frame rate (``[output_fps]``)
joint_pos           float32    (T, n)          joint positions (rad)
joint_vel           float32    (T, n)          joint velocities (rad/s), ``np.gradient`` of joint_pos
body_pos_w          float32    (T, B, 3)       body frame origins, world (m)
body_quat_w         float32    (T, B, 4)       body orientations, world, **w,x,y,z**
body_lin_vel_w      float32    (T, B, 3)       body origin linear velocities, world (m/s)
body_ang_vel_w      float32    (T, B, 3)       body angular velocities, world (rad/s)
joint_names         str        (n,)            (ours; its loader ignores it) the joint_pos order
body_names          str        (B,)            (ours) the body order
==================  =========  ==============  ================================================

Velocities follow csv_to_npz: base linear and joint velocities by ``np.gradient`` over the frames,
the base angular velocity from the rotation between the neighbouring frames (``log(q[k+1] q[k-1]*) / 2dt``,
ends repeated); body velocities are MuJoCo's rigid-body velocities for that base and joint motion.
Joints are in Unitree's order for G1 (the order csv_to_npz maps by name), else the motion's; bodies are
the robot's MuJoCo bodies (the world excluded). BeyondMimic's own files list joints and bodies in Isaac
Lab's articulation order, and its tracker picks bodies by index (``robot.find_bodies``): map by
``joint_names``/``body_names`` when the orders differ.
"""

from __future__ import annotations

import io
from pathlib import Path

import mujoco
import numpy as np

from engine.atomic_io import atomic_write_bytes
from engine.export.unitree_csv import joint_order
from engine.retarget.motion import RobotMotion

KEYS = ("fps", "joint_pos", "joint_vel", "body_pos_w", "body_quat_w", "body_lin_vel_w", "body_ang_vel_w")


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    w1, x1, y1, z1 = np.moveaxis(a, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(b, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def _axis_angle(q: np.ndarray) -> np.ndarray:
    q = q * np.where(q[:, :1] < 0, -1.0, 1.0)  # shortest rotation
    s = np.linalg.norm(q[:, 1:], axis=1)
    angle = 2.0 * np.arctan2(s, q[:, 0])
    scale = np.where(s > 1e-12, angle / np.maximum(s, 1e-12), 2.0)
    return q[:, 1:] * scale[:, None]


def base_velocities(qpos: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(base linear velocity world, base angular velocity world, joint velocities), as csv_to_npz."""
    t_n = len(qpos)
    if t_n < 2:
        return np.zeros((t_n, 3)), np.zeros((t_n, 3)), np.zeros((t_n, qpos.shape[1] - 7))
    lin = np.gradient(qpos[:, 0:3], dt, axis=0)
    joints = np.gradient(qpos[:, 7:], dt, axis=0)
    if t_n < 3:
        rel = _quat_mul(qpos[1:2, 3:7], qpos[0:1, 3:7] * np.array([1, -1, -1, -1]))
        ang = np.repeat(_axis_angle(rel) / dt, t_n, axis=0)
    else:
        rel = _quat_mul(qpos[2:, 3:7], qpos[:-2, 3:7] * np.array([1, -1, -1, -1]))
        omega = _axis_angle(rel) / (2.0 * dt)
        ang = np.concatenate([omega[:1], omega, omega[-1:]], axis=0)
    return lin, ang, joints


def beyondmimic_arrays(motion: RobotMotion) -> dict[str, np.ndarray]:
    from engine.robot.model import load_robot

    robot = load_robot(motion.robot)
    model = robot.mj_model
    data = mujoco.MjData(model)
    names = joint_order(motion)
    have = {n: i for i, n in enumerate(motion.joint_names)}
    q = motion.qpos
    dt = 1.0 / motion.fps
    lin, ang, joint_vel = base_velocities(q, dt)
    t_n = motion.frames
    joint_pos = np.zeros((t_n, len(names)))
    joint_vel_out = np.zeros((t_n, len(names)))
    for k, n in enumerate(names):
        if n in have:
            joint_pos[:, k] = q[:, 7 + have[n]]
            joint_vel_out[:, k] = joint_vel[:, have[n]]
    qpos_adr = [int(model.joint(n).qposadr[0]) for n in motion.joint_names]
    dof_adr = [int(model.joint(n).dofadr[0]) for n in motion.joint_names]
    bodies = list(range(1, model.nbody))
    b_n = len(bodies)
    pos = np.zeros((t_n, b_n, 3))
    quat = np.zeros((t_n, b_n, 4))
    vlin = np.zeros((t_n, b_n, 3))
    vang = np.zeros((t_n, b_n, 3))
    vel6 = np.zeros(6)
    for t in range(t_n):
        data.qpos[:] = 0.0
        data.qpos[:7] = q[t, :7]
        data.qpos[qpos_adr] = q[t, 7:]
        rot = np.zeros(9)
        mujoco.mju_quat2Mat(rot, q[t, 3:7])
        data.qvel[:] = 0.0
        data.qvel[0:3] = lin[t]
        data.qvel[3:6] = rot.reshape(3, 3).T @ ang[t]  # MuJoCo's free joint: angular velocity in the body frame
        data.qvel[dof_adr] = joint_vel[t]
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        mujoco.mj_comVel(model, data)
        pos[t] = data.xpos[bodies]
        quat[t] = data.xquat[bodies]
        for k, b in enumerate(bodies):
            mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_XBODY, b, vel6, 0)  # body frame origin
            vang[t, k] = vel6[:3]
            vlin[t, k] = vel6[3:]
    fps = motion.fps
    fps_arr = np.array([int(round(fps))], dtype=np.int64) if abs(fps - round(fps)) < 1e-9 else np.array([fps])
    f32 = np.float32
    return {
        "fps": fps_arr, "joint_pos": joint_pos.astype(f32), "joint_vel": joint_vel_out.astype(f32),
        "body_pos_w": pos.astype(f32), "body_quat_w": quat.astype(f32), "body_lin_vel_w": vlin.astype(f32),
        "body_ang_vel_w": vang.astype(f32), "joint_names": np.array(names, dtype=str),
        "body_names": np.array([model.body(b).name for b in bodies], dtype=str),
    }


def export_beyondmimic_npz(motion: RobotMotion, path: str | Path) -> None:
    buf = io.BytesIO()
    np.savez(buf, **beyondmimic_arrays(motion))  # type: ignore[arg-type]  # numpy's stub reads **kwds as allow_pickle; np.savez as csv_to_npz
    atomic_write_bytes(path, buf.getvalue())
