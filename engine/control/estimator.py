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

import mujoco
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from engine.control.controller import RobotState
from engine.robot.model import RobotModel

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

__all__ = [
    "EstimatorParams",
    "FootKinematics",
    "ImuEkf",
    "ImuEkfParams",
    "ImuNoise",
    "ImuSample",
    "LegKinematics",
    "LegKinematicsOdometry",
    "LegOdometryParams",
    "MujocoImu",
    "StateEstimator",
    "quat_to_rotation",
    "rotation_to_quat",
]

MAX_GYRO_RADPS = 35.0  # beyond any legged robot's base rate: a broken sample
MAX_ACCEL_MPS2 = 160.0  # 16 g


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


# ----------------------------------------------------------------------------- IMU


@dataclass(frozen=True)
class ImuSample:
    """One IMU sample in the base frame: angular rate and specific force (reads +g·up at rest)."""

    gyro_radps: FloatArray
    accel_mps2: FloatArray

    def values(self) -> tuple[list[float], list[float]] | None:
        """(gyro, accel) as python floats, or None when the sample is garbage: wrong shape,
        NaN/Inf, or beyond plausible ranges (saturated or corrupted)."""
        g, a = self.gyro_radps, self.accel_mps2
        try:
            gyro = g.tolist() if isinstance(g, np.ndarray) else [float(c) for c in g]
            accel = a.tolist() if isinstance(a, np.ndarray) else [float(c) for c in a]
            gx, gy, gz = gyro
            ax, ay, az = accel
        except (TypeError, ValueError):
            return None
        lim_g, lim_a = MAX_GYRO_RADPS, MAX_ACCEL_MPS2
        # NaN fails every comparison, so the bounds reject it too; Inf fails the bounds.
        if (-lim_g < gx < lim_g and -lim_g < gy < lim_g and -lim_g < gz < lim_g
                and -lim_a < ax < lim_a and -lim_a < ay < lim_a and -lim_a < az < lim_a):
            return [float(gx), float(gy), float(gz)], [float(ax), float(ay), float(az)]
        return None

    def is_valid(self) -> bool:
        return self.values() is not None


@dataclass(frozen=True)
class ImuNoise:
    """Additive IMU errors for simulation: white-noise densities, constant biases, bias random walk."""

    gyro_noise_density_radps_rthz: float = 3e-4  # ≈ BMI088-class MEMS
    gyro_bias_radps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_bias_walk_radps2_rthz: float = 0.0
    accel_noise_density_mps2_rthz: float = 2e-3
    accel_bias_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0)


class MujocoImu:
    """Reads the model's ``imu_gyro``/``imu_accel`` sensors as an :class:`ImuSample` (base frame).

    With ``noise``, white noise (density / √dt per sample), constant biases and an optional
    bias random walk are added from a seeded RNG. :meth:`truth_quat_xyzw` reads the
    ``imu_quat`` ground truth — for evaluation only, never feed it to the filter.
    """

    def __init__(self, mj_model: mujoco.MjModel, noise: ImuNoise | None = None, seed: int = 0, site: str = "imu"):
        self.gyro_adr = int(mj_model.sensor("imu_gyro").adr[0])
        self.accel_adr = int(mj_model.sensor("imu_accel").adr[0])
        self.quat_adr = int(mj_model.sensor("imu_quat").adr[0])
        self.dt_s = float(mj_model.opt.timestep)
        wxyz = np.array(mj_model.site(site).quat, dtype=float)
        rot = quat_to_rotation((wxyz[1], wxyz[2], wxyz[3], wxyz[0]))
        self.base_from_site = None if np.allclose(rot, np.eye(3)) else rot  # sensors read in the site frame
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.gyro_bias_radps = np.array(noise.gyro_bias_radps if noise else (0.0, 0.0, 0.0), dtype=float)

    def read(self, data: mujoco.MjData) -> ImuSample:
        gyro = np.array(data.sensordata[self.gyro_adr:self.gyro_adr + 3], dtype=float)
        accel = np.array(data.sensordata[self.accel_adr:self.accel_adr + 3], dtype=float)
        if self.base_from_site is not None:
            gyro, accel = self.base_from_site @ gyro, self.base_from_site @ accel
        n = self.noise
        if n is not None:
            per_sample = 1.0 / math.sqrt(self.dt_s)
            if n.gyro_bias_walk_radps2_rthz > 0.0:
                self.gyro_bias_radps += self.rng.normal(0.0, n.gyro_bias_walk_radps2_rthz * math.sqrt(self.dt_s), 3)
            gyro += self.gyro_bias_radps + self.rng.normal(0.0, n.gyro_noise_density_radps_rthz * per_sample, 3)
            accel += np.asarray(n.accel_bias_mps2) + self.rng.normal(0.0, n.accel_noise_density_mps2_rthz * per_sample, 3)
        return ImuSample(gyro, accel)

    def truth_quat_xyzw(self, data: mujoco.MjData) -> FloatArray:
        wxyz = data.sensordata[self.quat_adr:self.quat_adr + 4]
        return np.array([wxyz[1], wxyz[2], wxyz[3], wxyz[0]], dtype=float)


# ----------------------------------------------------------------------------- orientation EKF


@dataclass(frozen=True)
class ImuEkfParams:
    """Noise model and gating of :class:`ImuEkf` (densities per √Hz, 1σ, SI units)."""

    gyro_noise_density_radps_rthz: float = 3e-4  # white rate noise
    gyro_bias_walk_radps2_rthz: float = 2e-5  # bias random walk
    accel_noise_density_mps2_rthz: float = 2e-3  # white specific-force noise
    # Non-gravitational acceleration left in the gravity measurement, per sample: the base's
    # own acceleration (uncompensated) or the compensation's error (compensated).
    accel_dynamic_std_mps2: float = 1.0
    accel_deviation_gain: float = 5.0  # σ grows by this × | |a| − g |
    accel_gate_mps2: float = 3.0  # | |a| − g | above this: no gravity update (impact, free fall)
    innovation_gate_chi2: float = 9.21  # Huber-weight gravity updates beyond this (χ²₂, 99 %)
    tilt_min_time_constant_s: float = 0.0  # gravity-update gain ≤ dt/τ (0: no cap); see EstimatorParams
    stance_yaw_rate_std_radps: float = 0.03  # stance-sole spin about the ground normal, per update
    init_tilt_std_rad: float = 0.02  # roll/pitch from the initial accelerometer average
    init_yaw_std_rad: float = 0.01  # the given initial yaw
    init_gyro_bias_std_radps: float = 0.005  # ≈ 0.3 °/s; larger turn-on biases are learned more slowly


def _inv_sym(s: list[list[float]]) -> list[list[float]]:
    """Inverse of a symmetric positive-definite 1×1, 2×2 or 3×3 matrix (closed form)."""
    m = len(s)
    if m == 1:
        return [[1.0 / s[0][0]]]
    if m == 2:
        (a, b), (_, d) = s
        k = 1.0 / (a * d - b * b)
        return [[d * k, -b * k], [-b * k, a * k]]
    (a, b, c), (_, d, e), (_, _, f) = s
    c00, c01, c02 = d * f - e * e, c * e - b * f, b * e - c * d
    k = 1.0 / (a * c00 + b * c01 + c * c02)
    c11, c12, c22 = a * f - c * c, b * c - a * e, a * d - b * b
    return [[c00 * k, c01 * k, c02 * k], [c01 * k, c11 * k, c12 * k], [c02 * k, c12 * k, c22 * k]]


class ImuEkf:
    """Error-state EKF on the base orientation and gyro bias (Solà 2015, Secs. 5–7).

    ``rotation`` is world ← base. Error convention: R = R̂ Exp(δθ) (δθ in the base frame),
    b_g = b̂_g + δb_g; covariance order [δθ, δb_g]. The error-reset Jacobian ``I − [δθ/2]×``
    is taken as identity (δθ ≲ 1e-3 rad per correction). Standalone use: :meth:`propagate`
    per gyro sample, then :meth:`update_gravity` / :meth:`update_stance_yaw_rate` or
    :meth:`correct` for both at once.
    """

    def __init__(self, params: ImuEkfParams | None = None, gravity_mps2: float = 9.81):
        self.params = params or ImuEkfParams()
        self.gravity_mps2 = float(gravity_mps2)
        self.quat_xyzw: Quat = (0.0, 0.0, 0.0, 1.0)
        self._bias = [0.0, 0.0, 0.0]  # gyro bias, rad/s
        self.cov: FloatArray = np.eye(6)
        self.initialized = False
        self.gravity_updates = 0
        self.gravity_skipped = 0
        self.gravity_downweighted = 0
        self._f = np.eye(6)
        self._q_cov: Quat = self.quat_xyzw  # nominal attitude when the covariance was last propagated
        self._pending_dt = 0.0  # time the covariance lags the nominal state
        self._q_dt = -1.0
        self._q_diag = np.zeros((6, 6))
        self._c_dt = -1.0
        self._sigma2_base = 0.0  # gravity-direction variance without the deviation term
        self._gain_cap = 0.0  # σ² ≥ this × (H P Hᵀ) keeps the gain ≤ dt/τ

    # -------------------------------------------------------------- state
    def initialize(self, accel_mps2: FloatArray, yaw_rad: float, gyro_bias_radps: FloatArray | None = None) -> bool:
        """Roll/pitch from one accelerometer sample, yaw given. False (stays uninitialised) if unusable."""
        a = np.asarray(accel_mps2, dtype=float)
        if (a.shape != (3,) or not np.all(np.isfinite(a))
                or abs(float(np.linalg.norm(a)) - self.gravity_mps2) > self.params.accel_gate_mps2):
            return False
        self.set_rotation(_tilt_with_yaw(a, yaw_rad))
        self._bias = [0.0, 0.0, 0.0] if gyro_bias_radps is None else [float(c) for c in gyro_bias_radps]
        p = self.params
        world_cov = np.diag([p.init_tilt_std_rad ** 2] * 2 + [p.init_yaw_std_rad ** 2])
        self.cov = np.zeros((6, 6))
        self.cov[:3, :3] = self.rotation.T.dot(world_cov).dot(self.rotation)  # δθ is in the base frame
        self.cov[3:, 3:] = np.eye(3) * p.init_gyro_bias_std_radps ** 2
        self.initialized = True
        return True

    def set_rotation(self, rot: FloatArray) -> None:
        q = rotation_to_quat(rot)
        self.quat_xyzw = self._q_cov = (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
        self._pending_dt = 0.0

    @property
    def rotation(self) -> FloatArray:
        """World ← base rotation matrix."""
        return quat_to_rotation(self.quat_xyzw)

    def rotation_rows(self) -> Rows:
        return _rot_rows(self.quat_xyzw)

    @property
    def gyro_bias_radps(self) -> FloatArray:
        return np.array(self._bias)

    @property
    def yaw_rad(self) -> float:
        return _yaw_of(self.rotation)

    def angular_velocity_b(self, gyro_radps) -> FloatArray:
        return np.asarray(gyro_radps, dtype=float) - self.gyro_bias_radps

    # -------------------------------------------------------------- filter
    def propagate(self, gyro_radps, dt_s: float) -> None:
        """Nominal and covariance propagation over one gyro sample (see the two parts)."""
        self.propagate_nominal(gyro_radps, dt_s)
        self.propagate_covariance()

    def propagate_nominal(self, gyro_radps, dt_s: float) -> None:
        """q ← q ⊗ Exp((ω_m − b̂) dt). The covariance catches up in :meth:`propagate_covariance`."""
        bx, by, bz = self._bias
        self.quat_xyzw = _quat_step(self.quat_xyzw, (gyro_radps[0] - bx) * dt_s, (gyro_radps[1] - by) * dt_s,
                                    (gyro_radps[2] - bz) * dt_s)
        self._pending_dt += dt_s

    def propagate_covariance(self) -> None:
        """P ← F P Fᵀ + Q over the time since the last call, F = [[ΔRᵀ, −I T], [0, I]].

        ΔR = R̂(t₀)ᵀ R̂(t) is the nominal rotation over the interval T (exact product of the
        per-sample Exp(ω dt)ᵀ); the bias coupling −I T and Q = diag(σ_g² T, σ_bw² T) are exact
        to first order in ωT (T = one or a few control ticks)."""
        t = self._pending_dt
        if t <= 0.0:
            return
        f = self._f
        if t != self._q_dt:
            p = self.params
            self._q_dt = t
            f[0, 3] = f[1, 4] = f[2, 5] = -t
            self._q_diag = np.diag([p.gyro_noise_density_radps_rthz ** 2 * t] * 3
                                   + [p.gyro_bias_walk_radps2_rthz ** 2 * t] * 3)
        x0, y0, z0, w0 = self._q_cov
        dq = _quat_mul((-x0, -y0, -z0, w0), self.quat_xyzw)
        f[:3, :3] = quat_to_rotation(dq).T
        self.cov = f.dot(self.cov).dot(f.T) + self._q_diag
        self._q_cov = self.quat_xyzw
        self._pending_dt = 0.0

    def _inject(self, dx: list[float]) -> None:
        self.quat_xyzw = self._q_cov = _quat_step(self.quat_xyzw, dx[0], dx[1], dx[2])
        b = self._bias
        self._bias = [b[0] + dx[3], b[1] + dx[4], b[2] + dx[5]]

    def correct(self, dt_s: float, accel_mps2=None, specific_force_w_mps2=None, foot_omega_w_radps=None,
                yaw_rate_std_radps: float | None = None) -> bool:
        """One EKF correction with the gravity direction and/or the stance-foot yaw rate.

        ``dt_s`` is the time the measurement covers (one tick, or the averaging interval).

        Gravity (when ``accel_mps2`` is given and passes the gate): the world-frame tilt
        ``y = (z_y, −z_x)/|z| ≈ [R̂ δθ]_xy`` of the specific force ``z`` in world axes —
        ``R̂ a_m`` by default, or ``specific_force_w_mps2`` when the caller has removed the
        base's linear acceleration — so ``H = [R̂_xy, 0]``. Noise grows with ``| |a| − g |``;
        Mahalanobis outliers are Huber-weighted.

        Yaw rate (when ``foot_omega_w_radps`` is given: the stance contacts' angular velocity in
        world axes as the current estimate predicts it, e.g. ``R̂ (ω_m − b̂ + ω_foot/base)`` of a
        flat sole): stance feet do not spin about the ground normal, so its vertical component
        is measured as 0 (1σ ``yaw_rate_std_radps``, default the parameter; Huber beyond 3σ).
        It observes the vertical gyro bias. Returns whether the gravity part was applied.
        """
        p = self.params
        if self._pending_dt > 0.0:
            self.propagate_covariance()
        if dt_s != self._c_dt:
            g = self.gravity_mps2
            self._c_dt = dt_s
            self._sigma2_base = (p.accel_noise_density_mps2_rthz ** 2 / dt_s + p.accel_dynamic_std_mps2 ** 2) / (g * g)
            k_max = min(1.0, dt_s / p.tilt_min_time_constant_s) if p.tilt_min_time_constant_s > 0.0 else 1.0
            self._gain_cap = (1.0 - k_max) / k_max
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = _rot_rows(self.quat_xyzw)
        rows: list[list[float]] = []
        innov: list[float] = []
        noise: list[float] = []
        gravity_used = False
        if accel_mps2 is not None:
            ax, ay, az = accel_mps2[0], accel_mps2[1], accel_mps2[2]
            g = self.gravity_mps2
            deviation = abs(math.sqrt(ax * ax + ay * ay + az * az) - g)
            if specific_force_w_mps2 is None:
                zx, zy = r00 * ax + r01 * ay + r02 * az, r10 * ax + r11 * ay + r12 * az
                zz = r20 * ax + r21 * ay + r22 * az
            else:
                zx, zy, zz = specific_force_w_mps2[0], specific_force_w_mps2[1], specific_force_w_mps2[2]
            norm = math.sqrt(zx * zx + zy * zy + zz * zz)
            if deviation <= p.accel_gate_mps2 and norm > 0.5 * g:  # the comparison also rejects NaN
                gravity_used = True
                rows.append([r00, r01, r02, 0.0, 0.0, 0.0])
                rows.append([r10, r11, r12, 0.0, 0.0, 0.0])
                innov += [zy / norm, -zx / norm]
                sigma2 = self._sigma2_base + (p.accel_deviation_gain * deviation / g) ** 2
                noise += [sigma2, sigma2]
            else:
                self.gravity_skipped += 1
        if foot_omega_w_radps is not None:
            fx, fy, fz = foot_omega_w_radps[0], foot_omega_w_radps[1], foot_omega_w_radps[2]
            # h = e_zᵀ R (ω_m − b + ω_rel): ∂h/∂δθ = (ω × u)ᵀ = R̂ᵀ(ω_f × e_z), ∂h/∂δb = −R̂ᵀ e_z.
            rows.append([r00 * fy - r10 * fx, r01 * fy - r11 * fx, r02 * fy - r12 * fx, -r20, -r21, -r22])
            residual = -fz
            innov.append(residual)
            std = p.stance_yaw_rate_std_radps if yaw_rate_std_radps is None else yaw_rate_std_radps
            var = std * std
            noise.append(max(var, residual * residual / 9.0))  # Huber beyond 3σ: a spinning/slipping foot
        if not rows:
            return False
        h = np.array(rows)
        hp = h.dot(self.cov)  # H P
        s = hp.dot(h.T).tolist()  # H P Hᵀ
        if gravity_used:
            # Gain ≤ dt/τ (tilt_min_time_constant_s): the tilt loop stays slower than the velocity loop.
            sigma2 = max(noise[0], max(s[0][0], s[1][1]) * self._gain_cap)
            a, b, d = s[0][0] + sigma2, s[0][1], s[1][1] + sigma2
            y0, y1 = innov[0], innov[1]
            d2 = (d * y0 * y0 - 2.0 * b * y0 * y1 + a * y1 * y1) / (a * d - b * b)
            if d2 > p.innovation_gate_chi2:  # Huber: inflate the noise of an outlier
                sigma2 *= d2 / p.innovation_gate_chi2
                self.gravity_downweighted += 1
            noise[0] = noise[1] = sigma2
            self.gravity_updates += 1
        for i, r in enumerate(noise):
            s[i][i] += r
        gain_t = np.array(_inv_sym(s)).dot(hp)  # Kᵀ = S⁻¹ H P
        self._inject(np.dot(innov, gain_t).tolist())
        self.cov = self.cov - hp.T.dot(gain_t)
        return gravity_used

    def update_gravity(self, accel_mps2: FloatArray, accel_linear_b_mps2: FloatArray | None = None,
                       dt_s: float = 0.002) -> bool:
        """Gravity-direction correction alone; ``accel_linear_b_mps2`` (base frame) is removed first."""
        a = np.asarray(accel_mps2, dtype=float)
        force_w = None if accel_linear_b_mps2 is None else self.rotation.dot(a - accel_linear_b_mps2)
        return self.correct(dt_s, accel_mps2=a.tolist(), specific_force_w_mps2=force_w)

    def update_stance_yaw_rate(self, gyro_radps: FloatArray, foot_omega_rel_b_radps: FloatArray,
                               n_feet: int = 1, dt_s: float = 0.002) -> None:
        """Stance-foot yaw-rate correction alone; ``foot_omega_rel_b_radps``: the feet's (mean)
        angular velocity relative to the base, base frame (see :meth:`correct`)."""
        omega_b = np.asarray(gyro_radps, dtype=float) - self._bias + np.asarray(foot_omega_rel_b_radps, dtype=float)
        self.correct(dt_s, foot_omega_w_radps=self.rotation.dot(omega_b),
                     yaw_rate_std_radps=self.params.stance_yaw_rate_std_radps / math.sqrt(max(n_feet, 1)))


# ----------------------------------------------------------------------------- leg kinematics

Vec3 = tuple[float, float, float]


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
            self.soles_joint.append(tuple(tuple(map(float, x)) for x in
                                          (centre, half_len, half_wid, normal / np.linalg.norm(normal))))
            self.points_joint.append(tuple(map(float, centre)))
            ground.append(0.0)  # the sole plane is the bottom of the corner spheres
        for foot in cfg.feet:
            frame = self.model.frames[robot.frame_id(f"foot_{foot.name}")]
            self.foot_names.append(foot.name)
            self.joint_ids.append(int(frame.parentJoint))
            self.soles_joint.append(None)
            self.points_joint.append(tuple(map(float, frame.placement.translation)))
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

    def compute(self, joint_q: FloatArray, joint_qd: FloatArray, quat_xyzw=(0.0, 0.0, 0.0, 1.0),
                omega_b_radps=(0.0, 0.0, 0.0)) -> FootKinematics:
        """Contact points for measured joints, base attitude ``quat_xyzw`` and base rate ``omega_b_radps``."""
        q, v = self._q, self._v
        q[3:7] = quat_xyzw
        q[7:] = joint_q
        v[3:6] = omega_b_radps
        v[6:] = joint_qd
        pin.forwardKinematics(self.model, self.data, q, v)
        point, vel, up_cos, rots, angs, deltas = [], [], [], [], [], []
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
        self.gravity_mps2 = gravity if gravity > 0.0 else 9.81
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
            init_rot = quat_to_rotation(state.q[3:7])
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
        q[:7] = (*odo._pos, *ekf.quat_xyzw)
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
        feet = odo.kinematics.compute(jq, jqd, ekf.quat_xyzw, omega_b)
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
