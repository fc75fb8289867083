"""Hot A/B of GaitPlanner.evaluate (issue 12): the replaced code (tests/gait/test_planner_evaluate_reference.py's
evaluate_before) against the current one, alternating on the same planner states of G1's sweep (10 states from
1.5 s to 9.3 s, the rates path: the last pose one planner tick back); thread CPU per call, best of 7 rounds.

    PYTHONPATH=. python tools/planner_evaluate_ab.py
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable

from engine.control.walking_controller import WalkingController
from engine.gait.command_schedule import preset
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot
from engine.sim import Simulation
from tests.gait.test_planner_evaluate_reference import evaluate_before

CALLS = 400
ROUNDS = 7
STATES_S = (1.5, 2.3, 3.1, 3.9, 4.7, 5.5, 6.3, 7.1, 8.05, 9.3)


def main() -> None:
    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    controller = WalkingController(robot, style)
    sim = Simulation(robot, controller)
    schedule = preset("sweep", style.velocities)
    dt = float(sim.model.opt.timestep)
    planner = controller.planner
    figures: dict[str, list[float]] = {"before": [], "now": []}
    k = 0
    for stop_s in STATES_S:
        while k * dt < stop_s or planner._last_pose is None:  # (relatch drops the last pose until the next tick)
            controller.set_command(schedule(k * dt))
            sim.step()
            k += 1
        last_pose = planner._last_pose
        assert last_pose is not None
        saved = dict(last_pose)
        saved["t"] -= 0.008  # one planner tick back: the rates path, as in the loop
        phi = planner.phi
        calls: dict[str, Callable[[], object]] = {"before": lambda: evaluate_before(planner, phi),
                                                  "now": lambda: planner.evaluate(phi)}
        best = dict.fromkeys(calls, float("inf"))
        for _ in range(ROUNDS):
            for name, call in calls.items():
                t0 = time.thread_time()
                for _ in range(CALLS):
                    planner._last_pose = saved
                    call()
                best[name] = min(best[name], (time.thread_time() - t0) / CALLS * 1e6)
        planner._last_pose = last_pose
        for name in calls:
            figures[name].append(best[name])
    for name, values in figures.items():
        print(f"{name:7s} " + " ".join(f"{x:5.1f}" for x in values) + f"  median {statistics.median(values):.1f} us")
    print(f"now / before = {statistics.median(figures['now']) / statistics.median(figures['before']):.3f}")


if __name__ == "__main__":
    main()
