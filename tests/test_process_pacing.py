"""Pacing of the engine process (engine.process.ticks_due): a short stall is paid back, a long one is dropped."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from engine.process import MAX_BACKLOG_S, MAX_BATCH_TICKS, ticks_due

PERIOD_S = 0.002


def run_after_stall(stall_s: float, tick_cost_s: float = 0.0) -> tuple[int, float]:
    """Ticks run and origin after a stall of ``stall_s`` from an up-to-date clock, on a machine whose tick
    costs ``tick_cost_s`` of wall time, until the clock owes nothing."""
    now, wall0, ticks = stall_s, 0.0, 0
    for _ in range(100_000):
        due, wall0 = ticks_due(now, wall0, ticks, PERIOD_S)
        if due == 0:
            break
        assert due <= MAX_BATCH_TICKS
        ticks += due
        now += due * tick_cost_s
    return ticks, wall0


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, MAX_BACKLOG_S - 0.01))
def test_a_stall_shorter_than_the_backlog_costs_no_simulated_time(stall_s):
    ticks, wall0 = run_after_stall(stall_s, tick_cost_s=PERIOD_S / 4)
    assert wall0 == 0.0  # nothing dropped
    assert ticks >= int(stall_s / PERIOD_S)  # every owed tick was run


@settings(max_examples=60, deadline=None)
@given(st.floats(MAX_BACKLOG_S + 0.01, 30.0))
def test_a_long_stall_drops_only_what_exceeds_the_backlog(stall_s):
    ticks, wall0 = run_after_stall(stall_s)
    backlog_ticks = round(MAX_BACKLOG_S / PERIOD_S)
    assert abs(wall0 - (stall_s - backlog_ticks * PERIOD_S)) <= PERIOD_S  # the excess moved the origin
    assert abs(ticks - backlog_ticks) <= 1  # the backlog itself was run


def test_never_runs_ahead_of_wall_time():
    now, wall0, ticks = 0.0, 0.0, 0
    for step in range(2000):
        now = step * 0.0007
        due, wall0 = ticks_due(now, wall0, ticks, PERIOD_S)
        ticks += due
        assert wall0 + ticks * PERIOD_S <= now + 1e-12
