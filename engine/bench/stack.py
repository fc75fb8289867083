"""The full control stack against MuJoCo alone, over the same 20 s sweep, in one run.

For each robot the walking controller (planner → CoM MPC → inverse dynamics → servos) walks
the neutral style's ``sweep`` preset headless, as fast as it goes, and every tick's MuJoCo
input (qpos, qvel, ctrl, the solver's warm start) is kept. MuJoCo alone then replays those
exact ticks: the same states and contacts, one ``mj_step`` each, timed call by call. The
ratio stack wall ÷ MuJoCo-alone wall is the figure the issue's goal is stated in (machines
differ; a ratio measured side by side does not).
"""

from __future__ import annotations

import time

import mujoco
import numpy as np

from engine.bench.stats import percentiles_us
from engine.robot.model import load_robot

STACK_ROBOTS = ("g1", "talos")
GOAL_RATIO = 6.0  # must; the goal is 3


def run_stack(robot_name: str, seconds: float = 20.0, style_name: str = "neutral") -> dict:
    """One stack run and its MuJoCo-alone replay; returns the figures of one row."""
    from engine.control.walking_controller import WalkingController
    from engine.gait.command_schedule import preset
    from engine.gait.style import load_style, styles_dir
    from engine.sim import Simulation

    robot = load_robot(robot_name)
    style = load_style(styles_dir(robot_name) / f"{style_name}.json")
    schedule = preset("sweep", style.velocities)
    controller = WalkingController(robot, style)
    sim = Simulation(robot, controller)
    model, data = sim.model, sim.data
    dt = float(model.opt.timestep)
    n = int(round(seconds / dt))
    qpos = np.empty((n, model.nq))
    qvel = np.empty((n, model.nv))
    warm = np.empty((n, model.nv))
    ctrl = np.empty((n, model.nu))
    ticks = 0
    wall0 = time.perf_counter()
    for k in range(n):
        qpos[k] = data.qpos
        qvel[k] = data.qvel
        warm[k] = data.qacc_warmstart
        controller.set_command(schedule(k * dt))
        sim.step()
        ctrl[k] = data.ctrl
        ticks += 1
        if sim.fallen:
            break
    stack_wall = time.perf_counter() - wall0
    # MuJoCo alone on the same ticks.
    replay = mujoco.MjData(model)
    step_s = np.empty(ticks)
    clock = time.perf_counter
    for k in range(ticks):
        replay.qpos[:] = qpos[k]
        replay.qvel[:] = qvel[k]
        replay.qacc_warmstart[:] = warm[k]
        replay.ctrl[:] = ctrl[k]
        t0 = clock()
        mujoco.mj_step(model, replay)
        step_s[k] = clock() - t0
    mujoco_wall = float(step_s.sum())
    return {
        "section": "stack", "robot": robot_name, "style": style_name, "sim_s": round(ticks * dt, 3),
        "fell": bool(sim.fallen), "mujoco_alone_wall_s": round(mujoco_wall, 3), "stack_wall_s": round(stack_wall, 3),
        "stack_over_mujoco": round(stack_wall / mujoco_wall, 2), "goal_ratio": GOAL_RATIO,
        "stack_rtf": round(ticks * dt / stack_wall, 2), "mujoco_rtf": round(ticks * dt / mujoco_wall, 2),
        "mj_step_median_us": percentiles_us(step_s)["median_us"],
    }


def bench_stack(seconds: float = 20.0) -> list[dict]:
    """G1 and TALOS: MuJoCo alone and the full stack over the same ``seconds`` of the sweep."""
    return [run_stack(name, seconds) for name in STACK_ROBOTS]
