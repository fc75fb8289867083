"""Tests for engine.gait.velocity_sampler (paper Sec. 5.3, Table 3, Eqs. 8-10)."""

from __future__ import annotations

import json
import math
from typing import Callable

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.gait.velocity_sampler import (
    TURN_STRAFE_NAMES,
    SAMPLE_DISPLAY_NAMES,
    SAMPLE_INDEX,
    SAMPLE_NAMES,
    SampleVelocities,
    f_soft,
    sample_blend,
    sample_weights,
)

SETTINGS = settings(max_examples=60, deadline=None)
MIRROR = [SAMPLE_INDEX[n.replace("left", "#").replace("right", "left").replace("#", "right")]
          for n in SAMPLE_NAMES]


@st.composite
def sample_velocities(draw) -> SampleVelocities:
    x_max = draw(st.floats(0.2, 2.0))
    return SampleVelocities(
        x_max_mps=x_max,
        x_slow_mps=x_max * draw(st.floats(0.2, 0.8)),
        y_max_mps=draw(st.floats(0.1, 1.0)),
        yaw_max_radps=draw(st.floats(0.2, 3.0)),
    )


@st.composite
def commands(draw, vel: SampleVelocities, span: float = 1.5) -> tuple[float, float, float]:
    u = st.floats(-span, span)
    return (draw(u) * vel.x_max_mps, draw(u) * vel.y_max_mps, draw(u) * vel.yaw_max_radps)


def to_physical(vel: SampleVelocities, n: np.ndarray) -> tuple[float, float, float]:
    return (float(n[0] * vel.x_max_mps), float(n[1] * vel.y_max_mps), float(n[2] * vel.yaw_max_radps))


def jump_of_derivative(f: Callable[[float], np.ndarray], s0: float, h: float = 1e-6) -> float:
    """|right - left| one-sided difference quotients of f at s0 (≈ 0 for C1, O(1) at a kink)."""
    wm, w0, wp = f(s0 - h), f(s0), f(s0 + h)
    return float(np.max(np.abs((wp - w0) / h - (w0 - wm) / h)))


# ------------------------------------------------------------------ basics
def test_names_and_f_soft() -> None:
    assert len(SAMPLE_NAMES) == len(SAMPLE_DISPLAY_NAMES) == 9
    assert SAMPLE_NAMES[0] == "forward_fast" and SAMPLE_DISPLAY_NAMES[2] == "Step In Place"
    assert f_soft(0.0) == 0.0 and f_soft(1.0) == 1.0 and f_soft(0.5) == 0.5
    assert f_soft(-3.0) == 0.0 and f_soft(7.0) == 1.0 and f_soft(0.25) == pytest.approx(0.15625)
    np.testing.assert_allclose(f_soft(np.array([-1.0, 0.25, 2.0])), [0.0, 0.15625, 1.0])


def test_velocity_table() -> None:
    v = SampleVelocities(0.6, 0.25, 0.3, 1.2)
    assert v.velocity_of("forward_fast") == (0.6, 0.0, 0.0)
    assert v.velocity_of("reverse_slow") == (-0.25, 0.0, 0.0)
    assert v.velocity_of("right_strafe") == (0.0, -0.3, 0.0)
    assert v.velocity_of("left_turn") == (0.0, 0.0, 1.2)
    assert v.as_array().shape == (9, 3)
    with pytest.raises(ValueError):
        v.velocity_of("moonwalk")
    for bad in [(0.6, 0.6, 0.3, 1.0), (0.6, 0.0, 0.3, 1.0), (0.6, 0.2, 0.0, 1.0), (0.6, 0.2, 0.3, -1.0)]:
        with pytest.raises(ValueError):
            SampleVelocities(*bad)
    with pytest.raises(ValueError):
        sample_weights((0.0, 0.0, 0.0), v, eta=1.5)


def test_worked_example_matches_equations() -> None:
    vel = SampleVelocities(0.6, 0.2, 0.3, 1.0)
    v = (0.4, 0.15, -0.5)  # x_n = 2/3, y_n = 0.5, yaw_n = -0.5 -> beta = 3pi/4
    b = sample_blend(v, vel)
    ax = f_soft((0.4 - 0.2) / (0.6 - 0.2))
    ab = f_soft((3 * math.pi / 4 - math.pi / 2) / (math.pi / 2))
    ats = f_soft(math.hypot(0.5, 0.5) * (1 - 0.5 * f_soft(2 / 3)))
    assert b.forward_reverse_pair == ("forward_slow", "forward_fast")
    assert b.turn_strafe_pair == ("left_strafe", "right_turn")
    assert b.alpha_x == pytest.approx(ax) and b.alpha_beta == pytest.approx(ab) and b.alpha_ts == pytest.approx(ats)
    assert b.beta_rad == pytest.approx(3 * math.pi / 4) and b.rho_n == pytest.approx(math.sqrt(0.5))
    expected = {
        "forward_slow": (1 - ats) * (1 - ax),
        "forward_fast": (1 - ats) * ax,
        "left_strafe": ats * (1 - ab),
        "right_turn": ats * ab,
    }
    for name, w in expected.items():
        assert b.weight_of(name) == pytest.approx(w)
    assert set(b.nonzero()) == set(expected)
    np.testing.assert_array_equal(b.weights, sample_weights(v, vel))
    json.dumps(b.to_dict())


def test_beta_wrap_pair_and_clipping() -> None:
    vel = SampleVelocities(0.6, 0.2, 0.3, 1.0)
    b = sample_blend((0.0, -0.1, 0.5), vel)  # fourth quadrant
    assert b.turn_strafe_pair == ("right_strafe", "left_turn")
    assert 1.5 * math.pi < b.beta_rad < 2 * math.pi
    b = sample_blend((5.0, 9.0, 0.0), vel)  # beyond every limit: clipped
    assert b.x_n == 1.0 and b.rho_n == 1.0
    assert b.alpha_ts == pytest.approx(f_soft(0.5))
    assert b.weight_of("forward_fast") == pytest.approx(1 - f_soft(0.5))
    assert b.weight_of("left_strafe") == pytest.approx(f_soft(0.5))
    b = sample_blend((0.3, 0.0, 0.0), vel)  # no turn/strafe: beta irrelevant
    assert b.alpha_ts == 0.0 and b.rho_n == 0.0 and b.beta_rad == 0.0
    # eta = 0: turn/strafe not attenuated by forward speed
    assert sample_blend((0.6, 0.3, 0.0), vel, eta=0.0).weight_of("left_strafe") >= 0.999  # on the circle: soft clip


# ------------------------------------------------------------- properties
@SETTINGS
@given(st.data(), sample_velocities(), st.floats(0.0, 1.0))
def test_weights_form_partition_of_unity(data: st.DataObject, vel: SampleVelocities, eta: float) -> None:
    for _ in range(20):
        v = data.draw(commands(vel))
        w = sample_weights(v, vel, eta)
        assert w.shape == (9,)
        assert np.all(w >= 0.0)
        assert w.sum() == pytest.approx(1.0, abs=1e-12)
        assert np.count_nonzero(w) <= 4
        np.testing.assert_array_equal(sample_blend(v, vel, eta).weights, w)


@SETTINGS
@given(sample_velocities(), st.floats(0.0, 1.0))
def test_sample_weight_is_one_at_own_velocity(vel: SampleVelocities, eta: float) -> None:
    """Exact for forward/reverse/in place; turn/strafe samples sit on the unit circle, where the
    C1 soft clip of ρn (band RHO_CLIP_BAND) leaves them at ≥ 0.999 of their own weight."""
    for i, name in enumerate(SAMPLE_NAMES):
        w = sample_weights(vel.velocity_of(name), vel, eta)
        if name in TURN_STRAFE_NAMES:
            assert w[i] >= 0.999 and np.count_nonzero(w) == 2 and w[SAMPLE_NAMES.index("in_place")] == pytest.approx(1 - w[i])
        else:
            assert w[i] == 1.0
            assert np.count_nonzero(w) == 1


@SETTINGS
@given(st.data(), sample_velocities(), st.floats(0.0, 1.0))
def test_left_right_mirror_symmetry(data: st.DataObject, vel: SampleVelocities, eta: float) -> None:
    for _ in range(20):
        vx, vy, wz = data.draw(commands(vel))
        w = sample_weights((vx, vy, wz), vel, eta)
        wm = sample_weights((vx, -vy, -wz), vel, eta)
        np.testing.assert_array_equal(wm, w[MIRROR])


@SETTINGS
@given(
    sample_velocities(),
    st.lists(st.floats(-1.3, 1.3), min_size=3, max_size=3),
    st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
    st.lists(st.floats(-0.4, 0.4), min_size=3, max_size=3),
)
def test_weights_lipschitz_along_smooth_paths(vel: SampleVelocities, v0, a, b) -> None:
    """First differences along a smooth normalised path stay O(h)."""
    s = np.linspace(0.0, 1.0, 1201)
    h = s[1] - s[0]
    path = np.array(v0)[:, None] + np.array(a)[:, None] * s + np.array(b)[:, None] * np.sin(2 * np.pi * s)
    w = np.array([sample_weights(to_physical(vel, p), vel) for p in path.T])
    speed = np.linalg.norm(np.array(a)) + 2 * np.pi * np.linalg.norm(np.array(b))
    # |dw/dv_n| <= 1.5 / (x_slow / x_max) + O(1) for the turn/strafe terms
    lip = 1.5 / (vel.x_slow_mps / vel.x_max_mps) + 10.0
    assert np.abs(np.diff(w, axis=0)).max() <= lip * speed * h


@SETTINGS
@given(
    sample_velocities(),
    st.floats(-1.2, 1.2),
    st.floats(-0.9, 0.9).filter(lambda r: abs(r) > 1e-3),
    st.floats(-0.9, 0.9),
    st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(lambda d: abs(d[0]) > 1e-3),
)
def test_c1_crossing_vx_zero_and_sample_boundaries(vel, ratio, yn, wn, d) -> None:
    """vx crosses 0, ±x_slow and ±x_max (step-1 boundaries and |x_n| in Eq. 10)."""
    xs = vel.x_slow_mps / vel.x_max_mps
    for x0 in (0.0, xs, -xs, 1.0, -1.0, ratio):
        base = np.array([x0, yn, wn])
        if abs(math.hypot(yn, wn) - 1.0) < 1e-3:
            continue  # rho_n = 1 clip kink of Eq. (10), see module notes
        f = lambda s, base=base: sample_weights(to_physical(vel, base + s * np.array(d)), vel)
        assert jump_of_derivative(f, 0.0) < 2e-3


@SETTINGS
@given(
    sample_velocities(),
    st.floats(-1.2, 1.2),
    st.floats(0.05, 0.95),
    st.sampled_from([0, 1, 2, 3]),
    st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(lambda d: abs(d[1]) + abs(d[2]) > 1e-2),
)
def test_c1_crossing_turn_strafe_boundaries_and_beta_wrap(vel, xn, r, q, d) -> None:
    """β crosses the sample directions, including the 2π -> 0 wrap (q = 0)."""
    angle = q * math.pi / 2
    base = np.array([xn, r * math.sin(angle), r * math.cos(angle)])  # (x_n, y_n, yaw_n)
    f = lambda s: sample_weights(to_physical(vel, base + s * np.array(d)), vel)
    assert jump_of_derivative(f, 0.0) < 2e-3


@SETTINGS
@given(
    sample_velocities(),
    st.floats(-1.2, 1.2),
    st.floats(-math.pi, math.pi),
    st.floats(-1.0, 1.0),
)
def test_c1_through_rho_zero(vel, xn, angle, dx) -> None:
    """A straight path through ρn = 0 (β undefined there) is C1, derivative of w_ts → 0."""
    direction = np.array([dx, math.sin(angle), math.cos(angle)])
    base = np.array([xn, 0.0, 0.0])
    f = lambda s: sample_weights(to_physical(vel, base + s * direction), vel)
    assert jump_of_derivative(f, 0.0) < 2e-3
    # turn/strafe part has zero slope at the origin
    ts = [SAMPLE_INDEX[n] for n in ("left_turn", "left_strafe", "right_turn", "right_strafe")]
    h = 1e-4
    assert np.abs(f(h)[ts] - f(0.0)[ts]).max() < 10 * h * h


def test_c1_check_detects_a_kink() -> None:
    """Sanity check of the C1 detector itself."""
    assert jump_of_derivative(lambda s: np.array([abs(s)]), 0.0) > 1.0
    assert jump_of_derivative(lambda s: np.array([f_soft(s)]), 0.0) < 1e-5
