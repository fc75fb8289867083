"""Error-state EKF of the base orientation and gyro bias on the IMU (Solà 2015)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

from engine.constants import GRAVITY_MPS2
from engine.control.estimation.quaternion import Quat, Rows, _quat_mul, _quat_step, _rot_rows, _tilt_with_yaw, _yaw_of, quat_to_rotation, rotation_to_quat


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

    def __init__(self, params: ImuEkfParams | None = None, gravity_mps2: float = GRAVITY_MPS2):
        self.params = params or ImuEkfParams()
        self.gravity_mps2 = float(gravity_mps2)
        self.quat_wxyz: Quat = (1.0, 0.0, 0.0, 0.0)
        self._bias = [0.0, 0.0, 0.0]  # gyro bias, rad/s
        self.cov: FloatArray = np.eye(6)
        self.initialized = False
        self.gravity_updates = 0
        self.gravity_skipped = 0
        self.gravity_downweighted = 0
        self._f = np.eye(6)
        self._q_cov: Quat = self.quat_wxyz  # nominal attitude when the covariance was last propagated
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
        self.quat_wxyz = self._q_cov = (float(q[0]), float(q[1]), float(q[2]), float(q[3]))
        self._pending_dt = 0.0

    @property
    def rotation(self) -> FloatArray:
        """World ← base rotation matrix."""
        return quat_to_rotation(self.quat_wxyz)

    def rotation_rows(self) -> Rows:
        return _rot_rows(self.quat_wxyz)

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
        self.quat_wxyz = _quat_step(self.quat_wxyz, (gyro_radps[0] - bx) * dt_s, (gyro_radps[1] - by) * dt_s,
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
        w0, x0, y0, z0 = self._q_cov
        dq = _quat_mul((w0, -x0, -y0, -z0), self.quat_wxyz)
        f[:3, :3] = quat_to_rotation(dq).T
        self.cov = f.dot(self.cov).dot(f.T) + self._q_diag
        self._q_cov = self.quat_wxyz
        self._pending_dt = 0.0

    def _inject(self, dx: list[float]) -> None:
        self.quat_wxyz = self._q_cov = _quat_step(self.quat_wxyz, dx[0], dx[1], dx[2])
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
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = _rot_rows(self.quat_wxyz)
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
