"""GaitPlanner.step computes the same references, bit for bit, as the code it replaced (issue 12's trim of the planner
tick's Python; tests/gait/planner_before.py keeps the replaced methods): two closed loops of G1's sweep side by side,
one planning with the replaced code, go the same way, every reference (its contact preview included) the same."""

from __future__ import annotations

import numpy as np

from engine.control.walking_controller import WalkingController
from engine.gait.command_schedule import preset
from engine.gait.planner import GaitPlanner
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot
from engine.sim import Simulation
from tests.gait.planner_before import PlannerBefore, assert_same_reference


def test_step_matches_the_python_it_replaced() -> None:
    """4 s of G1's sweep (standing, walking, turning, strafing) in two loops: every planner tick's reference and the
    simulated state equal the replaced code's loop's, bit for bit."""
    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    schedule = preset("sweep", style.velocities)
    now, before = WalkingController(robot, style), WalkingController(robot, style)
    assert type(before.planner) is GaitPlanner
    before.planner.__class__ = PlannerBefore  # the same planner, its tick the replaced code's
    sims = Simulation(robot, now), Simulation(robot, before)
    dt = float(sims[0].model.opt.timestep)
    compared, swinging, phases, last = 0, [0, 0], 0, None
    for k in range(2000):
        for controller, sim in zip((now, before), sims):
            controller.set_command(schedule(k * dt))
            sim.step()
            assert not sim.fallen
        ref = now.ref
        if ref is not None and ref is not last:  # a planner tick
            assert before.ref is not None
            assert_same_reference(ref, before.ref, f"t = {ref.t_s}")
            compared += 1
            phases += len(ref.preview)
            for i in range(2):
                swinging[i] += not bool(ref.contact[i])
            last = ref
    assert sims[0].data.qpos.tobytes() == sims[1].data.qpos.tobytes()
    assert np.array_equal(now.planner.weights, before.planner.weights)
    assert compared >= 490 and min(swinging) > 50 and phases > 4 * compared  # both feet swung and stood; previews
