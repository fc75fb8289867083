"""The simulated IMU (beside :mod:`engine.sim`): MuJoCo gyro/accelerometer sensors with noise and bias
random walk, read each tick into an :class:`ImuSample`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray

from engine.geometry.rotation import matrix_from_quat


FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]



MAX_GYRO_RADPS = 35.0  # beyond any legged robot's base rate: a broken sample
MAX_ACCEL_MPS2 = 160.0  # 16 g


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
    bias random walk are added from a seeded RNG. :meth:`truth_quat_wxyz` reads the
    ``imu_quat`` ground truth — for evaluation only, never feed it to the filter.
    """

    def __init__(self, mj_model: mujoco.MjModel, noise: ImuNoise | None = None, seed: int = 0, site: str = "imu"):
        self.gyro_adr = int(mj_model.sensor("imu_gyro").adr[0])
        self.accel_adr = int(mj_model.sensor("imu_accel").adr[0])
        self.quat_adr = int(mj_model.sensor("imu_quat").adr[0])
        self.dt_s = float(mj_model.opt.timestep)
        wxyz = np.array(mj_model.site(site).quat, dtype=float)
        rot = matrix_from_quat(wxyz)  # MuJoCo's w, x, y, z
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

    def truth_quat_wxyz(self, data: mujoco.MjData) -> FloatArray:
        return np.array(data.sensordata[self.quat_adr:self.quat_adr + 4], dtype=float)
