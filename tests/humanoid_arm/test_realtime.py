"""Timing of live LWL2 calls (realtime.py): wall and CPU time, preemption, the real-time section restores the
thread's scheduling policy; the puppet's statistics split real-time and ordinary calls."""

from __future__ import annotations

import os

import numpy as np

from engine.retarget.humanoid_arm.puppet_session import PuppetStats
from engine.retarget.humanoid_arm.realtime import CallTiming, RealtimeSection


def _busy(n: int = 20_000) -> float:
    return float(np.sum(np.arange(n, dtype=float) ** 2))


def test_an_ordinary_call_is_timed_and_not_real_time():
    section = RealtimeSection()
    with section.run(False):
        _busy()
    t = section.last
    assert t is not None and not t.realtime
    assert 0.0 < t.cpu_s and 0.0 < t.wall_s
    assert t.cpu_s <= t.wall_s + 1e-3  # the thread cannot use more CPU than wall time (clock granularity aside)
    assert section.available is None  # never tried


def test_a_real_time_section_restores_the_policy_or_says_why_not():
    before = (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority)
    section = RealtimeSection()
    with section.run(True):
        inside = os.sched_getscheduler(0)
        _busy()
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before
    assert section.last is not None
    if section.available:
        assert inside == os.SCHED_FIFO and section.last.realtime and section.error == ""
    else:
        assert inside == before[0] and not section.last.realtime
        assert section.error.startswith("real-time priority unavailable")
        with section.run(True):  # not retried: runs normally
            pass
        assert not section.last.realtime


def test_the_statistics_split_real_time_and_ordinary_calls():
    stats = PuppetStats()
    for k in range(100):
        rt = k % 2 == 1
        stats.add(CallTiming(wall_s=0.001 if rt else (0.030 if k == 50 else 0.001), cpu_s=0.0009, preempted=k == 50,
                             realtime=rt))
    s = stats.summary()
    assert s["realtime_calls"] == 50 and s["preempted"] == 1
    assert s["inference_us_p99_realtime"] == 1000.0
    assert s["inference_us_p99_ordinary"] > 1000.0  # the preempted ordinary call
    assert s["inference_cpu_us_p99"] == 900.0
    empty = PuppetStats().summary()
    assert empty["inference_us_p99"] == 0.0 and empty["realtime_calls"] == 0


def test_a_garbage_collection_during_a_call_is_counted():
    import gc

    section = RealtimeSection()
    with section.run(False):
        gc.collect()
    assert section.last is not None and section.last.gc
    with section.run(False):
        _busy(10)
    assert not section.last.gc
    stats = PuppetStats()
    stats.add(CallTiming(0.003, 0.001, True, False, True))
    stats.add(CallTiming(0.001, 0.001, False, False, False))
    s = stats.summary()
    assert (s["slow_calls"], s["slow_calls_preempted"], s["gc_during_calls"]) == (1, 1, 1)
