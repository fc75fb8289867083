"""Leg-kinematics odometry: base position and velocity from feet in contact held still."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.robot.model import RobotModel

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

from engine.control.estimation.leg_kinematics import FootKinematics, LegKinematics, Vec3


# ----------------------------------------------------------------------------- odometry


@dataclass(frozen=True)
class LegOdometryParams:
    """Noise model of :class:`LegKinematicsOdometry` (1σ, SI units, densities per √Hz)."""

    accel_noise_density_mps2_rthz: float = 0.05  # accelerometer input incl. tilt/bias errors
    no_imu_accel_density_mps2_rthz: float = 2.0  # IMU sample missing: constant-velocity model
    kinematic_position_std_m: float = 0.004  # leg kinematics per update (encoders, links, compliance)
    contact_velocity_std_mps: float = 0.03  # zero velocity of a contact point (rolling, micro-slip)
    ground_height_m: float | None = 0.0  # ground plane; None: height is odometry too (drifts)
    ground_std_m: float = 0.003
    contact_height_tol_m: float | None = 0.04  # flagged contacts this far above the ground are ignored
    velocity_gate_mps: float = 0.3  # per-foot zero-velocity innovations beyond this are down-weighted
    init_position_std_m: float = 0.01
    init_velocity_std_mps: float = 0.05
    correction_rate_tau_s: float = 0.02  # low-pass of the velocity-correction rate (tilt aiding)


class LegKinematicsOdometry:
    """Base position/velocity from leg kinematics and the accelerometer (a 2-state KF per world axis).

    Per axis, state ``[p, v]``. Predict: ``p += v dt + a dt²/2``, ``v += a dt`` with
    ``a = R̂ a_m − g``. Correct with two measurements (H = I): the base velocity implied by
    the stance feet's zero contact velocity (Huber-weighted mean over feet) and the base
    position implied by their anchors (mean of ``anchor_i − R̂ fk_i``). Anchors: laid at
    touchdown where the current position measurement puts the foot (x/y; z on the ground
    plane when known), re-levelled at contact switches so that measurement is continuous,
    slid with the sole's rolling contact point. Foot order: :attr:`foot_names`.
    """

    def __init__(self, robot: RobotModel, params: LegOdometryParams | None = None):
        self.params = params or LegOdometryParams()
        self.kinematics = LegKinematics(robot)
        self.foot_names = self.kinematics.foot_names
        self.n_feet = self.kinematics.n_feet
        self._pos = [0.0, 0.0, 0.0]
        self._vel = [0.0, 0.0, 0.0]
        self._cov = [[0.0, 0.0, 0.0] for _ in range(3)]  # per axis: pp, pv, vv
        self._anchors = [[0.0, 0.0, 0.0] for _ in range(self.n_feet)]
        self._anchored = [False] * self.n_feet
        self._rate = [0.0, 0.0, 0.0]  # low-passed velocity correction / dt (world)
        self._pending_dt = 0.0  # time predicted since the last correction
        self._position_pending = False
        self.reset(np.zeros(3))

    # -------------------------------------------------------------- state
    @property
    def position_m(self) -> FloatArray:
        return np.array(self._pos)

    @property
    def velocity_mps(self) -> FloatArray:
        return np.array(self._vel)

    @property
    def anchors_m(self) -> FloatArray:
        """World anchor of each foot (meaningful where :attr:`anchored`)."""
        return np.array(self._anchors)

    @property
    def anchored(self) -> BoolArray:
        return np.array(self._anchored, dtype=bool)

    @property
    def correction_rate_mps2(self) -> FloatArray:
        """Low-passed rate of the kinematic velocity corrections: acceleration the accelerometer missed."""
        return np.array(self._rate)

    def position_std_m(self) -> FloatArray:
        return np.sqrt([c[0] for c in self._cov])

    def reset(self, position_m: FloatArray | None, velocity_mps: FloatArray | None = None) -> None:
        """Restart at ``position_m`` (None: from the first stance kinematics, x = y = 0, feet on the ground)."""
        p = self.params
        self._position_pending = position_m is None
        self._pos = [0.0, 0.0, 0.0] if position_m is None else [float(c) for c in position_m]
        self._vel = [0.0, 0.0, 0.0] if velocity_mps is None else [float(c) for c in velocity_mps]
        self._cov = [[p.init_position_std_m ** 2, 0.0, p.init_velocity_std_mps ** 2] for _ in range(3)]
        self._anchored = [False] * self.n_feet
        self._rate = [0.0, 0.0, 0.0]
        self._pending_dt = 0.0
        self.kinematics.reset()

    # -------------------------------------------------------------- contacts
    def _position_measurement(self, feet: list[int], rel_w: list[Vec3]) -> list[float]:
        """Base position implied by the anchors of ``feet``: mean of ``anchor_i − R̂ fk_i``."""
        x = y = z = 0.0
        for i in feet:
            a, r = self._anchors[i], rel_w[i]
            x += a[0] - r[0]
            y += a[1] - r[1]
            z += a[2] - r[2]
        k = 1.0 / len(feet)
        return [x * k, y * k, z * k]

    def _switch_contacts(self, active: list[bool], rel_w: list[Vec3]) -> None:
        """Lay anchors of touching-down feet, drop lifted ones, keep the position measurement continuous."""
        p = self.params
        old = [i for i in range(self.n_feet) if self._anchored[i]]
        new = [i for i in range(self.n_feet) if active[i]]
        before = self._position_measurement(old, rel_w) if old else list(self._pos)
        for i in new:
            if not self._anchored[i]:
                anchor = [before[ax] + rel_w[i][ax] for ax in range(3)]
                if p.ground_height_m is not None:
                    anchor[2] = p.ground_height_m + self.kinematics.ground_offset_m[i]
                self._anchors[i] = anchor
        if old and new:
            after = self._position_measurement(new, rel_w)
            n_shift = 2 if p.ground_height_m is not None else 3  # the ground fixes anchor heights
            for i in new:
                for ax in range(n_shift):
                    self._anchors[i][ax] += before[ax] - after[ax]
        self._anchored = list(active)

    # -------------------------------------------------------------- filter
    def update(self, dt_s: float, accel_world_mps2, feet: FootKinematics, contact) -> None:
        """One tick: :meth:`predict` then :meth:`correct`."""
        self.predict(dt_s, accel_world_mps2)
        self.correct(feet, contact)

    def predict(self, dt_s: float, accel_world_mps2) -> None:
        """Integrate ``accel_world_mps2`` = R̂ a_m − g over ``dt_s`` (None: constant velocity, inflated noise)."""
        p = self.params
        pos, vel = self._pos, self._vel
        if accel_world_mps2 is not None:
            q_acc = p.accel_noise_density_mps2_rthz ** 2
            h = 0.5 * dt_s * dt_s
            ax, ay, az = accel_world_mps2[0], accel_world_mps2[1], accel_world_mps2[2]
            pos[0] += vel[0] * dt_s + ax * h
            pos[1] += vel[1] * dt_s + ay * h
            pos[2] += vel[2] * dt_s + az * h
            vel[0] += ax * dt_s
            vel[1] += ay * dt_s
            vel[2] += az * dt_s
        else:
            q_acc = p.no_imu_accel_density_mps2_rthz ** 2
            pos[0] += vel[0] * dt_s
            pos[1] += vel[1] * dt_s
            pos[2] += vel[2] * dt_s
        q_pp, q_pv, q_vv = q_acc * dt_s ** 3 / 3.0, q_acc * dt_s ** 2 / 2.0, q_acc * dt_s
        for c in self._cov:
            pp, pv, vv = c
            c[0] = pp + dt_s * (2.0 * pv + dt_s * vv) + q_pp
            c[1] = pv + dt_s * vv + q_pv
            c[2] = vv + q_vv
        self._pending_dt += dt_s

    def correct(self, feet: FootKinematics, contact) -> None:
        """Correct with the feet flagged in ``contact`` (kinematics from :meth:`LegKinematics.compute`)."""
        p = self.params
        pos, vel = self._pos, self._vel
        dt_s = self._pending_dt
        self._pending_dt = 0.0
        if dt_s <= 0.0:
            return

        # Feet: base → contact point (world axes), and the base velocity if that point is still.
        rel_w = feet.point_w_m
        vel_w = [(-x, -y, -z) for x, y, z in feet.point_vel_w_mps]
        if self.kinematics.flat_feet:
            for i in range(self.n_feet):
                if self._anchored[i]:
                    sx, sy, sz = feet.slide_w(i)
                    anchor = self._anchors[i]
                    anchor[0] += sx
                    anchor[1] += sy
                    anchor[2] += sz

        active = [bool(c) for c in contact]
        ground = p.ground_height_m
        offsets = self.kinematics.ground_offset_m
        if self._position_pending and any(active):
            stance = [i for i in range(self.n_feet) if active[i]]
            pos[0] = pos[1] = 0.0
            pos[2] = sum((ground or 0.0) + offsets[i] - rel_w[i][2] for i in stance) / len(stance)
            self._position_pending = False
        if p.contact_height_tol_m is not None and ground is not None:
            for i in range(self.n_feet):
                if active[i] and pos[2] + rel_w[i][2] - offsets[i] - ground > p.contact_height_tol_m:
                    active[i] = False
        if active != self._anchored:
            self._switch_contacts(active, rel_w)
        stance = [i for i in range(self.n_feet) if active[i]]
        if not stance:
            decay = 1.0 - dt_s / (p.correction_rate_tau_s + dt_s)
            self._rate = [r * decay for r in self._rate]
            return

        # Measurements: position from the anchors, velocity from zero contact velocity (Huber-weighted).
        m = len(stance)
        y_pos = self._position_measurement(stance, rel_w)
        inv_gate2 = 1.0 / p.velocity_gate_mps ** 2
        w_sum = yvx = yvy = yvz = 0.0
        for i in stance:
            vx, vy, vz = vel_w[i]
            ex, ey, ez = vx - vel[0], vy - vel[1], vz - vel[2]
            w = 1.0 / max(1.0, (ex * ex + ey * ey + ez * ez) * inv_gate2)
            w_sum += w
            yvx += w * vx
            yvy += w * vy
            yvz += w * vz
        y_vel = (yvx / w_sum, yvy / w_sum, yvz / w_sum)
        r_vel = p.contact_velocity_std_mps ** 2 / w_sum
        r_pos_xy = p.kinematic_position_std_m ** 2 / m
        r_pos_z = r_pos_xy + (p.ground_std_m ** 2 / m if ground is not None else 0.0)

        # Per-axis update with H = I (2×2, closed form).
        alpha = dt_s / (p.correction_rate_tau_s + dt_s)
        for ax in range(3):
            c = self._cov[ax]
            pp, pv, vv = c
            s_pp = pp + (r_pos_xy if ax < 2 else r_pos_z)
            s_vv = vv + r_vel
            inv_det = 1.0 / (s_pp * s_vv - pv * pv)
            k_pp = (pp * s_vv - pv * pv) * inv_det
            k_pv = (pv * s_pp - pp * pv) * inv_det
            k_vp = (pv * s_vv - vv * pv) * inv_det
            k_vv = (vv * s_pp - pv * pv) * inv_det
            ep, ev = y_pos[ax] - pos[ax], y_vel[ax] - vel[ax]
            pos[ax] += k_pp * ep + k_pv * ev
            dv = k_vp * ep + k_vv * ev
            vel[ax] += dv
            c[0] = (1.0 - k_pp) * pp - k_pv * pv
            c[1] = (1.0 - k_pp) * pv - k_pv * vv
            c[2] = (1.0 - k_vv) * vv - k_vp * pv
            self._rate[ax] += (dv / dt_s - self._rate[ax]) * alpha
