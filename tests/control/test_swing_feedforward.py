"""The swing feet's feed-forward acceleration: consecutive reference rates, limited per axis.

A step adjustment moves a swing target mid-swing; differencing that jump twice over 8 ms planner
ticks gave 100+ m/s² spikes whose reaction at the stance foot fed back into the next adjustment
(G1 casual, stopping in the sweep: a period-2 limit cycle at the planner's 125 Hz and 2.17 mm stance slip). The limit keeps the
nominal swing's own accelerations (below ≈ 35 m/s² on G1 with the feedback off) and a capture step's
after a push, and cuts the spikes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from engine.control.walking_controller import PLAN_DT_S, WalkingController
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot
from engine.sim import Simulation


def _walking_controller() -> WalkingController:
    robot = load_robot("g1")
    controller = WalkingController(robot, load_style(styles_dir("g1") / "neutral.json"))
    sim = Simulation(robot, controller)
    sim.reset()
    controller.set_command(np.array([0.3, 0.0, 0.0]))
    for _ in range(400):  # 0.8 s: stepping, one foot in swing at some point
        sim.step()
    return controller


def test_a_jump_in_a_swing_rate_is_limited_and_a_nominal_one_passes() -> None:
    controller = _walking_controller()
    limit = controller.params.swing_feedforward_limit_mps2
    assert 0.0 < limit < np.inf
    prev = controller.ref
    assert prev is not None
    swing = int(np.argmin(prev.contact))
    both_swinging = replace(prev, contact=np.array([False, False]))
    controller.ref = both_swinging
    # a nominal change of rate (5 m/s² over one planner tick) goes through as it is
    small = both_swinging.foot_lin_vel.copy()
    small[swing] += np.array([5.0, -5.0, 2.0]) * PLAN_DT_S
    controller._feet_feedforward(replace(both_swinging, foot_lin_vel=small))
    np.testing.assert_allclose(controller._foot_acc[swing], [5.0, -5.0, 2.0], atol=1e-9)
    # a target moved by 1 cm within one planner tick: the rate jumps by 1.25 m/s, 156 m/s² unlimited
    jump = both_swinging.foot_lin_vel.copy()
    jump[swing] += np.array([0.0, 0.01, 0.0]) / PLAN_DT_S
    assert 0.01 / PLAN_DT_S**2 > limit
    controller._feet_feedforward(replace(both_swinging, foot_lin_vel=jump))
    assert controller._foot_acc[swing, 1] == limit
    assert np.all(np.abs(controller._foot_acc) <= limit)
    # a foot on the ground gets none
    stance = replace(both_swinging, contact=np.array([True, True]), foot_lin_vel=jump)
    controller._feet_feedforward(stance)
    assert not controller._foot_acc.any()
