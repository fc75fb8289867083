"""The compiled convex hull (engine.geometry.polygon.convex_hull_2d) equals its plain-Python reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from engine.geometry.polygon import convex_hull_2d, convex_hull_2d_numpy

coords = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)


@settings(max_examples=300, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(0, 16), st.just(2)), elements=coords))
def test_hull_equals_reference(points: np.ndarray) -> None:
    np.testing.assert_array_equal(convex_hull_2d(points), convex_hull_2d_numpy(points))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(st.integers(-3, 3), st.integers(-3, 3)), min_size=0, max_size=20))
def test_hull_equals_reference_on_a_grid(points: list[tuple[int, int]]) -> None:
    """Duplicates and collinear points (a coarse integer grid)."""
    pts = np.array(points, dtype=float).reshape(-1, 2) * 0.1
    np.testing.assert_array_equal(convex_hull_2d(pts), convex_hull_2d_numpy(pts))


def test_sole_rectangles() -> None:
    rng = np.random.default_rng(0)
    for _ in range(50):
        centre, yaw = rng.normal(0.0, 0.2, (2, 2)), rng.uniform(-np.pi, np.pi, 2)
        corners = []
        for c, a in zip(centre, yaw):
            rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
            corners.append(c + np.array([[-0.1, -0.04], [0.1, -0.04], [0.1, 0.04], [-0.1, 0.04]]) @ rot.T)
        pts = np.vstack(corners)
        np.testing.assert_array_equal(convex_hull_2d(pts), convex_hull_2d_numpy(pts))


AXES = [k * np.pi / 2 for k in range(-2, 3)]
#: Headings: the axes exactly, or at least 1e-6 rad off them. Between (an edge tilted 1e-12–1e-10 rad off vertical,
#: its corners' x a few 1e-12 m apart) the chain's 1e-15 collinear tolerance can still drop an end of the edge
#: (polygon.SAME_X_M: a known limit, README stop 40).
HEADINGS = st.sampled_from(AXES) | st.floats(-np.pi, np.pi).filter(
    lambda a: min(abs(a - axis) for axis in AXES) >= 1e-6)


@settings(max_examples=200, deadline=None)
@given(HEADINGS, st.floats(0.05, 0.4), st.floats(0.1, 0.3), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
def test_two_soles_side_by_side_give_their_rectangle_at_any_heading(yaw, gap_m, length_m, x, y):
    """Two soles side by side (a robot standing): the hull is the rectangle they span, whatever the heading. Turned by
    ±π, the corners on one edge differ in x by rounding alone (−0.09999999999999999 against −0.10000000000000002),
    and a hull sorted by raw x dropped an end of that edge (a hexagon inside the rectangle)."""
    from scipy.spatial import ConvexHull

    from engine.geometry.polygon import polygon_area

    rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
    sole = np.array([[length_m / 2, 0.04], [length_m / 2, -0.04], [-length_m / 2, -0.04], [-length_m / 2, 0.04]])
    pts = np.vstack([(sole + [0.0, side * (gap_m / 2 + 0.04)]) @ rot.T + [x, y] for side in (1.0, -1.0)])
    expected = ConvexHull(pts).volume  # (qhull: a 2-D hull's "volume" is its area)
    for hull in (convex_hull_2d(pts), convex_hull_2d_numpy(pts)):
        assert abs(polygon_area(hull)) == pytest.approx(expected, rel=1e-9)
        assert len(hull) == 4
