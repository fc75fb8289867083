"""The CoP the CoM MPC's plan needs under the style's CoM height (engine/gait/zmp_feasibility.py)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.constants import GRAVITY_MPS2
from engine.gait.zmp_feasibility import CopDemand, PlanFollower, cop_demands, outside_distance_m, required_cop

finite = st.floats(-1.0, 1.0, allow_nan=False)
heights = st.floats(0.3, 1.2, allow_nan=False)
SQUARE = np.array([[-0.1, -0.05], [0.1, -0.05], [0.1, 0.05], [-0.1, 0.05]])


@settings(max_examples=60, deadline=None)
@given(cx=finite, cy=finite, px=finite, py=finite, z=heights)
def test_at_the_pendulum_height_without_vertical_acceleration_the_plan_cop_is_the_required_one(cx, cy, px, py, z):
    """The MPC's own model: the CoM at the height it planned with, not accelerating vertically."""
    p = required_cop(np.array([cx, cy]), np.array([px, py]), z, z, 0.0)
    assert np.allclose(p, [px, py], atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(cx=finite, px=finite, z=heights, z_acc=st.floats(-8.0, 8.0, allow_nan=False))
def test_the_required_cop_is_the_point_mass_zmp(cx, px, z, z_acc):
    """p_req is where a point mass at height z with the plan's horizontal acceleration and vertical
    acceleration z̈ has its ZMP: the floor's force (m c̈, m (g + z̈)) passes through p_req and the CoM."""
    com, cop = np.array([cx, 0.0]), np.array([px, 0.0])
    p = required_cop(com, cop, z, z, z_acc)
    horizontal = GRAVITY_MPS2 / z * (cx - px)
    vertical = GRAVITY_MPS2 + z_acc
    # moment about the CoM of the floor's force applied at p: (p − c) × F = 0 in the sagittal plane
    assert math.isclose((p[0] - cx) * vertical + z * horizontal, 0.0, abs_tol=1e-9)
    # rising (z̈ > 0) brings the CoP toward the CoM, sinking pushes it beyond the plan's
    if z_acc > 0:
        assert abs(p[0] - cx) <= abs(px - cx) + 1e-12
    elif z_acc < 0:
        assert abs(p[0] - cx) >= abs(px - cx) - 1e-12


def test_distance_outside_a_polygon():
    assert math.isclose(outside_distance_m(np.array([0.0, 0.0]), SQUARE), -0.05)
    assert math.isclose(outside_distance_m(np.array([0.13, 0.0]), SQUARE), 0.03)
    assert math.isclose(outside_distance_m(np.array([0.0, -0.07]), SQUARE[::-1]), 0.02)  # either orientation


def test_a_bouncing_com_needs_the_cop_beyond_the_sole():
    """A CoM 4 cm beside the planned CoP on the sole's edge (as in single support: the CoM between the feet,
    the CoP on the stance sole's inner edge), bobbing 2 cm at 2.5 Hz. At the bottom of the bob (z̈ > 0) the
    floor pushes harder, so the same sideways acceleration needs the CoP nearer the CoM: beyond the sole.
    Without the bob it stays on the plan's."""
    t = np.linspace(0.0, 0.4, 41)
    z0 = 0.6
    bob = z0 + 0.02 * np.cos(2 * math.pi * 2.5 * t)
    com = np.tile([0.0, 0.09], (len(t), 1))
    cop = np.tile([0.0, 0.05], (len(t), 1))  # on the square's edge y = 0.05
    supports = [SQUARE] * len(t)
    still = cop_demands(t, np.full(len(t), z0), com, cop, supports, np.full(len(t), z0), 0.0)
    assert max(d.outside_m for d in still) < 1e-9
    moving = cop_demands(t, bob, com, cop, supports, np.full(len(t), z0), 0.0)
    worst = max(moving, key=lambda d: d.outside_m)
    assert worst.outside_m > 0.01 and worst.com_vertical_accel_mps2 > 3.0
    assert min(d.load_share for d in moving) < 1.0 < max(d.load_share for d in moving)
    assert isinstance(worst, CopDemand)


def test_the_plan_follower_keeps_a_standing_plan_still():
    """Standing on a square support, the MPC started at rest over its centre stays there."""
    from engine.control.mpc import SupportInterval

    follower = PlanFollower(preview_s=2.0)
    for k in range(20):
        t = 0.05 * k
        com, cop, ok = follower.step(t, [SupportInterval(t, t + 2.0, SQUARE)], 0.6, np.zeros(2))
        assert ok and np.allclose(com, 0.0, atol=1e-6) and np.allclose(cop, 0.0, atol=1e-6)


def test_a_plan_whose_com_left_its_cop_is_marked_diverged():
    """An open-loop plan that fell behind its footholds (CoM metres from the CoP) gives no verdict on the style."""
    t = np.linspace(0.0, 0.2, 5)
    near = cop_demands(t, np.full(5, 0.6), np.tile([0.0, 0.09], (5, 1)), np.tile([0.0, 0.05], (5, 1)), [SQUARE] * 5,
                       np.full(5, 0.6), 0.0)
    far = cop_demands(t, np.full(5, 0.6), np.tile([-2.0, 0.0], (5, 1)), np.tile([0.0, 0.0], (5, 1)), [SQUARE] * 5,
                      np.full(5, 0.6), 0.0)
    assert not any(d.plan_diverged for d in near) and all(d.plan_diverged for d in far)
