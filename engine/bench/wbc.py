"""Whole-body controller bench: our task-space inverse dynamics against placo's DynamicsSolver
on the same recorded states (closed-loop standing with a lateral push)."""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import NDArray

from engine.control.controller import RobotState
from engine.control.wbc import (
    TaskSpaceInverseDynamics,
    TrackingController,
    WbcDiagnostics,
    WbcReference,
    WholeBodyController,
)
from engine.control.wbc.placo_peer import PlacoWbc
from engine.robot.model import load_robot
from engine.sim import Simulation


def record_standing_states(robot_name: str = "g1", n: int = 300,
                           push_n_per_kg: float = 1.0) -> tuple[list[RobotState], WbcReference, float]:
    """States of a closed-loop standing run under our ID, with a 0.3 s lateral pelvis push after
    the first third; also returns the run's real-time factor (simulated s / wall s, ID + MuJoCo)."""
    robot = load_robot(robot_name)
    wbc = TaskSpaceInverseDynamics(robot)
    ref = wbc.hold_reference(robot.q_standing)
    sim = Simulation(robot, TrackingController(wbc, lambda _s: ref))
    states: list[RobotState] = []
    t_wall = time.perf_counter()
    for k in range(n):
        if k == n // 3:
            sim.push(np.array([0.0, push_n_per_kg * robot.mass_kg, 0.0]), 0.3)
        st = sim.state()
        states.append(RobotState(st.t_s, st.q.copy(), st.v.copy()))
        sim.step()
    rtf = n * sim.model.opt.timestep / (time.perf_counter() - t_wall)
    return states, ref, rtf


def benchmark_wbc(robot_name: str = "g1", n: int = 300) -> dict:
    """Median/p99 µs (thread CPU time) per tick of our ID (default, hand-written and OSQP backends) and of placo's DynamicsSolver on
    the SAME recorded states (closed-loop standing + push), our pinocchio/QP breakdown, and the
    closed-loop real-time factor of our ID + MuJoCo."""
    robot = load_robot(robot_name)
    states, ref, rtf = record_standing_states(robot_name, n)

    def interleaved(ctrls: list[WholeBodyController]) -> list[tuple[NDArray, list[WbcDiagnostics]]]:
        """Each recorded state is given to every controller in turn, so all of them run under
        the same machine conditions (and, as in the engine loop, with caches shared with the
        others rather than warm from their own previous tick)."""
        for ctrl in ctrls:
            ctrl.reset(states[0])
            for st in states[:20]:  # warm up (allocations, warm start)
                ctrl.compute(st, ref)
            ctrl.reset(states[0])
        times: list[list[float]] = [[] for _ in ctrls]
        diags: list[list[WbcDiagnostics]] = [[] for _ in ctrls]
        for st in states:
            for i, ctrl in enumerate(ctrls):
                t = time.thread_time()  # CPU time: robust on a shared machine
                ctrl.compute(st, ref)
                times[i].append(time.thread_time() - t)
                diags[i].append(ctrl.diagnostics)
        return [(np.asarray(t) * 1e6, d) for t, d in zip(times, diags)]

    def stats(a: NDArray) -> dict[str, float]:
        return {"median_us": round(float(np.median(a)), 1), "p99_us": round(float(np.percentile(a, 99)), 1)}

    (t_dense, d_dense), (t_hand, _), (t_osqp, _), (t_placo, d_placo) = interleaved(
        [TaskSpaceInverseDynamics(robot), TaskSpaceInverseDynamics(robot, qp_backend="dense"),
         TaskSpaceInverseDynamics(robot, qp_backend="osqp"), PlacoWbc(robot)])
    breakdown = {k: round(float(np.median([getattr(d, f"{k}_s") for d in d_dense])) * 1e6, 1)
                 for k in ("pinocchio", "build", "qp")}
    return {
        "robot": robot_name, "ticks": len(states),
        "ours": stats(t_dense), "ours_dense_backend": stats(t_hand), "ours_osqp_backend": stats(t_osqp),
        "placo": stats(t_placo),
        "ours_breakdown_median_us": breakdown,
        "ours_solved_fraction": float(np.mean([d.ok for d in d_dense])),
        "placo_solved_fraction": float(np.mean([d.ok for d in d_placo])),
        "placo_over_ours_median": round(float(np.median(t_placo) / np.median(t_dense)), 2),
        "closed_loop_rtf_ours_plus_mujoco": round(rtf, 2),
    }


def bench_wbc(robots: tuple[str, ...] = ("g1", "talos"), n: int = 300) -> list[dict]:
    """``studio bench wbc``: ours ÷ placo per tick on the same states (goal ≤ 1.0)."""
    rows = []
    for robot in robots:
        r = benchmark_wbc(robot, n=n)
        rows.append({"section": "wbc", "robot": robot, "ours_median_us": r["ours"]["median_us"],
                     "ours_p99_us": r["ours"]["p99_us"], "placo_median_us": r["placo"]["median_us"],
                     "placo_p99_us": r["placo"]["p99_us"], "ours_over_placo": round(1.0 / r["placo_over_ours_median"], 2),
                     "goal_ratio": 1.0, "hand_written_qp_median_us": r["ours_dense_backend"]["median_us"],
                     "ours_solved_fraction": r["ours_solved_fraction"],
                     **{f"ours_{k}_us": v for k, v in r["ours_breakdown_median_us"].items()}})
    return rows
