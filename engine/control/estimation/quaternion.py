"""Quaternion helpers of the estimator's filter state: Hamilton, stored x, y, z, w (pinocchio's order, as
the state q[3:7] it estimates); MuJoCo's w, x, y, z is converted where the IMU is read."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray


FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


# ----------------------------------------------------------------------------- rotations

Quat = tuple[float, float, float, float]  # x, y, z, w (pinocchio order), Hamilton


def _quat_mul(a: Quat, b: Quat) -> Quat:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def _quat_step(q: Quat, rx: float, ry: float, rz: float) -> Quat:
    """Normalised q ⊗ Exp(r) (one fused call: this runs every tick)."""
    angle2 = rx * rx + ry * ry + rz * rz
    if angle2 < 1e-16:
        bx, by, bz, bw = 0.5 * rx, 0.5 * ry, 0.5 * rz, 1.0
    else:
        angle = math.sqrt(angle2)
        k = math.sin(0.5 * angle) / angle
        bx, by, bz, bw = rx * k, ry * k, rz * k, math.cos(0.5 * angle)
    ax, ay, az, aw = q
    x = aw * bx + ax * bw + ay * bz - az * by
    y = aw * by - ax * bz + ay * bw + az * bx
    z = aw * bz + ax * by - ay * bx + az * bw
    w = aw * bw - ax * bx - ay * by - az * bz
    n = 1.0 / math.sqrt(x * x + y * y + z * z + w * w)
    return (x * n, y * n, z * n, w * n)


def quat_to_rotation(q_xyzw) -> FloatArray:
    """Unit xyzw quaternion → 3×3 rotation matrix."""
    x, y, z, w = (float(c) for c in q_xyzw)
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return np.array([[1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)],
                     [2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)],
                     [2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)]])


Rows = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


def _rot_rows(q: Quat) -> Rows:
    """Rows of the rotation matrix of a unit quaternion, as python floats."""
    x, y, z, w = q
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return ((1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)),
            (2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)),
            (2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)))


def rotation_to_quat(rot: FloatArray) -> FloatArray:
    """3×3 rotation matrix → unit xyzw quaternion with w ≥ 0."""
    q = np.array(pin.Quaternion(np.asarray(rot, dtype=float)).coeffs(), dtype=float)
    return -q if q[3] < 0.0 else q


def _yaw_of(rot: FloatArray) -> float:
    return math.atan2(float(rot[1, 0]), float(rot[0, 0]))


def _tilt_with_yaw(up_b: FloatArray, yaw_rad: float) -> FloatArray:
    """World ← base rotation whose base-frame "up" is ``up_b`` and whose ZYX yaw is ``yaw_rad``."""
    u = up_b / np.linalg.norm(up_b)
    roll = math.atan2(float(u[1]), float(u[2]))
    pitch = math.atan2(-float(u[0]), math.hypot(float(u[1]), float(u[2])))
    return pin.rpy.rpyToMatrix(roll, pitch, yaw_rad)
