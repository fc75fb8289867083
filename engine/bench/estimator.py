"""State estimator bench: the cost of one update on a recorded standing run with sensor noise."""

from __future__ import annotations

import time

import numpy as np

from engine.control.estimation import EstimatorParams, StateEstimator
from engine.imu import ImuNoise, MujocoImu
from engine.robot.model import load_robot
from engine.sim import Simulation


def benchmark_estimator(robot_name: str = "g1", n_ticks: int = 2000, seed: int = 0,
                        params: EstimatorParams | None = None) -> dict[str, float | str]:
    """Cost of one :meth:`StateEstimator.update` (µs), replaying a recorded standing simulation
    with realistic sensor noise so only the estimator is timed."""
    robot = load_robot(robot_name)
    sim = Simulation(robot)
    imu = MujocoImu(robot.mj_model, ImuNoise(gyro_bias_radps=(0.004, -0.003, 0.005)), seed=seed)
    rng = np.random.default_rng(seed + 1)
    ticks = []
    for _ in range(n_ticks):
        sim.step()
        ticks.append((sim.time_s, imu.read(sim.data), sim.joint_positions() + rng.normal(0.0, 1e-4, robot.n_joints),
                      sim.joint_velocities() + rng.normal(0.0, 0.02, robot.n_joints)))
    est = StateEstimator(robot, params=params)
    est.reset(None)
    contact = np.ones(est.odometry.n_feet, dtype=bool)
    costs = np.empty(n_ticks)
    clock = time.perf_counter
    for k, (t_s, sample, jq, jqd) in enumerate(ticks):
        t0 = clock()
        est.update(t_s, sample, jq, jqd, contact)
        costs[k] = clock() - t0
    costs = costs[n_ticks // 10:] * 1e6  # past initialisation
    return {"robot": robot_name, "median_us": float(np.median(costs)), "p90_us": float(np.percentile(costs, 90)),
            "p99_us": float(np.percentile(costs, 99)), "max_us": float(costs.max())}
