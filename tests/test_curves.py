"""Tests for engine.gait.curves (cubic Hermite function curves)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.gait.curves import MIN_KNOT_GAP_S, HermiteCurve, Knot, TangentMode

SETTINGS = settings(max_examples=60, deadline=None)
C1_MODES = (TangentMode.AUTO_CLAMPED, TangentMode.FLAT, TangentMode.ALIGNED)

values_st = st.one_of(
    st.floats(-2.0, 2.0, allow_nan=False, allow_infinity=False),
    st.sampled_from([0.0, 0.5, 1.0]),  # repeated values -> flat neighbours
)
slopes_st = st.floats(-20.0, 20.0, allow_nan=False, allow_infinity=False)


@st.composite
def knot_times(draw, n: int, duration_s: float, periodic: bool) -> list[float]:
    """n strictly increasing knot times inside the curve domain, reasonably spaced."""
    gaps = draw(st.lists(st.floats(0.05, 1.0), min_size=n + 1, max_size=n + 1))
    c = np.cumsum(gaps)
    times = (duration_s * c[:n] / c[-1]).tolist()
    if n and draw(st.booleans()):
        times[0] = 0.0
    if n > 1 and not periodic and draw(st.booleans()):
        times[-1] = duration_s
    return times


@st.composite
def curves(draw, modes=tuple(TangentMode), periodic=None, min_knots: int = 2) -> HermiteCurve:
    if periodic is None:
        periodic = draw(st.booleans())
    duration_s = draw(st.floats(0.2, 3.0))
    n = draw(st.integers(min_knots, 7))
    times = draw(knot_times(n, duration_s, periodic))
    knots = []
    for t in times:
        mode = draw(st.sampled_from(modes))
        v = draw(values_st)
        a = draw(slopes_st)
        b = draw(slopes_st) if mode is TangentMode.FREE else a
        knots.append(Knot(t, v, a, b, mode))
    return HermiteCurve(knots, duration_s, periodic)


def segment_spans(c: HermiteCurve) -> list[tuple[float, float, float, float]]:
    """(t0, t1, v0, v1) of every segment (periodic wrap segment included)."""
    ks = c.knots
    spans = [(a.t_s, b.t_s, a.value, b.value) for a, b in zip(ks, ks[1:])]
    if c.periodic:
        spans.append((ks[-1].t_s, ks[0].t_s + c.duration_s, ks[-1].value, ks[0].value))
    return spans


# --------------------------------------------------------------- properties
@SETTINGS
@given(curves(modes=(TangentMode.AUTO_CLAMPED,)))
def test_auto_clamped_never_overshoots(c: HermiteCurve) -> None:
    for t0, t1, v0, v1 in segment_spans(c):
        v = c.evaluate(np.linspace(t0, t1, 257))
        tol = 1e-12 * (1.0 + abs(v0) + abs(v1))
        assert v.min() >= min(v0, v1) - tol
        assert v.max() <= max(v0, v1) + tol


@SETTINGS
@given(curves(modes=(TangentMode.AUTO_CLAMPED, TangentMode.FLAT)))
def test_auto_and_flat_mix_never_overshoots(c: HermiteCurve) -> None:
    for t0, t1, v0, v1 in segment_spans(c):
        v = c.evaluate(np.linspace(t0, t1, 129))
        tol = 1e-12 * (1.0 + abs(v0) + abs(v1))
        assert min(v0, v1) - tol <= v.min() and v.max() <= max(v0, v1) + tol


@SETTINGS
@given(curves(modes=C1_MODES))
def test_c1_at_interior_knots_for_smooth_modes(c: HermiteCurve) -> None:
    m_in, m_out = c.resolved_slopes()
    np.testing.assert_array_equal(m_in, m_out)
    ks = c.knots
    interior = ks if c.periodic else ks[1:-1]
    for k in interior:
        if k.t_s == 0.0 and c.periodic:
            left = np.nextafter(c.duration_s, 0.0)
        else:
            left = np.nextafter(k.t_s, -np.inf)
        scale = 1.0 + abs(k.in_slope) + abs(c.second_derivative(k.t_s))
        assert c.evaluate(left) == pytest.approx(k.value, abs=1e-9)
        assert c.derivative(left) == pytest.approx(c.derivative(k.t_s), abs=1e-9 * scale)
        assert c.derivative(k.t_s) == pytest.approx(k.out_slope, abs=1e-12 * scale)


@SETTINGS
@given(curves(periodic=True))
def test_periodic_c0_everywhere_and_wraps(c: HermiteCurve) -> None:
    d = c.duration_s
    just_before = float(np.nextafter(d, 0.0))
    assert c.evaluate(just_before) == pytest.approx(c.evaluate(0.0), abs=1e-9)
    t = np.linspace(-d, 2 * d, 61)
    np.testing.assert_allclose(c.evaluate(t + d), c.evaluate(t), atol=1e-9)
    # derivatives of LINEAR / FREE knots may jump at knots: compare away from them
    ks = np.array([k.t_s for k in c.knots])
    u = np.mod(t, d)
    dist = np.abs(u[:, None] - ks[None, :])
    away = np.min(np.minimum(dist, d - dist), axis=1) > 1e-9 * d
    np.testing.assert_allclose(c.derivative(t - 3 * d)[away], c.derivative(t)[away], atol=1e-7)


@SETTINGS
@given(curves(modes=C1_MODES, periodic=True))
def test_periodic_c1_across_wrap(c: HermiteCurve) -> None:
    d = c.duration_s
    just_before = float(np.nextafter(d, 0.0))
    curv = max(abs(c.second_derivative(0.0)), abs(c.second_derivative(just_before)))
    tol = 1e-9 * (1.0 + abs(c.derivative(0.0)) + curv)
    assert c.derivative(just_before) == pytest.approx(c.derivative(0.0), abs=tol)
    assert c.derivative(-1e-13) == pytest.approx(c.derivative(0.0), abs=tol + 2e-13 * curv)


@SETTINGS
@given(curves(min_knots=1))
def test_evaluate_at_knots_returns_knot_values(c: HermiteCurve) -> None:
    ks = c.knots
    for k in ks:
        assert c.evaluate(k.t_s) == k.value
    np.testing.assert_array_equal(c.evaluate(np.array([k.t_s for k in ks])), [k.value for k in ks])


@SETTINGS
@given(curves(), st.floats(0.1, 5.0), st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20))
def test_rescaled_preserves_normalised_shape(c: HermiteCurve, d2: float, u: list[float]) -> None:
    d1 = c.duration_s
    r = c.rescaled(d2)
    assert r.duration_s == d2 and r.periodic == c.periodic and r.n_knots == c.n_knots
    t = np.array(u) * d1 * (1 - 1e-9)
    t2 = t * d2 / d1
    np.testing.assert_allclose(r.evaluate(t2), c.evaluate(t), atol=1e-9)
    scale = 1.0 + np.abs(c.derivative(t))
    # knot-boundary rounding may pick the neighbouring segment; C0 keeps values
    # close, for derivatives compare away from knots only
    ks = np.array([k.t_s for k in c.knots])
    away = np.min(np.abs(t[:, None] - ks[None, :]), axis=1) > 1e-6 * d1
    np.testing.assert_allclose(
        r.derivative(t2)[away], (c.derivative(t) * d1 / d2)[away], atol=1e-7 * scale.max() * d1 / d2
    )
    np.testing.assert_allclose(
        r.second_derivative(t2)[away],
        (c.second_derivative(t) * (d1 / d2) ** 2)[away],
        rtol=1e-6,
        atol=1e-6 * (1.0 + np.abs(c.second_derivative(t)).max()) * (d1 / d2) ** 2,
    )


@SETTINGS
@given(curves())
def test_bezier_control_points_reproduce_curve(c: HermiteCurve) -> None:
    cp = c.bezier_control_points()
    assert cp.shape == (c.n_segments, 4, 2)
    for seg in cp:
        for u in (0.0, 0.2, 0.5, 0.77, 1.0):
            p = seg.copy()
            for r in range(3, 0, -1):  # de Casteljau
                p = (1 - u) * p[:r] + u * p[1 : r + 1]
            t, v = p[0]
            assert v == pytest.approx(c.evaluate(t), abs=1e-9 * (1 + np.abs(cp[..., 1]).max()))


@SETTINGS
@given(curves(min_knots=0), st.lists(st.floats(-5.0, 8.0), min_size=1, max_size=30))
def test_vectorised_matches_scalar(c: HermiteCurve, ts: list[float]) -> None:
    arr = np.array(ts)
    for f in (c.evaluate, c.derivative, c.second_derivative):
        vec = f(arr)
        assert vec.shape == arr.shape
        sca = np.array([f(float(t)) for t in ts])
        np.testing.assert_allclose(vec, sca, rtol=1e-12, atol=1e-12)
        assert isinstance(f(float(ts[0])), float)
        assert f(arr.reshape(-1, 1)).shape == (len(ts), 1)
        assert isinstance(f(np.array(ts[0])), float)  # 0-d array -> float
    # large arrays take the numpy path (small ones loop over the scalar path)
    dense = np.linspace(-1.0, c.duration_s + 1.0, 301)
    for f in (c.evaluate, c.derivative, c.second_derivative):
        np.testing.assert_allclose(f(dense), [f(float(t)) for t in dense], rtol=1e-12, atol=1e-12)
    # knots and extrapolation boundaries too
    kt = [k.t_s for k in c.knots] + [0.0, c.duration_s] + [k.t_s for k in c.knots] * 5
    np.testing.assert_allclose(c.evaluate(np.array(kt)), [c.evaluate(t) for t in kt], atol=1e-12)
    np.testing.assert_allclose(c.derivative(np.array(kt)), [c.derivative(t) for t in kt], atol=1e-12)


@SETTINGS
@given(curves(min_knots=0))
def test_dict_round_trip(c: HermiteCurve) -> None:
    d = json.loads(json.dumps(c.to_dict()))
    c2 = HermiteCurve.from_dict(d, c.duration_s, c.periodic)
    assert c2 == c
    t = np.linspace(-0.5, c.duration_s + 0.5, 50)
    np.testing.assert_array_equal(c2.evaluate(t), c.evaluate(t))


@SETTINGS
@given(curves(), st.data())
def test_knot_moved_keeps_order_and_domain(c: HermiteCurve, data: st.DataObject) -> None:
    i = data.draw(st.integers(0, c.n_knots - 1))
    t = data.draw(st.floats(-2 * c.duration_s, 3 * c.duration_s))
    v = data.draw(values_st)
    m = c.with_knot_moved(i, t, v)
    times = [k.t_s for k in m.knots]
    assert m.n_knots == c.n_knots
    assert m.knots[i].value == v
    assert all(b > a for a, b in zip(times, times[1:]))
    if m.periodic:
        assert 0.0 <= times[0] and times[-1] < m.duration_s
    else:
        assert 0.0 <= times[0] and times[-1] <= m.duration_s
    # other knots untouched
    for j, (a, b) in enumerate(zip(c.knots, m.knots)):
        if j != i:
            assert (a.t_s, a.value) == (b.t_s, b.value)


# ------------------------------------------------------------------- units
def test_empty_and_single_knot() -> None:
    c0 = HermiteCurve([], 1.0)
    assert c0.evaluate(0.3) == 0.0 and c0.derivative(0.3) == 0.0
    np.testing.assert_array_equal(c0.evaluate(np.array([0.1, 2.0])), [0.0, 0.0])
    assert c0.bezier_control_points().shape == (0, 4, 2)
    for periodic in (False, True):
        c1 = HermiteCurve([Knot(0.4, 2.5, 3.0, 3.0, TangentMode.ALIGNED)], 1.0, periodic)
        assert c1.evaluate(-3.0) == c1.evaluate(0.4) == c1.evaluate(7.0) == 2.5
        assert c1.derivative(0.4) == 0.0 and c1.second_derivative(0.9) == 0.0
        np.testing.assert_array_equal(c1.evaluate(np.array([0.0, 0.9])), [2.5, 2.5])


def test_identical_times_rejected_with_index() -> None:
    with pytest.raises(ValueError, match=r"knot 2 .*knot 0"):
        HermiteCurve([Knot(0.5, 0.0), Knot(0.1, 1.0), Knot(0.5, 2.0)], 1.0)


def test_invalid_inputs() -> None:
    with pytest.raises(ValueError, match="outside"):
        HermiteCurve([Knot(0.0, 0.0), Knot(1.0, 0.0)], 1.0, periodic=True)
    with pytest.raises(ValueError, match="outside"):
        HermiteCurve([Knot(0.0, 0.0), Knot(1.5, 0.0)], 1.0)
    with pytest.raises(ValueError, match="duration_s"):
        HermiteCurve([], 0.0)
    with pytest.raises(ValueError, match="ALIGNED"):
        HermiteCurve([Knot(0.0, 0.0, 1.0, 2.0, TangentMode.ALIGNED)], 1.0)
    with pytest.raises(ValueError, match="tangent mode"):
        HermiteCurve([Knot(0.0, 0.0, mode="bogus")], 1.0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="finite"):
        HermiteCurve([Knot(0.0, math.nan)], 1.0)


def test_knots_sorted_and_modes_from_strings() -> None:
    c = HermiteCurve([Knot(0.8, 1.0, mode="flat"), Knot(0.2, 3.0)], 1.0)  # type: ignore[arg-type]
    assert [k.t_s for k in c.knots] == [0.2, 0.8]
    assert c.knots[1].mode is TangentMode.FLAT


def test_auto_clamped_slopes() -> None:
    # uniform monotone data: parabolic three-point slope
    c = HermiteCurve([Knot(0.0, 0.0), Knot(1.0, 1.0), Knot(2.0, 3.0), Knot(3.0, 3.5)], 3.0)
    m_in, m_out = c.resolved_slopes()
    assert m_in[1] == pytest.approx(1.5) and m_in[2] == pytest.approx(1.25)
    assert m_in[0] == 0.0 and m_in[-1] == 0.0  # non-periodic ends: flat handles
    # local extremum and flat neighbour -> 0
    c = HermiteCurve([Knot(0, 0.0), Knot(1, 2.0), Knot(2, 1.0), Knot(3, 1.0), Knot(4, 5.0)], 4.0)
    _, m = c.resolved_slopes()
    assert m[1] == 0.0 and m[2] == 0.0 and m[3] == 0.0
    # Fritsch-Carlson limit: 3 * smaller secant
    c = HermiteCurve([Knot(0, 0.0), Knot(1, 0.1), Knot(2, 10.0)], 2.0)
    assert c.resolved_slopes()[0][1] == pytest.approx(0.3)
    # periodic: computed cyclically (first knot is not flat)
    c = HermiteCurve([Knot(0.0, 0.0), Knot(0.25, 1.0), Knot(0.5, 0.0), Knot(0.75, -1.0)], 1.0, True)
    _, m = c.resolved_slopes()
    assert m[0] == pytest.approx(4.0) and m[2] == pytest.approx(-4.0)
    assert m[1] == 0.0 and m[3] == 0.0


def test_flat_linear_free_slopes() -> None:
    ks = [
        Knot(0.0, 0.0, mode=TangentMode.LINEAR),
        Knot(1.0, 2.0, mode=TangentMode.LINEAR),
        Knot(3.0, 1.0, 5.0, 7.0, TangentMode.FLAT),
        Knot(4.0, 0.0, -1.0, 2.0, TangentMode.FREE),
        Knot(5.0, 4.0, mode=TangentMode.LINEAR),
    ]
    c = HermiteCurve(ks, 5.0)
    m_in, m_out = c.resolved_slopes()
    np.testing.assert_allclose(m_in, [2.0, 2.0, 0.0, -1.0, 4.0])
    np.testing.assert_allclose(m_out, [2.0, -0.5, 0.0, 2.0, 4.0])
    # all-linear curve is the polyline
    lin = HermiteCurve([Knot(k.t_s, k.value, mode=TangentMode.LINEAR) for k in ks], 5.0)
    t = np.linspace(0.0, 5.0, 101)
    np.testing.assert_allclose(lin.evaluate(t), np.interp(t, [0, 1, 3, 4, 5], [0, 2, 1, 0, 4]), atol=1e-12)
    # FREE break: derivative jumps at the knot
    assert c.derivative(np.nextafter(4.0, 0.0)) == pytest.approx(-1.0, abs=1e-6)
    assert c.derivative(4.0) == pytest.approx(2.0)


def test_non_periodic_extrapolation_holds() -> None:
    c = HermiteCurve([Knot(0.2, 1.0, mode="linear"), Knot(0.6, 3.0, mode="linear")], 1.0)  # type: ignore[arg-type]
    assert c.evaluate(0.0) == 1.0 and c.evaluate(0.9) == 3.0 and c.evaluate(-4.0) == 1.0
    assert c.derivative(0.1) == 0.0 and c.derivative(0.7) == 0.0
    assert c.derivative(0.2) == pytest.approx(5.0) and c.derivative(0.6) == pytest.approx(5.0)
    assert c.second_derivative(0.9) == 0.0


def test_swing_curve_rescale_keeps_end_knot() -> None:
    c = HermiteCurve([Knot(0.0, 0.0), Knot(0.13, 0.07), Knot(0.37, 0.0)], 0.37)
    r = c.rescaled(0.41)
    assert r.knots[-1].t_s == 0.41 and r.knots[0].t_s == 0.0
    assert r.evaluate(0.41) == 0.0
    assert r.knots[1].t_s == pytest.approx(0.13 * 0.41 / 0.37)
    with pytest.raises(ValueError):
        c.rescaled(-1.0)


def test_periodic_rescale_stays_inside_domain() -> None:
    d = 0.3
    c = HermiteCurve([Knot(0.0, 0.0), Knot(np.nextafter(d, 0.0), 1.0)], d, periodic=True)
    for d2 in (0.1, 0.7, 1.0 / 3.0, 0.9999999):
        r = c.rescaled(d2)
        assert r.knots[-1].t_s < d2


def test_knot_moved_clamps() -> None:
    c = HermiteCurve([Knot(0.0, 0.0), Knot(0.5, 1.0), Knot(1.0, 0.0)], 1.0)
    m = c.with_knot_moved(1, 5.0, 2.0)
    assert m.knots[1].t_s == pytest.approx(1.0 - MIN_KNOT_GAP_S) and m.knots[1].value == 2.0
    m = c.with_knot_moved(1, -5.0, 2.0)
    assert m.knots[1].t_s == pytest.approx(MIN_KNOT_GAP_S)
    m = c.with_knot_moved(-1, 7.0, 0.5)
    assert m.knots[2].t_s == 1.0
    assert c.knots[1].value == 1.0  # original untouched
    p = HermiteCurve([Knot(0.1, 0.0), Knot(0.5, 1.0), Knot(0.8, 0.0)], 1.0, periodic=True)
    assert p.with_knot_moved(2, 2.0, 0.0).knots[2].t_s == pytest.approx(1.0 - MIN_KNOT_GAP_S)
    assert p.with_knot_moved(0, -2.0, 0.0).knots[0].t_s == 0.0
    with pytest.raises(IndexError):
        c.with_knot_moved(3, 0.0, 0.0)


def test_knot_added_and_removed() -> None:
    c = HermiteCurve([Knot(0.0, 0.0), Knot(0.5, 1.0), Knot(1.0, 0.0)], 1.0)
    a = c.with_knot_added(0.25)
    assert a.n_knots == 4
    k = a.knots[1]
    assert k.t_s == 0.25 and k.value == c.evaluate(0.25) and k.mode is TangentMode.AUTO_CLAMPED
    with pytest.raises(ValueError, match="knot 1"):
        c.with_knot_added(0.5)
    r = a.with_knot_removed(1)
    assert r == c
    p = HermiteCurve([Knot(0.0, 0.0), Knot(0.5, 1.0)], 1.0, periodic=True)
    pa = p.with_knot_added(1.75)
    assert pa.knots[2].t_s == 0.75 and pa.knots[2].value == pytest.approx(p.evaluate(0.75))
    with pytest.raises(ValueError):
        c.with_knot_added(1.5)


def test_with_tangent() -> None:
    c = HermiteCurve([Knot(0.0, 0.0), Knot(1.0, 1.0), Knot(2.0, 3.0)], 2.0)
    t = np.linspace(0, 2, 41)
    # switching auto -> aligned/free without slopes keeps the shape
    for mode in (TangentMode.ALIGNED, TangentMode.FREE):
        np.testing.assert_array_equal(c.with_tangent(1, mode).evaluate(t), c.evaluate(t))
    a = c.with_tangent(1, "aligned", in_slope=0.3)
    assert a.resolved_slopes()[0][1] == 0.3 and a.resolved_slopes()[1][1] == 0.3
    f = c.with_tangent(1, TangentMode.FREE, out_slope=4.0)
    assert f.knots[1].in_slope == pytest.approx(1.5) and f.knots[1].out_slope == 4.0
    assert f.with_tangent(1, TangentMode.ALIGNED).knots[1].in_slope == pytest.approx(2.75)
    with pytest.raises(ValueError):
        c.with_tangent(1, TangentMode.ALIGNED, 1.0, 2.0)
    z = f.with_tangent(1, TangentMode.FLAT, 9.0, 9.0)
    assert z.knots[1].in_slope == 0.0 and z.knots[1].out_slope == 0.0
    back = f.with_tangent(1, TangentMode.AUTO_CLAMPED)
    np.testing.assert_array_equal(back.evaluate(t), c.evaluate(t))


def test_from_dict_abbreviated_rows() -> None:
    c = HermiteCurve.from_dict({"knots": [[0, 0], [0.2, 0.1, "flat"], [0.4, 0]]}, 0.4)
    assert [k.mode for k in c.knots] == [TangentMode.AUTO_CLAMPED, TangentMode.FLAT, TangentMode.AUTO_CLAMPED]
    with pytest.raises(ValueError, match="knot 0"):
        HermiteCurve.from_dict({"knots": [[0, 0, 1, 2]]}, 1.0)
    d = c.to_dict()
    assert d == {"knots": [[0.0, 0.0, 0.0, 0.0, "auto_clamped"], [0.2, 0.1, 0.0, 0.0, "flat"], [0.4, 0.0, 0.0, 0.0, "auto_clamped"]]}
