"""Tests for engine.gait.phase_map (gait phase map Ω, paper Sec. 5.1)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import PchipInterpolator

from engine.gait.phase_map import (
    PHASE_WAYPOINTS,
    PHI_LTD,
    PHI_RLO,
    PHI_RTD,
    PhaseMap,
    equivalent_time,
)

SETTINGS = settings(max_examples=80, deadline=None)


@st.composite
def phase_maps(draw) -> PhaseMap:
    """Valid event times 0 < t_LTD < t_RLO < t_RTD < T_S (gaps >= 2 % of T_S)."""
    gaps = draw(st.lists(st.floats(0.02, 1.0), min_size=4, max_size=4))
    cycle_s = draw(st.floats(0.3, 3.0))
    c = np.cumsum(gaps) / sum(gaps) * cycle_s
    return PhaseMap(float(c[0]), float(c[1]), float(c[2]), cycle_s)


def circ(a, b, period: float = 1.0):
    """Distance on the circle of the given period (phase 1 - ulp ~ phase 0)."""
    d = np.mod(np.asarray(a, dtype=float) - np.asarray(b, dtype=float), period)
    return np.minimum(d, period - d)


def _events(m: PhaseMap) -> list[tuple[float, float]]:
    return list(zip(PHASE_WAYPOINTS, m.event_times_s))


def test_phase_constants() -> None:
    assert (PHI_LTD, PHI_RLO, PHI_RTD) == (0.1, 0.5, 0.6)
    assert PHASE_WAYPOINTS == (0.0, 0.1, 0.5, 0.6, 1.0)


@SETTINGS
@given(phase_maps())
def test_strictly_increasing(m: PhaseMap) -> None:
    phi = np.linspace(0.0, 1.0, 4001)
    t = m.time_at(phi)
    assert np.all(np.diff(t) > 0.0)
    assert np.all(m.dtime_dphase(phi) > 0.0)
    # inverse also strictly increasing
    tt = np.linspace(0.0, m.cycle_s, 4001, endpoint=False)
    assert np.all(np.diff(m.phase_at(tt)) > 0.0)


@SETTINGS
@given(phase_maps())
def test_events_map_exactly(m: PhaseMap) -> None:
    for phi, t in _events(m):
        assert m.time_at(phi) == t
        if phi < 1.0:
            assert m.phase_at(t) == phi
    assert m.phase_at(m.cycle_s) == 0.0  # wraps to the next LLO
    np.testing.assert_array_equal(m.time_at(np.array(PHASE_WAYPOINTS)), m.event_times_s)
    np.testing.assert_array_equal(m.phase_at(np.array(m.event_times_s[:4])), PHASE_WAYPOINTS[:4])


@SETTINGS
@given(phase_maps(), st.lists(st.floats(0.0, 1.0, exclude_max=True), min_size=1, max_size=50))
def test_inverse_round_trip(m: PhaseMap, phis: list[float]) -> None:
    # circular distance: phi = 1 - ulp legitimately maps to T_S and wraps to 0
    phi = np.array(phis)
    assert circ(m.phase_at(m.time_at(phi)), phi).max() <= 1e-12
    t = phi * m.cycle_s
    assert circ(m.time_at(m.phase_at(t)), t, m.cycle_s).max() <= 1e-12 * m.cycle_s
    for p in phis[:10]:
        assert circ(m.phase_at(m.time_at(p)), p) <= 1e-12
        assert circ(m.time_at(m.phase_at(p * m.cycle_s)), p * m.cycle_s, m.cycle_s) <= 1e-12


@SETTINGS
@given(phase_maps(), st.lists(st.floats(-10.0, 10.0), min_size=1, max_size=120))
def test_scalar_and_vector_agree(m: PhaseMap, xs: list[float]) -> None:
    x = np.array(xs)
    for f in (m.time_at, m.phase_at, m.dtime_dphase, m.unwrapped_phase, m.dphase_dtime):
        vec = f(x)
        assert vec.shape == x.shape
        np.testing.assert_allclose(vec, [f(float(v)) for v in xs], rtol=1e-13, atol=1e-13)
        assert isinstance(f(float(xs[0])), float)
        assert isinstance(f(np.array(xs[0])), float)
    np.testing.assert_array_equal(m.cycle_index(x), [m.cycle_index(float(v)) for v in xs])
    assert isinstance(m.cycle_index(float(xs[0])), int)


@SETTINGS
@given(phase_maps(), st.floats(0.0, 1.0, exclude_max=True), st.integers(-5, 5))
def test_periodic_wrap(m: PhaseMap, u: float, k: int) -> None:
    t = u * m.cycle_s
    tk = t + k * m.cycle_s
    phi = m.phase_at(t)
    assert 0.0 <= m.phase_at(tk) < 1.0
    assert circ(m.phase_at(tk), phi) <= 1e-9
    assert m.cycle_index(tk) in (k - 1, k, k + 1)  # boundary rounding
    assert m.unwrapped_phase(tk) == pytest.approx(k + phi, abs=1e-9)
    assert m.cycle_index(tk) + m.phase_at(tk) == m.unwrapped_phase(tk)
    assert m.time_at(phi + k) == pytest.approx(m.time_at(phi) + k * m.cycle_s, abs=1e-9)


@SETTINGS
@given(phase_maps())
def test_c1_including_cycle_wrap(m: PhaseMap) -> None:
    for phi in PHASE_WAYPOINTS[1:4]:
        left = m.dtime_dphase(np.nextafter(phi, 0.0))
        assert left == pytest.approx(m.dtime_dphase(phi), rel=1e-9)
    assert m.dtime_dphase(np.nextafter(1.0, 0.0)) == pytest.approx(m.dtime_dphase(0.0), rel=1e-9)
    # unwrapped phase is continuous across cycle boundaries
    eps = 1e-9 * m.cycle_s
    for k in (-1, 1, 2):
        a, b = m.unwrapped_phase(k * m.cycle_s - eps), m.unwrapped_phase(k * m.cycle_s + eps)
        assert 0.0 < b - a < 1e-6


@SETTINGS
@given(phase_maps())
def test_interior_slopes_match_scipy_pchip(m: PhaseMap) -> None:
    ref = PchipInterpolator(PHASE_WAYPOINTS, m.event_times_s)
    phi = np.array(PHASE_WAYPOINTS[1:4])
    np.testing.assert_allclose(m.dtime_dphase(phi), ref.derivative()(phi), rtol=1e-12)


@SETTINGS
@given(phase_maps(), phase_maps())
def test_equivalent_time_maps_events_to_events(a: PhaseMap, b: PhaseMap) -> None:
    for ta, tb in zip(a.event_times_s[:4], b.event_times_s[:4]):
        assert equivalent_time(ta, a, b) == tb
    assert equivalent_time(a.cycle_s, a, b) == 0.0
    assert equivalent_time(a.cycle_s, a, b, keep_cycle=True) == pytest.approx(b.cycle_s, abs=1e-12)
    t = np.linspace(0.0, a.cycle_s, 500, endpoint=False)
    tb = equivalent_time(t, a, b)
    assert np.all(np.diff(tb) > 0.0) and tb[0] == 0.0 and tb[-1] < b.cycle_s
    # round trip through B and back
    np.testing.assert_allclose(equivalent_time(tb, b, a), t, atol=1e-9)
    # identity map
    np.testing.assert_allclose(equivalent_time(t, a, a), t, atol=1e-12)
    # keep_cycle: continuous and monotone over several cycles
    t3 = np.linspace(-a.cycle_s, 2 * a.cycle_s, 900)
    tb3 = equivalent_time(t3, a, b, keep_cycle=True)
    assert np.all(np.diff(tb3) > 0.0)


def test_symmetric_gait_is_close_to_linear() -> None:
    # double support 10 %, single support 40 %: waypoints lie on a line
    m = PhaseMap(0.1, 0.5, 0.6, 1.0)
    phi = np.linspace(0.0, 1.0, 101)
    np.testing.assert_allclose(m.time_at(phi), phi, atol=1e-15)
    np.testing.assert_allclose(m.phase_at(phi[:-1]), phi[:-1], atol=1e-15)


def test_invalid_events_rejected() -> None:
    for bad in [(0.0, 0.5, 0.6, 1.0), (0.2, 0.1, 0.6, 1.0), (0.1, 0.5, 0.5, 1.0),
                (0.1, 0.5, 0.6, 0.6), (0.1, 0.5, float("nan"), 1.0), (-0.1, 0.5, 0.6, 1.0)]:
        with pytest.raises(ValueError):
            PhaseMap(*bad)


def test_properties_and_equality() -> None:
    m = PhaseMap(0.12, 0.55, 0.68, 1.1)
    assert m.event_times_s == (0.0, 0.12, 0.55, 0.68, 1.1)
    assert (m.t_ltd_s, m.t_rlo_s, m.t_rtd_s, m.cycle_s) == (0.12, 0.55, 0.68, 1.1)
    assert m == PhaseMap(0.12, 0.55, 0.68, 1.1) and hash(m) == hash(PhaseMap(0.12, 0.55, 0.68, 1.1))
    assert m != PhaseMap(0.1, 0.55, 0.68, 1.1)
    assert m.dphase_dtime(0.3) == pytest.approx(1.0 / m.dtime_dphase(m.phase_at(0.3)))
    assert m.cycle_index(-1e-3) == -1 and m.cycle_index(1.1) == 1 and m.cycle_index(0.0) == 0
