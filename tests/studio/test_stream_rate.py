"""The studio's stream rate (studio/stream_rate.py): every engine frame while the engine keeps real time,
fewer — never under the floor — while it falls behind, and back to full once it keeps up again."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from studio.stream_rate import ADAPT_PERIOD_S, FRAME_HZ, StreamRate


def _run(rate: StreamRate, rtf: float, seconds: float, t0: float = 0.0, hz: float = 60.0) -> tuple[int, float]:
    """Feed ``hz`` frames per second carrying ``rtf`` for ``seconds``; (frames admitted, end time)."""
    admitted, n = 0, int(round(seconds * hz))
    for i in range(n):
        now = t0 + i / hz
        rate.adapt(now, rtf)
        admitted += rate.admit(now)
    return admitted, t0 + n / hz


def test_an_engine_on_time_gets_every_frame_drawn():
    rate = StreamRate(*FRAME_HZ)
    admitted, _ = _run(rate, 1.0, 10.0)
    assert admitted == 600 and rate.full


def test_an_engine_behind_gets_the_floor_rate_then_full_again():
    floor, full = FRAME_HZ
    rate = StreamRate(floor, full)
    _, t = _run(rate, 0.5, 10.0)  # the engine is short of CPU: the studio streams less
    assert rate.rate_hz == floor
    admitted, t = _run(rate, 0.5, 10.0, t)
    assert abs(admitted - 10 * floor) <= 2  # 24 of 60 frames/s, not every third (20)
    _, t = _run(rate, 1.0, 10.0, t)  # the engine keeps real time again
    assert rate.full
    admitted, _ = _run(rate, 1.0, 1.0, t)
    assert admitted == 60


@settings(max_examples=60, deadline=None)
@given(reports=st.lists(st.tuples(st.floats(0.0, 1.2), st.floats(0.1, 3.0)), min_size=1, max_size=12),
       hz=st.sampled_from([30.0, 60.0, 90.0]))
def test_the_rate_stays_between_floor_and_full_and_admits_no_more_than_it(reports, hz):
    floor, full = FRAME_HZ
    rate = StreamRate(floor, full)
    t = 0.0
    for rtf, seconds in reports:
        start_rate = rate.rate_hz
        admitted, t_end = _run(rate, rtf, seconds, t, hz)
        assert floor <= rate.rate_hz <= full
        assert admitted <= int(round(seconds * hz))  # never more than offered
        most = max(start_rate, rate.rate_hz)
        if most < full:  # throttled: never more than the highest rate reached allows (+2: credit carried over)
            assert admitted <= (t_end - t) * most + 2
        t = t_end


def test_urgent_frames_always_go_out():
    rate = StreamRate(*FRAME_HZ)
    _run(rate, 0.3, 10.0)
    assert not rate.full
    assert all(rate.admit(100.0 + i * 1e-4, urgent=True) for i in range(10))


def test_the_rate_moves_at_most_once_per_period():
    rate = StreamRate(*FRAME_HZ)
    rate.adapt(0.0, 0.5)
    for i in range(100):
        rate.adapt(0.001 * i, 0.5)
    assert rate.full  # one period has not passed
    rate.adapt(ADAPT_PERIOD_S, 0.5)
    assert not rate.full


def test_floor_above_full_is_refused():
    with pytest.raises(ValueError):
        StreamRate(30.0, 20.0)
