"""Which sole edge the reference stands on, and how far the CoM lies outside the grounded corners' support
(engine/gait/support_edges.py: the rehearsal's "edges" onset, issue 13)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.gait.support_edges import EDGE_FLAT, EDGE_HEEL, EDGE_TOE, outside_support_m, support_edges
from engine.geometry.rotation import rot_z

LENGTH, WIDTH = 0.2, 0.08


def foot(x: float, y: float, yaw: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position (3,), rotation (3, 3), corners (4, 3)) of a flat sole centred at (x, y) heading ``yaw``:
    corners front-left, front-right, back-right, back-left."""
    rot = rot_z(yaw)
    local = np.array([[LENGTH / 2, WIDTH / 2, 0], [LENGTH / 2, -WIDTH / 2, 0], [-LENGTH / 2, -WIDTH / 2, 0],
                      [-LENGTH / 2, WIDTH / 2, 0]])
    pos = np.array([x, y, 0.0])
    return pos, rot, pos + local @ rot.T


def pair(yaw: float = 0.0, left_down=(1, 1, 1, 1), right_down=(1, 1, 1, 1), contact=(True, True)):
    """Both feet 0.2 m apart side by side, the pair turned by ``yaw`` about the origin; the reference's arrays."""
    turn = rot_z(yaw)
    (pl, rl, cl), (pr, rr, cr) = (foot(*(turn @ [0.0, y, 0.0])[:2], yaw) for y in (0.1, -0.1))
    return (np.array(contact), np.array([left_down, right_down], dtype=bool), np.stack([cl, cr]), np.stack([pl, pr]),
            np.stack([rl, rr]))


def test_a_sole_on_its_front_corners_stands_on_its_toe_on_its_back_corners_on_its_heel():
    contact, corners_down, corners, pos, rot = pair(left_down=(1, 1, 0, 0), right_down=(0, 0, 1, 1))
    assert support_edges(contact, corners_down, corners, pos, rot).tolist() == [EDGE_TOE, EDGE_HEEL]
    contact, corners_down, corners, pos, rot = pair()
    assert support_edges(contact, corners_down, corners, pos, rot).tolist() == [EDGE_FLAT, EDGE_FLAT]
    # a foot in the air stands on nothing, whatever its corners say
    contact, corners_down, corners, pos, rot = pair(left_down=(1, 1, 0, 0), contact=(False, True))
    assert support_edges(contact, corners_down, corners, pos, rot).tolist() == [EDGE_FLAT, EDGE_FLAT]


@settings(max_examples=60, deadline=None)
@given(st.floats(-math.pi, math.pi))
def test_both_feet_on_their_toes_leave_the_point_between_the_ankles_behind_them_at_any_heading(yaw):
    contact, corners_down, corners, pos, rot = pair(yaw, left_down=(1, 1, 0, 0), right_down=(1, 1, 0, 0))
    assert support_edges(contact, corners_down, corners, pos, rot).tolist() == [EDGE_TOE, EDGE_TOE]
    between = pos[:, :2].mean(axis=0)
    # the toe line lies half a sole ahead of the ankles' midpoint
    assert math.isclose(outside_support_m(between, contact, corners_down, corners), LENGTH / 2, abs_tol=1e-9)
    # flat, the same point is inside (by the half sole to the nearest edge: front and back)
    contact, corners_down, corners, pos, rot = pair(yaw)
    assert math.isclose(outside_support_m(between, contact, corners_down, corners), -LENGTH / 2, abs_tol=1e-9)


def test_the_edge_codes_are_the_planners():
    from engine.gait.planner_kernels import EDGE_CODES

    assert (EDGE_FLAT, EDGE_HEEL, EDGE_TOE) == (EDGE_CODES[None], EDGE_CODES["heel"], EDGE_CODES["toe"])


def test_no_corner_down_has_no_support():
    contact, corners_down, corners, _, _ = pair(contact=(False, False))
    assert math.isnan(outside_support_m(np.zeros(2), contact, corners_down, corners))
