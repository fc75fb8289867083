"""Gait reference bench: sampler + planner per 125 Hz tick over the sweep preset."""

from __future__ import annotations

import time

from engine.bench.stats import percentiles_us
from engine.robot.model import load_robot


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
