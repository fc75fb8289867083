"""Issue 12 (glue11): the walking controller's half-plane and contact tests on lists of flags decide as the array
methods they replaced (bool(array.all())), NaN included."""

from __future__ import annotations

import math

import numpy as np

from engine.control.walking_controller import _inside_polygon
from engine.geometry.polygon import halfplanes_cached


def inside_polygon_reference(p: np.ndarray, polygon: np.ndarray) -> bool:
    """walking_controller._inside_polygon before: the array's all()."""
    normals, offsets, bound = halfplanes_cached(polygon)
    return len(offsets) == 0 or bool((normals @ p <= bound).all())


def test_inside_polygon_equals_the_array_all() -> None:
    rng = np.random.default_rng(3)
    inside = outside = 0
    for trial in range(2000):
        n = int(rng.integers(3, 9))
        angles = np.sort(rng.uniform(0.0, 2.0 * math.pi, n))
        polygon = np.stack([np.cos(angles), np.sin(angles)], axis=1) * rng.uniform(0.05, 0.3) + rng.standard_normal(2)
        p = polygon.mean(axis=0) + rng.standard_normal(2) * rng.choice([0.01, 0.1, 1.0])
        if trial % 50 == 0:
            p[int(rng.integers(2))] = rng.choice([math.nan, math.inf, -math.inf])
        want = inside_polygon_reference(p, polygon)
        assert _inside_polygon(p, polygon) == want
        inside += want
        outside += not want
    for degenerate in (np.zeros((0, 2)), np.array([[0.0, 0.0]]), np.array([[0.0, 0.0], [1.0, 0.0]])):
        p = np.array([0.5, 0.0])
        assert _inside_polygon(p, degenerate) == inside_polygon_reference(p, degenerate)
    assert inside > 200 and outside > 200


def test_contact_all_on_a_list_equals_the_array_all() -> None:
    for a in (False, True):
        for b in (False, True):
            contact = np.array([a, b])
            assert all(contact.tolist()) == bool(contact.all())
