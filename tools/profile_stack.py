"""Where the walking stack's CPU goes on a headless sweep (issue 12): compiled calls vs the Python around them,
and a line-level sampler, with no profiler installed.

    python tools/profile_stack.py split  [--robot g1] [--seconds 20]   # numba / MuJoCo / pinocchio vs the rest
    python tools/profile_stack.py lines  [--robot g1] [--seconds 20]   # CPU samples per source line and function
    python tools/profile_stack.py ab DIR_A DIR_B [--robot g1] [--seconds 20] [--repeats 3]

``split`` wraps every numba dispatcher the stack's modules call, pinocchio's functions (whole-body snapshot and
the controller's CoM) and ``mj_step`` in a thread-CPU timer: what is left is the Python glue (plus the simulation's
state read-out and servos, which MuJoCo alone pays too). ``lines`` samples the interpreter every 0.3 ms of process
CPU (``ITIMER_PROF``); a sample that lands during a compiled call is counted on the first Python line that runs
after it (the caller's next line, or a Python function the compiled code calls, e.g. numba's array boxing), so read
compiled time from ``split``. ``ab`` runs the same sweep alternately from two source trees (e.g. /work/main and a
worktree), each in its own process (``PYTHONPATH`` = the tree), and prints thread-CPU seconds per simulated second
and the ratio B / A: the side-by-side comparison a shared machine needs. cProfile misleads here: it does not see
pinocchio's calls (counted in their callers), and its per-call hook inflates the many small Python functions.

Warm numba's cache first: ``python -c "from engine.compiled_kernels import warm_up; warm_up()"``.
"""

from __future__ import annotations

import argparse
import collections
import os
import signal
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

SAMPLE_PERIOD_S = 0.0003


def sweep_cpu_s(robot_name: str, seconds: float) -> tuple[float, int, float]:
    """Thread CPU seconds of ``seconds`` of the neutral style's sweep (after a 1 s warm-up walk), its ticks and
    the simulation's time step [s]."""
    from engine.control.walking_controller import WalkingController
    from engine.gait.command_schedule import preset
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import Simulation

    robot = load_robot(robot_name)
    style = load_style(styles_dir(robot_name) / "neutral.json")
    result = (0.0, 0, 0.0)
    for duration in (1.0, seconds):  # the first walk loads every kernel
        controller = WalkingController(robot, style)
        sim = Simulation(robot, controller)
        schedule = preset("sweep", style.velocities)
        dt = float(sim.model.opt.timestep)
        ticks = int(round(duration / dt))
        cpu0 = time.thread_time()
        done = 0
        for k in range(ticks):
            controller.set_command(schedule(k * dt))
            sim.step()
            done += 1
            if sim.fallen:
                break
        result = (time.thread_time() - cpu0, done, dt)
    return result


def split(robot_name: str, seconds: float) -> None:
    """Per-tick thread CPU of numba kernels, pinocchio and mj_step, and the rest."""
    import numba
    import pinocchio as pin

    import engine.control.mpc.controller as mpc_controller
    import engine.control.walking_controller as walking
    import engine.control.wbc.controller as wbc_controller
    import engine.control.wbc.snapshot as snapshot
    import engine.gait.blending as blending
    import engine.gait.planner as planner
    import engine.sim as sim_module

    spent: dict[str, float] = collections.defaultdict(float)
    clock = time.thread_time

    def timed(function: Callable[..., Any], label: str) -> Callable[..., Any]:
        def call(*args: Any, **kwargs: Any) -> Any:
            t0 = clock()
            out = function(*args, **kwargs)
            spent[label] += clock() - t0
            return out
        return call

    for module in (wbc_controller._kernels, snapshot._kernels, mpc_controller, planner, blending, walking):
        for name, value in list(vars(module).items()):
            if isinstance(value, numba.core.registry.CPUDispatcher):
                setattr(module, name, timed(value, f"numba {name}"))

    class _TimedPinocchio:
        def __getattr__(self, name: str) -> Any:
            value = getattr(pin, name)
            return timed(value, f"pinocchio {name}") if callable(value) and not isinstance(value, type) else value

    snapshot.pin = _TimedPinocchio()
    walking.pin = _TimedPinocchio()
    sim_module.mujoco.mj_step = timed(sim_module.mujoco.mj_step, "mj_step")
    sweep_cpu_s(robot_name, 0.0)
    spent.clear()
    cpu_s, ticks, _ = sweep_cpu_s(robot_name, seconds)
    total_us = cpu_s / ticks * 1e6
    print(f"{robot_name}: {total_us:.0f} µs CPU per tick (with the timers' own cost), {ticks} ticks")
    compiled = 0.0
    for label, value in sorted(spent.items(), key=lambda kv: -kv[1]):
        print(f"  {label:40s} {value / ticks * 1e6:7.1f} µs/tick")
        compiled += value / ticks * 1e6
    print(f"  {'the rest':40s} {total_us - compiled:7.1f} µs/tick (Python glue; the simulation's read-out and servos)")


def lines(robot_name: str, seconds: float, top: int = 50) -> None:
    """CPU samples per innermost source line (self) and per function on the stack (inclusive)."""
    per_line: collections.Counter[tuple[str, int, str]] = collections.Counter()
    per_function: collections.Counter[tuple[str, str]] = collections.Counter()
    samples = [0]
    root = str(Path(__file__).resolve().parents[1]) + os.sep

    def on_sample(signum: int, frame: FrameType | None) -> None:
        samples[0] += 1
        if frame is None:
            return
        per_line[(frame.f_code.co_filename.replace(root, ""), frame.f_lineno or 0, frame.f_code.co_name)] += 1
        seen = set()
        f: FrameType | None = frame
        while f is not None:
            key = (f.f_code.co_filename.replace(root, ""), f.f_code.co_name)
            if key not in seen:
                per_function[key] += 1
                seen.add(key)
            f = f.f_back

    sweep_cpu_s(robot_name, 0.0)
    signal.signal(signal.SIGPROF, on_sample)
    signal.setitimer(signal.ITIMER_PROF, SAMPLE_PERIOD_S, SAMPLE_PERIOD_S)
    try:
        cpu_s, ticks, _ = sweep_cpu_s(robot_name, seconds)
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0.0, 0.0)
    n = max(samples[0], 1)
    print(f"{robot_name}: {samples[0]} samples, {cpu_s / ticks * 1e6:.0f} µs CPU per tick")
    print("lines (self):")
    for (name, line, function), count in per_line.most_common(top):
        print(f"  {100 * count / n:5.1f} %  {name}:{line} {function}")
    print("functions (inclusive):")
    for (name, function), count in per_function.most_common(top):
        print(f"  {100 * count / n:5.1f} %  {name} {function}")


def ab(tree_a: str, tree_b: str, robot_name: str, seconds: float, repeats: int) -> None:
    """The sweep from two source trees in turn, ``repeats`` times: CPU s per simulated s and B / A."""
    figures: dict[str, list[float]] = {tree_a: [], tree_b: []}
    for _ in range(repeats):
        for tree in (tree_a, tree_b):
            env = dict(os.environ, PYTHONPATH=tree)
            out = subprocess.run([sys.executable, str(Path(__file__).resolve()), "one", "--robot", robot_name,
                                  "--seconds", str(seconds)], cwd=tree, env=env, check=True, capture_output=True,
                                 text=True).stdout.split()
            figures[tree].append(float(out[-1]))
            print(f"  {tree}: {figures[tree][-1]:.4f} CPU s per simulated s", flush=True)
    a, b = statistics.median(figures[tree_a]), statistics.median(figures[tree_b])
    print(f"{robot_name}: median A {a:.4f}, B {b:.4f} CPU s per simulated s; B / A = {b / a:.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("mode", choices=("split", "lines", "ab", "one"))
    parser.add_argument("trees", nargs="*", help="ab: the two source trees (A, then B)")
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    if args.mode == "split":
        split(args.robot, args.seconds)
    elif args.mode == "lines":
        lines(args.robot, args.seconds)
    elif args.mode == "ab":
        if len(args.trees) != 2:
            parser.error("ab takes two source trees")
        ab(args.trees[0], args.trees[1], args.robot, args.seconds, args.repeats)
    else:  # one: the figure ab reads, from this process's PYTHONPATH
        cpu_s, ticks, dt = sweep_cpu_s(args.robot, args.seconds)
        print(f"{cpu_s / (ticks * dt):.4f}")


if __name__ == "__main__":
    main()
