"""The closed-form initial-CoP clip (engine.geometry.polygon.clip_into_polygon) equals the bisection it replaced."""

from __future__ import annotations

import numpy as np


def test_clip_to_polygon_equals_the_bisection_it_replaced() -> None:
    """The closed-form clip returns exactly the point a 30-step bisection on the segment found."""
    from engine.control.mpc import polygon_centroid, polygon_halfplanes
    from engine.control.walking_controller import _clip_to_polygon

    def bisection(p, polygon):  # the implementation before the speed-up
        normals, offsets = polygon_halfplanes(polygon)
        if len(offsets) == 0 or np.all(normals @ p <= offsets + 1e-9):
            return p
        c = polygon_centroid(polygon)
        lo, hi = 0.0, 1.0
        for _ in range(30):
            mid = 0.5 * (lo + hi)
            if np.all(normals @ (c + mid * (p - c)) <= offsets + 1e-9):
                lo = mid
            else:
                hi = mid
        return c + lo * (p - c)

    rng = np.random.default_rng(7)
    for _ in range(400):
        center, yaw = rng.uniform(-1, 1, 2), rng.uniform(-np.pi, np.pi)
        half = rng.uniform(0.02, 0.2, 2)
        box = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * half
        rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        polygon = box @ rot.T + center
        p = center + rng.normal(0, 0.3, 2)
        np.testing.assert_array_equal(_clip_to_polygon(p, polygon), bisection(p, polygon))
