"""The walking controller's tuning is one typed parameter set per robot ([control.walking])."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from engine.control.gait_feedback import GaitFeedbackGains
from engine.control.walking_parameters import WalkingParameters
from engine.robot.config import RobotConfigError, load_robot_config


def test_defaults_and_overrides() -> None:
    cfg = load_robot_config("g1")
    # G1's file overrides exactly what its [control.walking] table names; every other field is the default
    assert WalkingParameters.from_config(cfg) == replace(WalkingParameters(), **dict(cfg.walking))
    assert WalkingParameters.from_config(replace(cfg, walking={})) == WalkingParameters()
    custom = replace(cfg, walking={"cop_margin_m": 0.02, "command_accel_limits": [0.5, 0.5, 2.0],
                                   "relatch_after_plan_ticks": 3, "restart_when_thrown": True})
    params = WalkingParameters.from_config(custom)
    assert params.cop_margin_m == 0.02 and params.command_accel_limits == (0.5, 0.5, 2.0)
    assert params.relatch_after_plan_ticks == 3 and params.restart_when_thrown is True


@pytest.mark.parametrize(("table", "message"), [
    ({"cop_margin": 0.02}, r"g1.toml: control.walking.cop_margin: unknown WalkingParameters field; did you mean 'cop_margin_m'"),
    ({"cop_margin_m": "wide"}, r"control.walking.cop_margin_m: expected a number"),
    ({"command_accel_limits": [1.0]}, r"control.walking.command_accel_limits: expected a list of 3 numbers"),
    ({"relatch_after_plan_ticks": 1.5}, r"control.walking.relatch_after_plan_ticks: expected a non-negative integer"),
    ({"restart_when_thrown": 1}, r"control.walking.restart_when_thrown: expected true or false"),
])
def test_bad_field_is_a_config_error_naming_it(table: dict, message: str) -> None:
    cfg = replace(load_robot_config("g1"), walking=table)
    with pytest.raises(RobotConfigError, match=message):
        WalkingParameters.from_config(cfg)


def test_talos_gait_feedback_comes_from_its_config() -> None:
    gains = GaitFeedbackGains.for_robot("talos")
    assert (gains.time_kp_per_m, gains.time_kd_s_per_m, gains.step_gain) == (3.0, 0.9, 0.7)
    assert GaitFeedbackGains.for_robot("g1") == GaitFeedbackGains(kappa_single=(0.75, 1.6))  # g1.toml's one gain


def test_mpc_rate_parameter_solves_every_other_planner_tick() -> None:
    from engine.control.walking_controller import WalkingController
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import Simulation

    robot = load_robot("g1")
    params = replace(WalkingParameters.for_robot("g1"), mpc_every_plan_ticks=2)
    ctrl = WalkingController(robot, load_style(styles_dir("g1") / "neutral.json"), params=params)
    solves = []
    solve = ctrl.mpc.solve
    ctrl.mpc.solve = lambda *a, **k: solves.append(ctrl.tick) or solve(*a, **k)
    sim = Simulation(robot, ctrl)
    for _ in range(40):  # 10 planner ticks
        sim.step()
    assert solves == [0, 8, 16, 24, 32]  # the first plan at once, then every second planner tick (8 ms apart)
    assert ctrl.plan is not None and ctrl.plan.ok


def test_talos_hurries_every_support_while_pushed() -> None:
    """robots/talos.toml hurry_while_pushed: with the observer seeing a push, κ goes to its upper bound in
    single (2.0) and double support whatever the CoM error says; without a push the κ law is left alone."""
    from engine.control.gait_feedback import FeedbackOutput
    from engine.control.walking_controller import WalkingController
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot

    params = WalkingParameters.for_robot("talos")
    assert params.hurry_while_pushed and params.capture_from_stance_foot and params.max_step_width_m == 0.6
    assert GaitFeedbackGains.for_robot("talos").kappa_single == (0.75, 2.0)
    assert not WalkingParameters.for_robot("g1").hurry_while_pushed
    robot = load_robot("talos")
    ctrl = WalkingController(robot, load_style(styles_dir("talos") / "neutral.json"))
    fb = FeedbackOutput(np.zeros(2), np.zeros(2), 0.9, -0.02, -0.1, np.zeros(2))  # a lagging CoM slows the gait
    com = np.zeros(2)
    ctrl.observer.force_n = np.zeros(2)

    def hurry(ctrl, fb, com, single):  # noqa: ANN001, ANN202
        return ctrl.step_adjustment.hurry_when_thrown_out(fb, ctrl.params, com, np.zeros(2), 0.9, "left", single,
                                                          ctrl._mpc_shift, ctrl.observer.force_n)

    assert hurry(ctrl, fb, com, single=True).kappa == 0.9
    ctrl.observer.force_n = np.array([0.0, -100.0])
    assert hurry(ctrl, fb, com, single=True).kappa == 2.0
    assert hurry(ctrl, fb, com, single=False).kappa == 2.0  # κ_double's bound


def test_lateral_cop_margin_narrows_the_planned_soles_sideways_only() -> None:
    """cop_lateral_extra_margin_m (G1: its ankle roll range is half TALOS's): the controller's contact preview
    plans single-support CoPs on a sole that much narrower on each side and exactly as long; the step
    adjustment's best lateral CoP on the stance foot shrinks with it. TALOS keeps the margin all round."""
    from engine.control.walking_controller import WalkingController
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot

    assert WalkingParameters.for_robot("talos").cop_lateral_extra_margin_m == 0.0
    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    base = replace(WalkingParameters.for_robot("g1"), cop_lateral_extra_margin_m=0.0)
    extents = {}
    for extra in (0.0, 0.008):
        ctrl = WalkingController(robot, style, params=replace(base, cop_lateral_extra_margin_m=extra))
        for _ in range(60):
            ctrl.planner.step(0.008, np.array([0.3, 0.0, 0.0]))
        singles = [p for p in ctrl.planner.preview() if len(p.footholds) == 1]
        assert singles
        phase = singles[0]
        (foot,) = phase.footholds.values()
        c, s = np.cos(foot.yaw), np.sin(foot.yaw)
        rel = np.asarray(phase.polygon) - [foot.x, foot.y]
        along, across = rel @ [c, s], rel @ [-s, c]
        extents[extra] = (np.ptp(along), np.ptp(across), ctrl.step_adjustment.reach_side_m)
    (len0, wid0, reach0), (len1, wid1, reach1) = extents[0.0], extents[0.008]
    assert len1 == pytest.approx(len0, abs=1e-12)
    assert wid1 == pytest.approx(wid0 - 0.016, abs=1e-12)
    assert reach1 == pytest.approx(reach0 - base.step_reach_share * 0.008, abs=1e-12)
