"""A stance foot rolled onto its edge stands on that edge only (WalkingParameters.rolled_foot_edge_lift_m)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engine.control.controller import RobotState
from engine.control.walking_controller import WalkingController
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot


def _corner_heights(controller: WalkingController, q: np.ndarray, foot: int) -> np.ndarray:
    track = controller.touchdown
    pin.framesForwardKinematics(track.model, track.data, q)
    m = track.data.oMf[track.foot_frames[foot]]
    return m.translation[2] + (m.rotation @ track.corner_offsets_m[foot].T)[2]


def test_a_rolled_foot_keeps_its_lower_edge_and_a_flat_one_all_corners() -> None:
    robot = load_robot("g1")
    controller = WalkingController(robot, load_style(styles_dir("g1") / "neutral.json"))
    assert controller.params.rolled_foot_edge_lift_m == 0.0  # off by default (the QP stands on the plan's corners)
    lift = 0.004
    q = robot.q_standing.copy()
    contact = np.ones((2, 4), dtype=bool)
    state = RobotState(0.0, q, np.zeros(robot.pin_model.nv))
    assert controller.touchdown.on_rolled_edges(state, contact, lift) is contact  # standing flat: the plan's corners
    roll_q = robot.pin_model.joints[robot.pin_model.getJointId("left_ankle_roll_joint")].idx_q
    for roll in (0.15, -0.15):
        q_rolled = q.copy()
        q_rolled[roll_q] = roll
        out = controller.touchdown.on_rolled_edges(RobotState(0.0, q_rolled, state.v), contact, lift)
        z = _corner_heights(controller, q_rolled, 0)
        low = z <= np.median(z)  # the two lower corners: one side of the sole (0.15 rad lifts the other 8 mm)
        assert low.sum() == 2 and abs(z[~low].mean() - z[low].mean()) > 0.006
        np.testing.assert_array_equal(out[0], low)
        np.testing.assert_array_equal(out[1], contact[1])  # the right foot is flat
        # A swing foot (no corner in the plan's contact) stays in the air; a heel-only contact keeps its lower corner.
        swing = contact.copy()
        swing[0] = False
        np.testing.assert_array_equal(controller.touchdown.on_rolled_edges(RobotState(0.0, q_rolled, state.v), swing,
                                                                           lift)[0], np.zeros(4, dtype=bool))
        heel = contact.copy()
        heel[0] = [False, False, True, True]
        np.testing.assert_array_equal(controller.touchdown.on_rolled_edges(RobotState(0.0, q_rolled, state.v), heel,
                                                                           lift)[0], low & heel[0])
