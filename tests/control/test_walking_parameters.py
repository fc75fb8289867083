"""The walking controller's tuning is one typed parameter set per robot ([control.walking])."""

from __future__ import annotations

from dataclasses import replace

import pytest

from engine.control.gait_feedback import GaitFeedbackGains
from engine.control.walking_parameters import WalkingParameters
from engine.robot.config import RobotConfigError, load_robot_config


def test_defaults_and_overrides() -> None:
    cfg = load_robot_config("g1")
    assert WalkingParameters.from_config(cfg) == WalkingParameters()
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
    assert GaitFeedbackGains.for_robot("g1") == GaitFeedbackGains()
