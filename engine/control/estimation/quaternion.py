"""Quaternion helpers of the estimator's filter state: Hamilton, stored w, x, y, z (the project's
convention, MuJoCo's order). Pinocchio's x, y, z, w appears only where the estimate is written into
a pinocchio configuration q[3:7] (:func:`wxyz_from_xyzw` / :func:`xyzw_from_wxyz` at that edge)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray


FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


# ----------------------------------------------------------------------------- rotations

Quat = tuple[float, float, float, float]  # w, x, y, z, Hamilton


def wxyz_from_xyzw(q_xyzw) -> Quat:
    """Pinocchio's x, y, z, w → the project's w, x, y, z."""
    return (float(q_xyzw[3]), float(q_xyzw[0]), float(q_xyzw[1]), float(q_xyzw[2]))


def xyzw_from_wxyz(q_wxyz) -> tuple[float, float, float, float]:
    """The project's w, x, y, z → pinocchio's x, y, z, w (a configuration's q[3:7])."""
    return (float(q_wxyz[1]), float(q_wxyz[2]), float(q_wxyz[3]), float(q_wxyz[0]))


def _quat_mul(a: Quat, b: Quat) -> Quat:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def _quat_step(q: Quat, rx: float, ry: float, rz: float) -> Quat:
    """Normalised q ⊗ Exp(r) (one fused call: this runs every tick)."""
    angle2 = rx * rx + ry * ry + rz * rz
    if angle2 < 1e-16:
        bx, by, bz, bw = 0.5 * rx, 0.5 * ry, 0.5 * rz, 1.0
    else:
        angle = math.sqrt(angle2)
        k = math.sin(0.5 * angle) / angle
        bx, by, bz, bw = rx * k, ry * k, rz * k, math.cos(0.5 * angle)
    aw, ax, ay, az = q
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    w = aw * bw - ax * bx - ay * by - az * bz
    n = 1.0 / math.sqrt(x * x + y * y + z * z + w * w)
    return (w * n, x * n, y * n, z * n)


def quat_to_rotation(q_wxyz) -> FloatArray:
    """Unit w, x, y, z quaternion → 3×3 rotation matrix."""
    w, x, y, z = (float(c) for c in q_wxyz)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return np.array([[1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)],
                     [2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)],
                     [2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)]])


Rows = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


def _rot_rows(q: Quat) -> Rows:
    """Rows of the rotation matrix of a unit w, x, y, z quaternion, as python floats."""
    w, x, y, z = q
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return ((1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)),
            (2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)),
            (2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)))


def rotation_to_quat(rot: FloatArray) -> FloatArray:
    """3×3 rotation matrix → unit w, x, y, z quaternion with w ≥ 0."""
    x, y, z, w = pin.Quaternion(np.asarray(rot, dtype=float)).coeffs()
    q = np.array([w, x, y, z], dtype=float)
    return -q if q[0] < 0.0 else q


def _yaw_of(rot: FloatArray) -> float:
    return math.atan2(float(rot[1, 0]), float(rot[0, 0]))


def _tilt_with_yaw(up_b: FloatArray, yaw_rad: float) -> FloatArray:
    """World ← base rotation whose base-frame "up" is ``up_b`` and whose ZYX yaw is ``yaw_rad``."""
    u = up_b / np.linalg.norm(up_b)
    roll = math.atan2(float(u[1]), float(u[2]))
    pitch = math.atan2(-float(u[0]), math.hypot(float(u[1]), float(u[2])))
    return pin.rpy.rpyToMatrix(roll, pitch, yaw_rad)
