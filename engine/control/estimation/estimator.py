"""Whole-body state estimator (paper Sec. 7.2): IMU orientation EKF + leg-kinematic odometry.

:class:`StateEstimator` runs once per 500 Hz control tick and returns a pinocchio-convention
:class:`RobotState` (base pose and base-frame twist estimated, joints as measured); in
``mode="truth"`` it passes the simulator's ground truth through unchanged. Its parts:

* :class:`ImuEkf` — error-state EKF on the base orientation (Solà 2015, local error
  ``R = R̂ Exp(δθ)``). Nominal state: quaternion ``q`` (world ← base) and gyro bias ``b_g``;
  error state ``[δθ, δb_g]``, 6×6 covariance. The nominal attitude is integrated with the
  bias-corrected gyro every tick; the covariance catches up at each correction with the
  exact interval transition ``[[ΔRᵀ, −I T], [0, I]]``. Corrections: (a) the gravity
  direction, a 2-D measurement of the world-frame tilt error, its noise grown with
  ``| |a| − g |``, skipped beyond a gate (impacts, free fall), Huber-weighted on its
  Mahalanobis distance; (b) stance feet do not spin about the ground normal (flat soles
  lying flat; or the rigid fit of ≥ 2 point feet), which makes the vertical gyro bias
  observable. Yaw itself has no absolute reference (no magnetometer or vision): it
  random-walks with the gyro noise and the residual bias error (≈0.1–0.4° per 5 s in the
  tests, with a 0.3 °/s turn-on bias) and is never pulled back.
* :class:`LegKinematicsOdometry` — per world axis a 2-state (position, velocity) Kalman
  filter: an isotropic noise model decouples the axes, so the gains are closed-form 2×2.
  Predicted with the accelerometer (rotated to world, gravity removed); corrected with the
  base velocity implied by the zero velocity of the stance contact points,
  ``v = −(ω × r_i + R̂ J_i q̇)``, and the base position implied by the stance feet's world
  anchors, ``p = anchor_i − r_i`` (``r_i = R̂ fk_i(q)``). An anchor is laid at touchdown so
  that it agrees with the current position measurement (no innovation change), and the
  anchors are re-levelled at every contact switch so that measurement is continuous: no
  jumps at touchdown or lift-off. With a ground plane, anchor heights are the plane's
  (absolute base height); without, height is odometry like x/y. A sole's contact point is a
  soft-min of its corners (centre when flat, moving continuously to the heel/toe or an edge
  as the foot rolls) and its anchor slides with it. Flagged contacts far above the ground
  are ignored; zero-velocity outliers (slip) are Huber-weighted.
* :class:`LegKinematics` — one pinocchio forward pass per update with the base at the
  origin and the estimated attitude and angular rate, so placements and velocities come out
  in the world axes the filters need.

Tilt aiding: the accelerometer's direction is corrupted by the base's own acceleration (up
to 15° on G1 under a 40 N push). With ``linear_accel_compensation`` (default) the gravity
update removes the linear acceleration the odometry explains (accelerometer + its low-passed
kinematic velocity corrections), so roll/pitch are corrected by what the legs see as
unexplained acceleration — the loosely coupled form of a kinematics-aided inertial filter.
Its gain is capped (time constant ≥ 0.25 s) to stay slower than the velocity loop. A
horizontal accelerometer bias b_a is indistinguishable from tilt (error ≈ b_a/g rad).

Rates: the attitude and the base position/velocity are propagated with the IMU every tick;
the measurement updates run every ``correction_divider`` ticks (default 4, i.e. 125 Hz: leg
kinematics + odometry correction on one tick, the EKF correction on the next, two inertial-only
ticks), which keeps the Python cost per tick low (G1: ≈35–45 µs median, ≈55–70 µs on the
update ticks; divider 2 ≈ 50–60 µs every tick; divider 1 ≈ 85–90 µs) at no measurable accuracy
cost standing or in the kinematic swing test (see tests/test_estimator.py).

MuJoCo note: ``data.sensordata`` is computed inside ``mj_step`` before integration, so a
sample read after a step describes the state one physics step earlier (gyro ω(t − dt), and
the accelerometer the acceleration that took v(t − dt) to v(t)). The filters treat a sample
as the motion over the last tick, which is exactly that.

Small dense algebra (2×2, 3×3) is written out in scalars: numpy's per-call overhead
dominates at this size and the tick budget is tens of microseconds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from engine.constants import GRAVITY_MPS2
from engine.control.controller import RobotState
from engine.robot.model import RobotModel

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

from engine.imu import ImuSample
from engine.control.estimation.ekf import ImuEkf, ImuEkfParams
from engine.control.estimation.leg_kinematics import FootKinematics, Vec3
from engine.control.estimation.odometry import LegKinematicsOdometry, LegOdometryParams
from engine.control.estimation.quaternion import _yaw_of, quat_to_rotation, wxyz_from_xyzw, xyzw_from_wxyz


# ----------------------------------------------------------------------------- combined


@dataclass(frozen=True)
class EstimatorParams:
    """Parameters of :class:`StateEstimator`."""

    imu: ImuEkfParams = field(default_factory=ImuEkfParams)
    legs: LegOdometryParams = field(default_factory=LegOdometryParams)
    # Remove the linear acceleration the odometry explains before taking gravity's direction.
    linear_accel_compensation: bool = True
    compensated_accel_dynamic_std_mps2: float = 0.3  # gravity-update σ when compensating
    compensated_tilt_min_time_constant_s: float = 0.25  # tilt loop slower than the velocity loop
    stance_yaw_rate: bool = True  # flat feet only
    flat_foot_tilt_rad: float = 0.02  # stance soles tilted more than this (rocking on an edge) may spin
    # Roll/pitch start from the mean of the first usable accelerometer samples (1: the first one);
    # until then the reset orientation is reported and the odometry waits.
    init_accel_samples: int = 25
    nominal_dt_s: float = 0.002
    max_dt_s: float = 0.02  # longer gaps are integrated as this (and counted)
    # Measurement updates (leg kinematics, EKF corrections) every this many ticks, on consecutive
    # ticks when ≥ 2; the attitude and base position/velocity are propagated with the IMU every
    # tick. Contact flags take effect at the next leg update (≤ divider ticks late).
    correction_divider: int = 4


class StateEstimator:
    """The robot state the controller sees: estimated from IMU + encoders, or the simulator's truth.

    Call :meth:`update` once per control tick; ``contact`` is one flag per foot in
    :attr:`foot_names` order (bipeds: left, right — the gait reference's stance flags)::

        est = StateEstimator(robot)                  # mode="truth" passes the simulator's state
        imu = MujocoImu(robot.mj_model, noise=None)  # in simulation
        est.reset(sim.state())                       # known start pose (None: on the ground at x = y = 0)
        state = est.update(sim.time_s, imu.read(sim.data), sim.joint_positions(), sim.joint_velocities(),
                           ref.contact)              # every tick, before the controller

    During the first ``init_accel_samples`` ticks the reset pose is reported while roll/pitch
    are averaged from the accelerometer.
    """

    def __init__(self, robot: RobotModel, mode: str = "estimated", params: EstimatorParams | None = None):
        if mode not in ("estimated", "truth"):
            raise ValueError(f"mode must be 'estimated' or 'truth', not {mode!r}")
        self.robot = robot
        self.mode = mode
        self.params = params or EstimatorParams()
        if self.params.correction_divider < 1:
            raise ValueError("correction_divider must be ≥ 1")
        gravity = float(-robot.mj_model.opt.gravity[2])
        self.gravity_mps2 = gravity if gravity > 0.0 else GRAVITY_MPS2
        imu_params = self.params.imu
        if self.params.linear_accel_compensation:
            imu_params = replace(imu_params, accel_dynamic_std_mps2=self.params.compensated_accel_dynamic_std_mps2,
                                 tilt_min_time_constant_s=self.params.compensated_tilt_min_time_constant_s)
        self.ekf = ImuEkf(imu_params, self.gravity_mps2)
        self.odometry = LegKinematicsOdometry(robot, self.params.legs)
        self.foot_names = self.odometry.foot_names
        self.n_joints = robot.n_joints
        self.rejected_imu_samples = 0
        self.rejected_joint_samples = 0
        self.clamped_dt = 0
        self.clock_resyncs = 0
        self._cos_flat = math.cos(self.params.flat_foot_tilt_rad)
        self.reset(None)

    def reset(self, state: RobotState | None) -> None:
        """Restart. Position, velocity and yaw from ``state`` (None: x = y = 0 with the stance feet
        on the ground, yaw 0); roll/pitch from the first usable accelerometer sample."""
        self._t_prev_s: float | None = None
        self._stale_ticks = 0
        self._last_gyro: list[float] = [0.0, 0.0, 0.0]
        self._has_gyro = False
        self._init_sum = [0.0, 0.0, 0.0]
        self._init_count = 0
        self._tick = 0  # ticks since the last measurement update
        self._interval_s = 0.0
        self._acc_sum = [0.0, 0.0, 0.0]  # Σ R̂ a_m over the interval (world specific force)
        self._acc_count = 0
        self._acc_dev = 0.0  # max | |a_m| − g | over the interval
        self._spin: tuple[Vec3 | None, float | None] = (None, None)  # stance spin for the next EKF update
        self._joint_q: FloatArray | None = None if state is None else np.array(state.q[7:], dtype=float)
        self.ekf.initialized = False
        if state is None:
            self._init_yaw_rad, init_rot = 0.0, np.eye(3)
            self.odometry.reset(None)
        else:
            init_rot = quat_to_rotation(wxyz_from_xyzw(state.q[3:7]))  # pinocchio q: x, y, z, w
            self._init_yaw_rad = _yaw_of(init_rot)
            self.odometry.reset(np.array(state.q[:3], dtype=float), init_rot.dot(np.asarray(state.v[:3], dtype=float)))
        self.ekf.set_rotation(init_rot)  # until the first usable accelerometer sample
        if state is not None:
            # A known starting pose (the robot is placed, as on a stand): start fused at once
            # rather than reporting a frozen pose while the first samples average in.
            self.ekf.initialize(init_rot.T @ np.array([0.0, 0.0, self.gravity_mps2]), self._init_yaw_rad)
        self._last: RobotState | None = state

    @property
    def last_state(self) -> RobotState | None:
        return self._last

    # -------------------------------------------------------------- update
    def update(self, t_s: float, sensors: ImuSample | None, joint_q: FloatArray, joint_qd: FloatArray,
               contact, truth: RobotState | None = None) -> RobotState:
        """Fuse one tick of measurements; returns the state in pinocchio conventions."""
        if self.mode == "truth":
            if truth is None:
                raise ValueError("truth mode needs the ground-truth state")
            self._last = RobotState(float(truth.t_s), np.array(truth.q, dtype=float), np.array(truth.v, dtype=float))
            return RobotState(self._last.t_s, self._last.q.copy(), self._last.v.copy())

        p = self.params
        dt = self._step_dt(t_s)
        values = None if sensors is None else sensors.values()
        if sensors is not None and values is None:
            self.rejected_imu_samples += 1
        jq, jqd = self._clean_joints(joint_q, joint_qd)
        flags = [bool(c) for c in (contact.tolist() if isinstance(contact, np.ndarray) else contact)]
        if len(flags) != self.odometry.n_feet:
            raise ValueError(f"contact has {len(flags)} flags, expected {self.odometry.n_feet} ({self.foot_names})")

        ekf, odo = self.ekf, self.odometry
        accel: list[float] | None = None
        if values is not None:
            gyro, accel = values
            self._last_gyro, self._has_gyro = gyro, True
            if not ekf.initialized:
                self._accumulate_initial_tilt(accel)
        else:
            gyro = self._last_gyro  # zero-order hold through a dropped sample
        bias = ekf._bias
        if dt > 0.0 and ekf.initialized:
            # Every tick: inertial propagation of the attitude and of the base position/velocity.
            accel_w = None
            if accel is not None:
                (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = ekf.rotation_rows()  # the sample's attitude
                ax, ay, az = accel
                g = self.gravity_mps2
                accel_w = (r00 * ax + r01 * ay + r02 * az, r10 * ax + r11 * ay + r12 * az,
                           r20 * ax + r21 * ay + r22 * az - g)
                self._acc_sum[0] += accel_w[0]
                self._acc_sum[1] += accel_w[1]
                self._acc_sum[2] += accel_w[2] + g
                self._acc_count += 1
                dev = abs(math.sqrt(ax * ax + ay * ay + az * az) - g)
                if dev > self._acc_dev:
                    self._acc_dev = dev
            if self._has_gyro:
                ekf.propagate_nominal(gyro, dt)
            odo.predict(dt, accel_w)
            self._interval_s += dt
            # Measurement updates: legs then attitude on the same tick (divider 1), or on
            # consecutive ticks of each cycle (divider ≥ 2), so no tick carries both.
            divider = p.correction_divider
            phase = self._tick % divider if divider > 1 else 0
            self._tick += 1
            if phase == 0:
                self._correct_legs(gyro, flags, jq, jqd)
            if phase == (1 if divider > 1 else 0):
                self._correct_attitude()
                bias = ekf._bias
        omega_b = (gyro[0] - bias[0], gyro[1] - bias[1], gyro[2] - bias[2]) if self._has_gyro else (0.0, 0.0, 0.0)

        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = ekf.rotation_rows()
        vx, vy, vz = odo._vel
        q = np.empty(7 + self.n_joints)
        q[:7] = (*odo._pos, *xyzw_from_wxyz(ekf.quat_wxyz))  # pinocchio order at the state's edge
        q[7:] = jq
        v = np.empty(6 + self.n_joints)
        v[:6] = (r00 * vx + r10 * vy + r20 * vz, r01 * vx + r11 * vy + r21 * vz, r02 * vx + r12 * vy + r22 * vz, *omega_b)
        v[6:] = jqd
        t_out = float(t_s)
        if not math.isfinite(t_out):
            t_out = self._t_prev_s if self._t_prev_s is not None else 0.0
        self._last = RobotState(t_out, q, v)
        return self._last

    def _correct_legs(self, gyro: list[float], flags: list[bool], jq: FloatArray, jqd: FloatArray) -> None:
        """Leg kinematics: odometry correction, and the stance spin for the next attitude update."""
        ekf, odo = self.ekf, self.odometry
        bias = ekf._bias
        omega_b = (gyro[0] - bias[0], gyro[1] - bias[1], gyro[2] - bias[2]) if self._has_gyro else (0.0, 0.0, 0.0)
        feet = odo.kinematics.compute(jq, jqd, ekf.quat_wxyz, omega_b)
        odo.correct(feet, flags)
        self._spin = self._stance_spin(feet, flags) if self.params.stance_yaw_rate else (None, None)

    def _correct_attitude(self) -> None:
        """EKF correction with the interval's accelerometer samples and the latest stance spin."""
        ekf = self.ekf
        n = self._acc_count
        if n:
            if self.params.linear_accel_compensation:
                # R̂ a_m minus the explained linear acceleration (R̂ a_m − g e_z + the legs' corrections).
                rx, ry, rz = self.odometry._rate
                force_w = (-rx, -ry, self.gravity_mps2 - rz)
            else:
                force_w = (self._acc_sum[0] / n, self._acc_sum[1] / n, self._acc_sum[2] / n)
            # The accelerometer argument only feeds the | |a| − g | gate: the worst deviation seen.
            foot_omega, yaw_std = self._spin
            ekf.correct(self._interval_s, (0.0, 0.0, self.gravity_mps2 + self._acc_dev), force_w, foot_omega, yaw_std)
        else:
            ekf.propagate_covariance()
        self._spin = (None, None)
        self._interval_s = 0.0
        self._acc_sum = [0.0, 0.0, 0.0]
        self._acc_count = 0
        self._acc_dev = 0.0

    def _stance_spin(self, feet: FootKinematics, flags: list[bool]) -> tuple[Vec3 | None, float | None]:
        """Estimated spin of the stance contacts (world angular velocity, only z is observed) and its 1σ.

        Flat soles: the mean angular velocity of the stance soles that lie flat (a sole rocking
        on an edge can twist). Point feet (≥ 2 in stance): the vertical rate of the best rigid
        fit of the contact points' velocities, ``Σ (u_i − ū)·(e_z × Δr_i) / Σ |Δr_i,xy|²``.
        """
        odo = self.odometry
        std = self.params.imu.stance_yaw_rate_std_radps
        stance = [i for i in range(odo.n_feet) if flags[i] and odo._anchored[i]]
        if odo.kinematics.flat_feet:
            stance = [i for i in stance if feet.sole_up_cos[i] > self._cos_flat]
            n = len(stance)
            if n == 0:
                return None, None
            if n == 1:
                return feet.omega_w(stance[0]), std
            wx = wy = wz = 0.0
            for i in stance:
                w = feet.omega_w(i)
                wx, wy, wz = wx + w[0], wy + w[1], wz + w[2]
            return (wx / n, wy / n, wz / n), std / math.sqrt(n)
        n = len(stance)
        if n < 2:
            return None, None
        rx = sum(feet.point_w_m[i][0] for i in stance) / n
        ry = sum(feet.point_w_m[i][1] for i in stance) / n
        ux = sum(feet.point_vel_w_mps[i][0] for i in stance) / n
        uy = sum(feet.point_vel_w_mps[i][1] for i in stance) / n
        num = den = 0.0
        for i in stance:
            dx, dy = feet.point_w_m[i][0] - rx, feet.point_w_m[i][1] - ry
            num += dx * (feet.point_vel_w_mps[i][1] - uy) - dy * (feet.point_vel_w_mps[i][0] - ux)
            den += dx * dx + dy * dy
        if den < 0.05 ** 2:
            return None, None
        return (0.0, 0.0, num / den), self.params.legs.contact_velocity_std_mps / math.sqrt(den)

    def _accumulate_initial_tilt(self, accel: list[float]) -> None:
        """Average plausible (≈ 1 g) samples; initialise the EKF from their mean."""
        ax, ay, az = accel
        if abs(math.sqrt(ax * ax + ay * ay + az * az) - self.gravity_mps2) > self.ekf.params.accel_gate_mps2:
            return
        s = self._init_sum
        self._init_sum = [s[0] + ax, s[1] + ay, s[2] + az]
        self._init_count += 1
        if self._init_count >= max(1, self.params.init_accel_samples):
            self.ekf.initialize(np.array(self._init_sum) / self._init_count, self._init_yaw_rad)

    def _step_dt(self, t_s: float) -> float:
        t = float(t_s)
        if not math.isfinite(t):
            return 0.0
        if self._t_prev_s is None:
            self._t_prev_s = t
            return self.params.nominal_dt_s
        dt = t - self._t_prev_s
        if dt <= 0.0:  # repeated or out-of-order tick: no propagation
            self._stale_ticks += 1
            if self._stale_ticks >= 3 and dt < 0.0:  # the clock restarted (e.g. a simulation reset)
                self._t_prev_s = t
                self.clock_resyncs += 1
            return 0.0
        self._stale_ticks = 0
        self._t_prev_s = t
        if dt > self.params.max_dt_s:
            self.clamped_dt += 1
            return self.params.max_dt_s
        return dt

    def _clean_joints(self, joint_q: FloatArray, joint_qd: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Non-finite encoder values are replaced by the last good position / zero velocity."""
        jq = joint_q if type(joint_q) is np.ndarray and joint_q.dtype == np.float64 else np.asarray(joint_q, dtype=float)
        jqd = joint_qd if type(joint_qd) is np.ndarray and joint_qd.dtype == np.float64 else np.asarray(joint_qd, dtype=float)
        n = self.n_joints
        if jq.shape != (n,) or jqd.shape != (n,):
            raise ValueError(f"expected {n} joint positions and velocities")
        if not math.isfinite(jq.dot(jq) + jqd.dot(jqd)):
            self.rejected_joint_samples += 1
            prev = self._joint_q if self._joint_q is not None else self.robot.q_standing[7:]
            jq = np.where(np.isfinite(jq), jq, prev)
            jqd = np.where(np.isfinite(jqd), jqd, 0.0)
        if self._joint_q is None:
            self._joint_q = jq.copy()
        else:
            self._joint_q[:] = jq
        return jq, jqd

    # -------------------------------------------------------------- diagnostics
    def orientation_std_rad(self) -> FloatArray:
        """1σ of the orientation error (base-frame axes)."""
        return np.sqrt(np.diag(self.ekf.cov)[:3])

    def position_std_m(self) -> FloatArray:
        return self.odometry.position_std_m()
