"""Benchmarks behind ``studio bench``: figures measured side by side in one run.

Each section returns rows (dicts). Sections grow with the product: ``sim`` (MuJoCo),
later the reference (sampler + planner), MPC, inverse dynamics, the full stack and the
studio's edit latency.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Callable

import mujoco
import numpy as np

from engine.robot.config import robot_names
from engine.robot.model import load_robot
from engine.sim import Simulation
from engine.bench_push import bench_push
from engine.bench_styles import bench_styles

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


def bench_stack(seconds: float = 8.0) -> list[dict]:
    """Full stack (planner + MPC + feedback + inverse dynamics + MuJoCo) headless, G1 and TALOS,
    walking 0.3 m/s (TALOS 0.2) after standing up: the real-time factor and per-stage cost."""
    from engine.gait.command_schedule import from_keyframes
    from engine.gait.style import load_style, styles_dir
    from engine.walk_runner import run_walk

    rows = []
    for robot, speed in (("g1", 0.3), ("talos", 0.2)):
        model = load_robot(robot)
        style = load_style(styles_dir(robot) / "neutral.json")
        schedule = from_keyframes([[0, 0, 0, 0], [1, 0, 0, 0], [3, speed, 0, 0]], "bench")
        summary, _ = run_walk(model, style, schedule, seconds, record=False)
        timing = summary["timing_us"]
        rows.append({"section": "stack", "robot": robot, "wbc": "paper", "real_time_factor": summary["real_time_factor"],
                     "goal_rtf": 15.0, "fell": summary["fell"], "planner_median_us": timing["planner"]["median"],
                     "mpc_median_us": timing["mpc"]["median"], "mpc_p99_us": timing["mpc"]["p99"],
                     "wbc_median_us": timing["wbc"]["median"], "sim_median_us": timing["sim"]["median"]})
    return rows


def bench_wbc() -> list[dict]:
    """Our inverse dynamics against placo's DynamicsSolver on the same recorded states."""
    from engine.control.inverse_dynamics import benchmark_wbc

    rows = []
    for robot in ("g1", "talos"):
        r = benchmark_wbc(robot, n=300)
        rows.append({"section": "wbc", "robot": robot, "ours_median_us": r["ours"]["median_us"],
                     "ours_p99_us": r["ours"]["p99_us"], "placo_median_us": r["placo"]["median_us"],
                     "placo_p99_us": r["placo"]["p99_us"], "ours_over_placo": round(1.0 / r["placo_over_ours_median"], 2),
                     "goal_ratio": 1.5, "ours_solved_fraction": r["ours_solved_fraction"]})
    return rows


def bench_mpc() -> list[dict]:
    from engine.control.com_mpc import benchmark_solve

    r = benchmark_solve()
    return [{"section": "mpc", **{k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()},
             "goal_median_us": 500}]


def bench_estimator() -> list[dict]:
    from engine.control.estimator import benchmark_estimator

    r = benchmark_estimator("g1")
    return [{"section": "estimator", "robot": "g1", **{k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()}}]


def bench_edit_latency(edits: int = 20) -> list[dict]:
    """Studio edit latency: a curve edit arriving at the server (StyleSession.apply) until the first
    streamed pose computed with it (engine process in edit mode, real pipe, real pacing)."""
    import threading
    from dataclasses import replace

    from engine import protocol as msg
    from engine.gait.curves import HermiteCurve, Knot
    from studio.engine_link import EngineLink
    from studio.style_session import StyleSession

    seen: dict[int, float] = {}
    loaded = threading.Event()
    lock = threading.Lock()

    def on_event(event) -> None:
        if isinstance(event, msg.RobotLoaded):
            loaded.set()
        elif isinstance(event, msg.Frame):
            with lock:
                if event.style_revision not in seen:
                    seen[event.style_revision] = time.perf_counter()

    import shutil
    import tempfile

    from engine.gait.style import styles_dir

    scratch = Path(tempfile.mkdtemp(prefix="motion-studio-bench-"))
    shutil.copy(styles_dir("g1") / "neutral.json", scratch / "neutral.json")
    link = EngineLink("g1", on_event)
    link.start()
    session = StyleSession("g1", folder=scratch)  # never autosave into the user's styles
    session.open("neutral")
    sent: dict[int, float] = {}
    revision = [0]

    def push(style, reason) -> None:
        revision[0] += 1
        sent[revision[0]] = time.perf_counter()
        link.send(msg.SetStyle(session.as_document(), revision=revision[0]))

    session.subscribe(push)
    try:
        if not loaded.wait(60):
            raise RuntimeError("engine did not start")
        link.send(msg.SetMode("edit", {"sample": "in_place"}))
        time.sleep(2.0)
        for i in range(edits):
            sample = session.style.samples["in_place"]
            curve = sample.curves["left_foot.z"]
            d = curve.duration_s
            height = 0.05 + 0.02 * (i % 2)
            new = HermiteCurve([Knot(0.0, 0.0, mode="flat"), Knot(0.5 * d, height), Knot(d, 0.0, mode="flat")], d)
            t0 = time.perf_counter()
            session.apply(session.style.with_sample("in_place", sample.with_curve("left_foot.z", new)), "bench")
            sent[revision[0]] = t0  # the edit arrived at the server when apply() was called
            time.sleep(0.25)
    finally:
        link.stop()
        shutil.rmtree(scratch, ignore_errors=True)
    latencies = [seen[r] - sent[r] for r in sent if r in seen and seen[r] >= sent[r]]
    row = {"section": "edit", "robot": "g1", "edits": len(sent), "reflected": len(latencies), **percentiles_us(latencies),
           "goal_median_us": 100_000}
    return [row]


SECTIONS: dict[str, Callable[..., list[dict]]] = {
    "sim": bench_sim, "reference": bench_reference, "mpc": bench_mpc, "wbc": bench_wbc,
    "estimator": bench_estimator, "stack": bench_stack, "edit": bench_edit_latency,
    "push": bench_push, "styles": bench_styles,
}
BATCH_SECTIONS = ("push", "styles")  # minutes to hours of closed-loop walks: only when asked for


def percentiles_us(samples_s: list[float] | np.ndarray) -> dict[str, float]:
    arr = np.asarray(samples_s, dtype=float) * 1e6
    return {"median_us": round(float(np.median(arr)), 1), "p99_us": round(float(np.percentile(arr, 99)), 1)}
