"""State estimation (``--state estimated``), one concept a module:

* :mod:`engine.imu` — the simulated IMU (beside :mod:`engine.sim`);
* :mod:`~engine.control.estimation.quaternion` — the filter's quaternion algebra;
* :mod:`~engine.control.estimation.ekf` — error-state EKF of orientation and gyro bias (Solà 2015);
* :mod:`~engine.control.estimation.leg_kinematics` — feet relative to the base;
* :mod:`~engine.control.estimation.odometry` — leg-kinematics odometry with zero-velocity contacts;
* :mod:`~engine.control.estimation.estimator` — :class:`StateEstimator`, the combination.
"""

from engine.control.estimation.ekf import ImuEkf, ImuEkfParams
from engine.control.estimation.estimator import EstimatorParams, StateEstimator
from engine.control.estimation.leg_kinematics import FootKinematics, LegKinematics
from engine.control.estimation.odometry import LegKinematicsOdometry, LegOdometryParams
from engine.control.estimation.quaternion import quat_to_rotation, rotation_to_quat
from engine.imu import ImuNoise, ImuSample, MujocoImu

__all__ = ["EstimatorParams", "FootKinematics", "ImuEkf", "ImuEkfParams", "ImuNoise", "ImuSample", "LegKinematics",
           "LegKinematicsOdometry", "LegOdometryParams", "MujocoImu", "StateEstimator", "quat_to_rotation",
           "rotation_to_quat"]
