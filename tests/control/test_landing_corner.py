"""The early-touchdown gate by a foot's planned lowest corner (WalkingParameters.landing_corner_height_m)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin

from engine.control.walking_controller import WalkingController
from engine.control.wbc import TaskSpaceInverseDynamics
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot


def _reference_with_left_foot(controller: WalkingController, z_m: float, pitch_rad: float):  # noqa: ANN202
    wbc = controller.wbc
    assert isinstance(wbc, TaskSpaceInverseDynamics)
    reference = wbc.hold_reference(controller.robot.q_standing)
    reference.foot_pos_m[0, 2] = z_m
    reference.foot_rotation[0] = pin.rpy.rpyToMatrix(0.0, pitch_rad, 0.0)
    return reference


def test_a_toe_down_foot_is_low_by_its_corner_only_when_enabled() -> None:
    robot = load_robot("g1")
    controller = WalkingController(robot, load_style(styles_dir("g1") / "neutral.json"))
    height = controller.params.landing_height_m  # the centre's gate, 10 mm
    # Sole centre 15 mm up, pitched toe-down 0.2 rad: the front corners (85 mm ahead of the centre on G1's 0.17 m
    # sole) at ≈ 15 − 85 sin 0.2 ≈ −2 mm.
    pitched = _reference_with_left_foot(controller, 0.015, 0.2)
    front = 0.015 + (pitched.foot_rotation[0][2] @ controller.touchdown.corner_offsets_m[0].T).min()
    assert front < 0.003
    flat = _reference_with_left_foot(controller, 0.015, 0.0)
    low = _reference_with_left_foot(controller, 0.005, 0.0)
    assert not controller.touchdown.planned_low(pitched, 0, height, controller.params)  # off by default: the centre alone
    assert controller.touchdown.planned_low(low, 0, height, controller.params)
    controller.params = dataclasses.replace(controller.params, landing_corner_height_m=0.003)
    assert controller.touchdown.planned_low(pitched, 0, height, controller.params)
    assert not controller.touchdown.planned_low(flat, 0, height, controller.params)  # flat, its corners as high as its centre
    assert controller.touchdown.planned_low(low, 0, height, controller.params)
    assert math.isclose(float(flat.foot_pos_m[0, 2]), 0.015)
    np.testing.assert_allclose(flat.foot_rotation[0], np.eye(3), atol=1e-12)
