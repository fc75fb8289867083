"""Per-robot whole-body controller tuning lives in robots/<name>.toml ([control.wbc])."""

from __future__ import annotations

from dataclasses import replace

import pytest

from engine.control.wbc import WbcGains
from engine.robot.config import RobotConfigError, load_config
from engine.robot.model import load_robot
from tests.conftest import REPO


def test_talos_gains_come_from_its_config() -> None:
    talos = load_robot("talos")
    gains = WbcGains.for_robot(talos)
    assert talos.config.wbc_gains == {"servo_kp_scale": 0.05, "servo_kd_scale": 0.2, "swing_foot_kp": 300.0,
                                      "swing_foot_kd": 35.0}
    assert (gains.servo_kp_scale, gains.servo_kd_scale, gains.swing_foot_kp, gains.swing_foot_kd) == (0.05, 0.2, 300.0, 35.0)
    # G1: the defaults but the style tasks' weight share and the CoM task's weight (robots/g1.toml [control.wbc])
    assert WbcGains.for_robot(load_robot("g1")) == replace(WbcGains(), priority_level2_scale=0.1, com_weight=300.0)


def test_unknown_gain_is_a_config_error_naming_the_field() -> None:
    g1 = load_robot("g1")
    robot = replace(g1, config=replace(g1.config, wbc_gains={"swing_foot_kpp": 1.0}))
    with pytest.raises(RobotConfigError, match=r"g1.toml: control.wbc.swing_foot_kpp: unknown WbcGains field; did you mean 'swing_foot_kp'"):
        WbcGains.for_robot(robot)


def test_non_numeric_gain_is_refused_at_load(tmp_path) -> None:
    text = (REPO / "robots" / "talos.toml").read_text().replace("swing_foot_kp = 300.0", 'swing_foot_kp = "stiff"')
    path = tmp_path / "talos.toml"
    path.write_text(text)
    with pytest.raises(RobotConfigError, match="control.wbc.swing_foot_kp: expected"):
        load_config(path)
