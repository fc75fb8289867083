"""The compiled convex hull (engine.geometry.polygon.convex_hull_2d) equals its plain-Python reference."""

from __future__ import annotations

import numpy as np
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
