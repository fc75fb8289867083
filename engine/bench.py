"""Benchmarks behind ``studio bench``: figures measured side by side in one run.

Each section returns rows (dicts). Sections grow with the product: ``sim`` (MuJoCo),
later the reference (sampler + planner), MPC, inverse dynamics, the full stack and the
studio's edit latency.
"""

from __future__ import annotations

import time
from typing import Callable

import mujoco
import numpy as np

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


def bench_reference(robot: str = "g1", style_name: str = "neutral", seconds: float = 50.0) -> list[dict]:
    """Sampler + planner per 125 Hz tick over the sweep preset (joystick-like, changing command).

    Two rows: r(t) alone, and r(t) plus the 2 s contact preview the MPC consumes.
    """
    from engine.gait.command_schedule import preset
    from engine.gait.offline_plan import planner_for
    from engine.gait.planner import PLANNER_RATE_HZ
    from engine.gait.style import load_style, styles_dir

    model = load_robot(robot)
    style = load_style(styles_dir(robot) / f"{style_name}.json")
    schedule = preset("sweep", style.velocities)
    rows = []
    dt = 1.0 / PLANNER_RATE_HZ
    for with_preview in (False, True):
        planner = planner_for(model, style)
        times = []
        for _ in range(int(seconds * PLANNER_RATE_HZ)):
            command = schedule(planner.t_s + dt)
            t0 = time.perf_counter()
            planner.step(dt, command, with_preview=with_preview)
            times.append(time.perf_counter() - t0)
        rows.append({"section": "reference", "robot": robot, "style": style_name,
                     "what": "sampler+planner+preview" if with_preview else "sampler+planner",
                     **percentiles_us(times), "goal_median_us": 100, "ticks": len(times)})
    return rows


SECTIONS: dict[str, Callable[[], list[dict]]] = {"sim": bench_sim, "reference": bench_reference}


def percentiles_us(samples_s: list[float] | np.ndarray) -> dict[str, float]:
    arr = np.asarray(samples_s, dtype=float) * 1e6
    return {"median_us": round(float(np.median(arr)), 1), "p99_us": round(float(np.percentile(arr, 99)), 1)}
