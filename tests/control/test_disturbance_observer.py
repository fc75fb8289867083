"""The external force observer: it finds a constant push from momentum and applied ground
forces, ignores small model errors, and never reports NaN."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.control.disturbance_observer import ExternalForceObserver

MASS_KG = 33.0
DT_S = 0.002


def simulate(observer: ExternalForceObserver, push_n: np.ndarray, seconds: float,
             ground_n=lambda t: np.zeros(2), model_error_n: np.ndarray | None = None) -> list[np.ndarray]:
    """A point mass under ground force + push; the observer sees the ground force it was told
    (plus an optional constant model error) and the true velocity."""
    v = np.zeros(2)
    observer.reset(v)
    estimates = []
    for k in range(int(round(seconds / DT_S))):
        t = k * DT_S
        f_ground = ground_n(t)
        v = v + (f_ground + push_n) / MASS_KG * DT_S
        told = f_ground if model_error_n is None else f_ground + model_error_n
        estimates.append(observer.update(DT_S, v, told).copy())
    return estimates


@settings(max_examples=30, deadline=None)
@given(st.floats(-120.0, 120.0), st.floats(-120.0, 120.0))
def test_a_constant_push_is_found_within_a_few_time_constants(fx: float, fy: float):
    push = np.array([fx, fy])
    observer = ExternalForceObserver(MASS_KG, time_constant_s=0.08, deadband_n_per_kg=0.25, max_n_per_kg=4.0)
    # The ground fights the push in a wobbly way (as stepping does): the estimate must not care.
    estimates = simulate(observer, push, 0.6, ground_n=lambda t: -0.5 * push + 20.0 * np.sin(12.0 * t))
    final = estimates[-1]
    norm = np.linalg.norm(push)
    if norm <= 0.25 * MASS_KG:
        assert np.allclose(final, 0.0)
    else:
        seen = min(norm, 4.0 * MASS_KG)  # beyond 4 N/kg it is a fall, not a push: capped
        expected = push / norm * (seen - 0.25 * MASS_KG)  # the deadband shrinks, never turns
        assert np.allclose(final, expected, atol=0.5)


def test_small_model_errors_do_not_show_as_a_push():
    observer = ExternalForceObserver(MASS_KG)
    estimates = simulate(observer, np.zeros(2), 2.0, model_error_n=np.array([5.0, -5.0]))
    assert max(np.linalg.norm(e) for e in estimates) == 0.0


def test_a_fall_is_capped_and_bad_input_is_ignored():
    observer = ExternalForceObserver(MASS_KG, max_n_per_kg=4.0)
    estimates = simulate(observer, np.array([2000.0, 0.0]), 0.5)
    assert max(np.linalg.norm(e) for e in estimates) <= 4.0 * MASS_KG + 1e-9
    before = observer.force_n.copy()
    assert np.array_equal(observer.update(DT_S, np.array([np.nan, 0.0]), np.zeros(2)), before)
    assert np.array_equal(observer.update(DT_S, np.zeros(2), np.array([np.inf, 0.0])), before)
    assert np.array_equal(observer.update(DT_S, np.zeros(2), None), before)
    observer.reset()
    assert observer.magnitude_n == 0.0
