"""Leg kinematics of the estimator: foot positions and Jacobians relative to the base."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from engine.robot.model import RobotModel

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


# ----------------------------------------------------------------------------- leg kinematics

Vec3 = tuple[float, float, float]


def _vec3(x: FloatArray) -> Vec3:
    return (float(x[0]), float(x[1]), float(x[2]))


class FootKinematics:
    """Per foot, from the encoders and the base attitude: vectors in world axes, base origin held still.

    ``point_w_m[i]``: base origin → contact point. ``point_vel_w_mps[i]``: the contact point's
    velocity from the base rotation and the joints (the base velocity is its negative when the
    point is still). ``sole_up_cos[i]``: cos of the sole normal's angle to the vertical (1 for
    point feet). :meth:`omega_w` and :meth:`slide_w` are evaluated on demand.
    """

    __slots__ = ("point_w_m", "point_vel_w_mps", "sole_up_cos", "_rot", "_ang", "_delta")

    def __init__(self, point_w_m: list[Vec3], point_vel_w_mps: list[Vec3], sole_up_cos: list[float],
                 rot: list[tuple[float, ...]], ang: list[Vec3], delta: list[Vec3 | None]):
        self.point_w_m = point_w_m
        self.point_vel_w_mps = point_vel_w_mps
        self.sole_up_cos = sole_up_cos
        self._rot = rot  # per foot: world ← joint rotation, row-major 9-tuple
        self._ang = ang  # per foot: angular velocity, joint frame
        self._delta = delta  # per foot: contact point offset change since the last tick, joint frame

    def omega_w(self, i: int) -> Vec3:
        """Angular velocity of foot ``i`` in world axes (base rotation included)."""
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._rot[i]
        wx, wy, wz = self._ang[i]
        return (r00 * wx + r01 * wy + r02 * wz, r10 * wx + r11 * wy + r12 * wz, r20 * wx + r21 * wy + r22 * wz)

    def slide_w(self, i: int) -> Vec3:
        """Motion of foot ``i``'s contact point along the sole since the last tick, world axes."""
        d = self._delta[i]
        if d is None:
            return (0.0, 0.0, 0.0)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = self._rot[i]
        dx, dy, dz = d
        return (r00 * dx + r01 * dy + r02 * dz, r10 * dx + r11 * dy + r12 * dz, r20 * dx + r21 * dy + r22 * dz)


class LegKinematics:
    """Forward kinematics of the feet in world-aligned axes about the base origin (one pinocchio pass).

    The base pose in the kinematic model is (0, R̂) with angular velocity ω̂, so joint placements
    and velocities come out directly as the world-axis quantities the filters need.

    Soles (bipeds): the contact point is the soft-min (length ``softmin_m``) of the four
    corner heights along the vertical. For a rectangle ``c ± a ± b`` it separates into
    ``c − a·tanh(a_z/s) − b·tanh(b_z/s)`` (``a_z``: the world height of the half-axis): the sole
    centre when flat, moving continuously to the heel/toe or inner/outer edge as the foot
    tilts. Point feet (quadrupeds): the sphere centre. :attr:`ground_offset_m` is the contact
    point's height above the ground when in contact.
    """

    def __init__(self, robot: RobotModel, softmin_m: float = 0.004):
        cfg = robot.config
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.inv_softmin = 1.0 / float(softmin_m)
        self.foot_names: list[str] = []
        self.joint_ids: list[int] = []
        # Per sole, in its joint frame: centre, half-length axis, half-width axis, unit up normal.
        self.soles_joint: list[tuple[Vec3, Vec3, Vec3, Vec3] | None] = []
        self.points_joint: list[Vec3] = []  # point feet: sphere centre in the joint frame
        ground: list[float] = []
        for side in cfg.soles:
            frames = [self.model.frames[robot.frame_id(f"{side}_foot_c{i}")] for i in range(4)]
            c = np.array([f.placement.translation for f in frames])  # FL, FR, BR, BL
            centre = c.mean(axis=0)
            half_len = 0.5 * (c[0] - c[3])  # back-left → front-left
            half_wid = 0.5 * (c[0] - c[1])  # front-right → front-left
            normal = np.cross(half_len, half_wid)
            self.foot_names.append(side)
            self.joint_ids.append(int(frames[0].parentJoint))
            self.soles_joint.append((_vec3(centre), _vec3(half_len), _vec3(half_wid),
                                     _vec3(normal / np.linalg.norm(normal))))
            self.points_joint.append(_vec3(centre))
            ground.append(0.0)  # the sole plane is the bottom of the corner spheres
        for foot in cfg.feet:
            frame = self.model.frames[robot.frame_id(f"foot_{foot.name}")]
            self.foot_names.append(foot.name)
            self.joint_ids.append(int(frame.parentJoint))
            self.soles_joint.append(None)
            self.points_joint.append(_vec3(frame.placement.translation))
            ground.append(float(foot.radius_m))
        if not self.foot_names:
            raise ValueError(f"{robot.name}: no feet in the contact model, nothing to estimate from")
        self.flat_feet = bool(cfg.soles)
        self.n_feet = len(self.foot_names)
        self.ground_offset_m = ground
        self._q = pin.neutral(self.model)
        self._v = np.zeros(self.model.nv)
        self._prev_offset: list[Vec3 | None] = [None] * self.n_feet

    def reset(self) -> None:
        self._prev_offset = [None] * self.n_feet

    def compute(self, joint_q: FloatArray, joint_qd: FloatArray, quat_wxyz=(1.0, 0.0, 0.0, 0.0),
                omega_b_radps=(0.0, 0.0, 0.0)) -> FootKinematics:
        """Contact points for measured joints, base attitude ``quat_wxyz`` (w, x, y, z) and base rate ``omega_b_radps``."""
        q, v = self._q, self._v
        q[3:7] = (quat_wxyz[1], quat_wxyz[2], quat_wxyz[3], quat_wxyz[0])  # pinocchio: x, y, z, w
        q[7:] = joint_q
        v[3:6] = omega_b_radps
        v[6:] = joint_qd
        pin.forwardKinematics(self.model, self.data, q, v)
        point: list[Vec3] = []
        vel: list[Vec3] = []
        up_cos: list[float] = []
        rots: list[tuple[float, ...]] = []
        angs: list[Vec3] = []
        deltas: list[Vec3 | None] = []
        tanh, k = math.tanh, self.inv_softmin
        oMi, v_joint = self.data.oMi, self.data.v
        for i in range(self.n_feet):
            jid = self.joint_ids[i]
            (r00, r01, r02, tx), (r10, r11, r12, ty), (r20, r21, r22, tz), _ = oMi[jid].homogeneous.tolist()
            lx, ly, lz, wx, wy, wz = v_joint[jid].vector.tolist()  # joint frame
            sole = self.soles_joint[i]
            if sole is not None:
                (cx, cy, cz), (ax, ay, az), (bx, by, bz), (nx, ny, nz) = sole
                ta = tanh((r20 * ax + r21 * ay + r22 * az) * k)
                tb = tanh((r20 * bx + r21 * by + r22 * bz) * k)
                ox, oy, oz = cx - ax * ta - bx * tb, cy - ay * ta - by * tb, cz - az * ta - bz * tb
                up_cos.append(r20 * nx + r21 * ny + r22 * nz)
                prev = self._prev_offset[i]
                deltas.append(None if prev is None else (ox - prev[0], oy - prev[1], oz - prev[2]))
                self._prev_offset[i] = (ox, oy, oz)
            else:
                ox, oy, oz = self.points_joint[i]
                up_cos.append(1.0)
                deltas.append(None)
            point.append((r00 * ox + r01 * oy + r02 * oz + tx, r10 * ox + r11 * oy + r12 * oz + ty,
                          r20 * ox + r21 * oy + r22 * oz + tz))
            px, py, pz = lx + wy * oz - wz * oy, ly + wz * ox - wx * oz, lz + wx * oy - wy * ox
            vel.append((r00 * px + r01 * py + r02 * pz, r10 * px + r11 * py + r12 * pz, r20 * px + r21 * py + r22 * pz))
            rots.append((r00, r01, r02, r10, r11, r12, r20, r21, r22))
            angs.append((wx, wy, wz))
        return FootKinematics(point, vel, up_cos, rots, angs, deltas)
