"""The stance-foot capture point that places steps under a push (`StepAdjustment.xi_at_touchdown`):
the LIP's divergent component ξ̇ = ω (ξ − p) about the stance sole's best CoP p, with a steady push's
equilibrium shift f/(m ω²) taken off first."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.gait.footsteps import Foothold


@pytest.fixture(scope="module")
def controller():
    from engine.control.walking_controller import WalkingController
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot

    ctrl = WalkingController(load_robot("g1"), load_style(styles_dir("g1") / "neutral.json"))
    ctrl.planner.latched["right"] = Foothold(0.1, -0.12, 0.3)  # stance foot of a left swing, turned
    return ctrl


OMEGA = math.sqrt(9.81 / 0.7)
coord = st.floats(-0.6, 0.6)
times = st.floats(0.0, 0.5)


def _local(ctrl, p):
    foot = ctrl.planner.latched["right"]
    c, s = math.cos(foot.yaw), math.sin(foot.yaw)
    d = np.asarray(p) - [foot.x, foot.y]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def _inside_reach(ctrl, local) -> bool:
    steps = ctrl.step_adjustment
    return (-steps.reach_back_m <= local[0] <= steps.reach_forward_m) and abs(local[1]) <= steps.reach_side_m


@settings(max_examples=60, deadline=None)
@given(x=coord, y=coord, vx=coord, vy=coord, t=times)
def test_a_captured_xi_stays_and_an_uncaptured_one_runs_away_from_the_sole(controller, x, y, vx, vy, t):
    ctrl = controller
    ctrl._mpc_shift = np.zeros(2)
    com, vel = np.array([x, y]), np.array([vx, vy])
    xi = com + vel / OMEGA
    out = ctrl.step_adjustment.xi_at_touchdown("left", com, vel, OMEGA, t, ctrl._mpc_shift)
    if _inside_reach(ctrl, _local(ctrl, xi)):
        np.testing.assert_allclose(out, xi, atol=1e-12)  # the CoP sits under ξ: it holds still
        return
    # outside: ξ moves straight away from the nearest reachable CoP, by e^{ωt}
    local = _local(ctrl, xi)
    steps = ctrl.step_adjustment
    cop_local = np.array([np.clip(local[0], -steps.reach_back_m, steps.reach_forward_m),
                          np.clip(local[1], -steps.reach_side_m, steps.reach_side_m)])
    gap = np.linalg.norm(local - cop_local)
    moved = _local(ctrl, out)
    assert np.linalg.norm(moved - cop_local) == pytest.approx(gap * math.exp(OMEGA * t), rel=1e-9)
    a, b = moved - cop_local, local - cop_local
    assert a[0] * b[1] - a[1] * b[0] == pytest.approx(0.0, abs=1e-9)  # along the same line


@settings(max_examples=30, deadline=None)
@given(x=coord, y=coord, fx=st.floats(-0.15, 0.15), fy=st.floats(-0.15, 0.15), t=times)
def test_a_steady_push_is_taken_as_the_shift_of_the_equilibrium(controller, x, y, fx, fy, t):
    """The MPC plans with supports shifted by −f/(m ω²); ξ against the real soles is ξ minus that shift."""
    ctrl = controller
    shift = np.array([fx, fy])
    com, vel = np.array([x, y]), np.zeros(2)
    ctrl._mpc_shift = shift
    pushed = ctrl.step_adjustment.xi_at_touchdown("left", com, vel, OMEGA, t, ctrl._mpc_shift)
    ctrl._mpc_shift = np.zeros(2)
    moved = ctrl.step_adjustment.xi_at_touchdown("left", com - shift, vel, OMEGA, t, ctrl._mpc_shift)
    np.testing.assert_allclose(pushed, moved, atol=1e-12)
