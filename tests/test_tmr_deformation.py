"""Temporal deformation s_α (STMR Fig. 3a): the paper's invariants as hypothesis properties."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.retarget.quadruped.tmr.deformation import (
    DeformationError,
    TemporalDeformation,
    check_log2_bound,
    check_segments,
    interpolate_points,
    interpolate_qpos,
)

log2s = st.lists(st.floats(-1.0, 1.0), min_size=1, max_size=5)


@given(log2s, st.floats(0.2, 20.0))
@settings(max_examples=60, deadline=None)
def test_s_alpha_maps_the_deformed_clip_onto_the_source_monotonically(b: list[float], duration: float) -> None:
    d = TemporalDeformation.from_log2(b, duration)
    seg = duration / len(b)
    assert d.duration_s == pytest.approx(sum(2.0**x for x in b) * seg)
    t = np.linspace(0.0, d.duration_s, 200)
    s = d(t)
    assert s[0] == pytest.approx(0.0) and s[-1] == pytest.approx(duration)
    assert np.all(np.diff(s) >= -1e-12)
    # segment i of the source takes α_i · T/S of control time: its knots map onto the source's
    np.testing.assert_allclose(d(d.control_knots_s), d.source_knots_s, atol=1e-9)
    # inside segment i the source advances at rate 1/α_i
    for i, x in enumerate(b):
        a, c = d.control_knots_s[i], d.control_knots_s[i + 1]
        mid = np.array([a + 0.25 * (c - a), a + 0.75 * (c - a)])
        assert (d(mid[1]) - d(mid[0])) / (mid[1] - mid[0]) == pytest.approx(2.0 ** -x, rel=1e-6)


def test_identity_alpha_keeps_time() -> None:
    d = TemporalDeformation((1.0, 1.0, 1.0), 3.0)
    t = np.linspace(0, 3, 31)
    np.testing.assert_allclose(d(t), t)


@given(st.integers(2, 40), st.floats(10.0, 200.0))
@settings(max_examples=30, deadline=None)
def test_linear_interpolation_hits_the_frames_and_keeps_unit_quaternions(frames: int, fps: float) -> None:
    rng = np.random.default_rng(frames)
    q = rng.standard_normal((frames, 10))
    q[:, 3:7] /= np.linalg.norm(q[:, 3:7], axis=1, keepdims=True)
    t_frames = np.arange(frames) / fps
    out = interpolate_qpos(q, fps, t_frames)
    np.testing.assert_allclose(np.abs(np.sum(out[:, 3:7] * q[:, 3:7], axis=1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(out[:, [0, 1, 2, 7, 8, 9]], q[:, [0, 1, 2, 7, 8, 9]], atol=1e-9)
    mid = interpolate_qpos(q, fps, t_frames[:-1] + 0.5 / fps)
    np.testing.assert_allclose(np.linalg.norm(mid[:, 3:7], axis=1), 1.0, atol=1e-9)
    p = rng.standard_normal((frames, 16, 3))
    np.testing.assert_allclose(interpolate_points(p, fps, t_frames[:-1] + 0.5 / fps), 0.5 * (p[:-1] + p[1:]), atol=1e-9)


@pytest.mark.parametrize("bound", [0.0, -1.0, 2.5, float("nan")])
def test_bad_bounds_are_refused(bound: float) -> None:
    with pytest.raises(DeformationError):
        check_log2_bound(bound)


def test_segments_need_two_frames_each() -> None:
    assert check_segments(3, 6, 50.0) == 3
    with pytest.raises(DeformationError):
        check_segments(0, 100, 50.0)
    with pytest.raises(DeformationError):
        check_segments(4, 7, 50.0)


@settings(max_examples=40, deadline=None)
@given(z0=st.floats(0.2, 0.5), z1=st.floats(0.2, 0.5), dx=st.floats(-0.5, 0.5), before=st.integers(1, 5),
       air=st.integers(2, 60), after=st.integers(1, 5), dt=st.sampled_from([0.005, 0.01, 0.02]))
def test_re_timed_flights_are_ballistic_between_take_off_and_landing(z0, z1, dx, before, air, after, dt) -> None:  # noqa: ANN001
    from engine.retarget.quadruped.tmr.deformation import ballistic_flights, flight_intervals

    n = before + air + after
    contact = np.ones((n, 4), dtype=bool)
    contact[before: before + air] = False
    q = np.zeros((n, 19))
    q[:, 3] = 1.0
    q[:before, 2], q[before + air:, 2] = z0, z1
    q[before + air:, 0] = dx
    q[before: before + air, 2] = 3.0  # a kinematic arc made at another timing
    out = ballistic_flights(q, contact, dt)
    a, b = flight_intervals(contact)[0]
    assert (a, b) == (before - 1, before + air)
    np.testing.assert_allclose(out[[a, b], :3], q[[a, b], :3], atol=1e-12)  # take-off and landing kept
    np.testing.assert_allclose(np.diff(out[a: b + 1, 2], 2), -9.81 * dt**2, atol=1e-9)  # gravity only
    np.testing.assert_allclose(np.diff(out[a: b + 1, 0], 2), 0.0, atol=1e-12)  # constant horizontal velocity
    np.testing.assert_array_equal(out[:, 3:], q[:, 3:])  # orientation and joints untouched


@settings(max_examples=40, deadline=None)
@given(before=st.integers(2, 6), air=st.integers(1, 8), after=st.integers(2, 6), log2_alpha=st.floats(-1.0, 1.0))
def test_re_timed_flights_take_off_and_land_on_the_sources_stance_frames(before, air, after, log2_alpha) -> None:  # noqa: ANN001
    """A sample interpolated between a stance frame and a flight frame is airborne, so the deformed flight's
    take-off and landing samples carry the source's stance configurations (no jump of the base at take-off)."""
    from engine.retarget.quadruped.tmr.deformation import ballistic_flights, flight_intervals, sample_contact

    fps, dt = 10.0, 0.01
    n = before + air + after
    contact = np.ones((n, 4), dtype=bool)
    contact[before: before + air] = False
    contact[0, 1] = False  # a swing foot keeps its nearest-frame state
    q = np.zeros((n, 19))
    q[:, 3] = 1.0
    q[:, 2] = 0.3
    q[before: before + air, 2] = 0.8  # the source's arc
    d = TemporalDeformation.from_log2([log2_alpha], (n - 1) / fps)
    src = d(np.arange(int(np.floor(d.duration_s / dt + 1e-9)) + 1) * dt)
    c = sample_contact(contact, fps, src)
    x = src * fps
    stance_frame = np.isclose(x, np.rint(x)) & contact[np.clip(np.rint(x).astype(int), 0, n - 1)].any(axis=1)
    inside = (x > before - 1 + 1e-9) & (x < before + air - 1e-9)
    assert not c[inside].any()  # strictly between the last and first stance frames: airborne
    (a, b), = flight_intervals(c)
    assert x[a] <= before - 1 + 1e-9 and x[b] >= before + air - 1e-9
    assert stance_frame[a] or x[a] < before - 1  # take-off at (or before) the last stance frame
    out = ballistic_flights(interpolate_qpos(q, fps, src), c, dt)
    assert out[a, 2] == pytest.approx(0.3) and out[b, 2] == pytest.approx(0.3)
    assert not c[0, 1] and c[0, 0]  # outside the flight, each foot keeps its nearest frame's state
