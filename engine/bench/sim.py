"""MuJoCo alone: physics steps per second per robot (bare ``mj_step`` and with joint servos)."""

from __future__ import annotations

import time

import mujoco

from engine.robot.config import robot_names
from engine.robot.model import load_robot
from engine.sim import Simulation

SIM_BENCH_ROBOTS = ("g1", "talos", "go1", "go2", "a1", "b1", "anymal_c")


def bench_sim(robots: tuple[str, ...] = SIM_BENCH_ROBOTS, seconds_per_robot: float = 1.0) -> list[dict]:
    """Physics steps per second, bare ``mj_step`` and a full tick with joint servos, per robot.

    The real-time-factor ceiling is what the simulator alone allows (steps/s × timestep).
    """
    rows = []
    known = set(robot_names())
    for name in robots:
        if name not in known:
            continue
        robot = load_robot(name)
        sim = Simulation(robot)
        dt = float(robot.mj_model.opt.timestep)
        # Settle a moment so contacts are realistic.
        for _ in range(200):
            sim.step()
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds_per_robot / 2:
            mujoco.mj_step(sim.model, sim.data)
            n += 1
        bare = n / (time.perf_counter() - t0)
        sim.reset()
        n, t0 = 0, time.perf_counter()
        while time.perf_counter() - t0 < seconds_per_robot / 2:
            sim.step()
            n += 1
        ticked = n / (time.perf_counter() - t0)
        rows.append({
            "section": "sim", "robot": name, "timestep_s": dt, "mj_steps_per_s": round(bare, 1),
            "ticks_per_s": round(ticked, 1), "rtf_ceiling": round(bare * dt, 2),
            "rtf_with_servos": round(ticked * dt, 2), "fell": bool(sim.fallen),
        })
    return rows
