"""Hot A/B of GaitPlanner.step (issue 12): the planner calls of a closed-loop sweep (reset, step with its feedback,
relatch) are recorded once, then replayed alternately into the planner as it was (tests/gait/planner_before.py's
PlannerBefore: the replaced code) and the current one, on the same inputs; thread CPU per step and whether every
reference (preview included) is the same, bit for bit.

    PYTHONPATH=. python tools/planner_step_ab.py [--robot g1] [--seconds 8] [--rounds 5] [--profile]
"""

from __future__ import annotations

import argparse
import collections
import copy
import signal
import statistics
import time
from types import FrameType
from typing import Any

from engine.control.walking_controller import WalkingController
from engine.gait.command_schedule import preset
from engine.gait.planner import GaitPlanner
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot
from engine.sim import Simulation
from tests.gait.planner_before import PlannerBefore, assert_same_reference

Call = tuple[str, tuple[Any, ...], dict[str, Any]]
RECORDED = ("reset", "step", "relatch", "set_style")  # the planner calls that change its state


def record_calls(robot_name: str, seconds: float) -> tuple[GaitPlanner, list[Call]]:
    """A fresh copy of the controller's planner (as constructed) and the calls the closed loop made on it."""
    robot = load_robot(robot_name)
    style = load_style(styles_dir(robot_name) / "neutral.json")
    controller = WalkingController(robot, style)
    planner = controller.planner
    calls: list[Call] = []
    fresh: list[GaitPlanner] = []

    def recorder(name: str) -> Any:
        method = getattr(planner, name)

        def call(*args: Any, **kwargs: Any) -> Any:
            if not fresh:
                copied = copy.deepcopy(planner)
                for recorded in RECORDED:
                    copied.__dict__.pop(recorded, None)  # (the recorders themselves)
                fresh.append(copied)
            calls.append((name, copy.deepcopy(args), copy.deepcopy(kwargs)))
            return method(*args, **kwargs)
        return call

    for name in RECORDED:
        setattr(planner, name, recorder(name))
    sim = Simulation(robot, controller)
    schedule = preset("sweep", style.velocities)
    dt = float(sim.model.opt.timestep)
    for k in range(int(round(seconds / dt))):
        controller.set_command(schedule(k * dt))
        sim.step()
        if sim.fallen:
            break
    return fresh[0], calls


def replay(planner: GaitPlanner, calls: list[Call], keep: bool = True) -> tuple[float, list[Any]]:
    """Thread CPU of the steps (s) and the steps' references (``keep``; else none is kept beyond the next step, as
    in the loop, which drops a reference a tick later: the garbage collector sees what it sees there)."""
    out = []
    cpu = 0.0
    for name, args, kwargs in calls:
        if name == "step":
            t0 = time.thread_time()
            ref = planner.step(*args, **kwargs)
            cpu += time.thread_time() - t0
            if keep:
                out.append(ref)
        else:
            getattr(planner, name)(*args, **kwargs)
    return cpu, out


def sample_lines(start: GaitPlanner, calls: list[Call], rounds: int) -> None:
    """CPU samples per line (self) and function (inclusive) of ``rounds`` replays (profile_stack's sampler)."""
    per_line: collections.Counter[tuple[str, int, str]] = collections.Counter()
    per_function: collections.Counter[tuple[str, str]] = collections.Counter()
    samples = [0]

    def on_sample(signum: int, frame: FrameType | None) -> None:
        samples[0] += 1
        if frame is None:
            return
        where = frame if frame.f_code.co_filename != "<string>" or frame.f_back is None else frame.f_back
        per_line[(where.f_code.co_filename, where.f_lineno or 0, where.f_code.co_name)] += 1  # (a dataclass: its caller)
        seen = set()
        f: FrameType | None = frame
        while f is not None:
            key = (f.f_code.co_filename, f.f_code.co_name)
            if key not in seen:
                per_function[key] += 1
                seen.add(key)
            f = f.f_back

    signal.signal(signal.SIGPROF, on_sample)
    signal.setitimer(signal.ITIMER_PROF, 0.0002, 0.0002)
    try:
        for _ in range(rounds):
            replay(copy.deepcopy(start), calls)
    finally:
        signal.setitimer(signal.ITIMER_PROF, 0.0, 0.0)
    n = max(samples[0], 1)
    for (name, line, function), count in per_line.most_common(45):
        print(f"  {100 * count / n:5.1f} %  {name.split('plan11/')[-1]}:{line} {function}")
    for (name, function), count in per_function.most_common(40):
        print(f"  {100 * count / n:5.1f} %  {name.split('plan11/')[-1]} {function}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--profile", action="store_true", help="cProfile the current planner's replay instead")
    parser.add_argument("--lines", action="store_true", help="sample the current planner's replay per line instead")
    args = parser.parse_args()
    start, calls = record_calls(args.robot, args.seconds)
    n_steps = sum(1 for c in calls if c[0] == "step")
    if args.profile:
        import cProfile
        import pstats
        planner = copy.deepcopy(start)
        prof = cProfile.Profile()
        prof.enable()
        replay(planner, calls)
        prof.disable()
        pstats.Stats(prof).sort_stats("tottime").print_stats(30)
        return
    if args.lines:
        sample_lines(start, calls, args.rounds)
        return
    refs: dict[str, list[Any]] = {}
    for name in ("before", "now"):  # the same references, bit for bit
        planner = copy.deepcopy(start)
        if name == "before":
            planner.__class__ = PlannerBefore
        refs[name] = replay(planner, calls)[1]
    for i, (a, b) in enumerate(zip(refs["before"], refs["now"])):
        assert_same_reference(b, a, f"step {i}")
    del refs, a, b
    figures: dict[str, list[float]] = {"before": [], "now": []}
    for round_index in range(args.rounds):
        for name in (("before", "now") if round_index % 2 == 0 else ("now", "before")):  # alternate who goes first
            planner = copy.deepcopy(start)
            if name == "before":
                planner.__class__ = PlannerBefore
            figures[name].append(replay(planner, calls, keep=False)[0] / n_steps * 1e6)
    b, n = min(figures["before"]), min(figures["now"])
    print(f"{args.robot}: {n_steps} steps, all references the same bit for bit; µs per step (best of {args.rounds}): "
          f"before {b:.1f}, now {n:.1f}; now / before = {n / b:.3f} (medians {statistics.median(figures['before']):.1f}, "
          f"{statistics.median(figures['now']):.1f})")


if __name__ == "__main__":
    main()
