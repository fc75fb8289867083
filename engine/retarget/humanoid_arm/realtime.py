"""Timing of one live LWL2 call: wall time, the thread's CPU time, preemption, and an optional real-time
section.

On a loaded machine the wall-clock p99 of a ~1 ms computation is set by the scheduler, not by the computation:
every call slower than 2 ms in `studio bench puppet` (load average 12–28 on 2 cores) had an involuntary context
switch in it (``getrusage(RUSAGE_THREAD).ru_nivcsw``), none ran the garbage collector, and none used more than
2 ms of the thread's CPU time. A *real-time section* runs the call under ``SCHED_FIFO`` (the calling thread only,
for the call's duration, then back to its previous policy), so ordinary processes cannot preempt it; Linux's
real-time throttling (``sched_rt_runtime_us``) still bounds it. It needs ``CAP_SYS_NICE`` (root, or the
capability); without it the call runs normally and :attr:`RealtimeSection.available` says so.
"""

from __future__ import annotations

import gc
import os
import resource
import time
from dataclasses import dataclass

RT_PRIORITY = 10  # low among real-time priorities (1..99): above every ordinary process, below the kernel's own
_gc_runs = [0]  # garbage collections started in this process (any thread), counted by the hook below


def _count_gc(phase: str, info: dict) -> None:
    if phase == "start":
        _gc_runs[0] += 1


if _count_gc not in gc.callbacks:
    gc.callbacks.append(_count_gc)


@dataclass
class CallTiming:
    wall_s: float
    cpu_s: float  # the calling thread's CPU time
    preempted: bool  # an involuntary context switch happened during the call
    realtime: bool  # ran in a real-time section
    gc: bool = False  # a garbage collection ran during the call


class RealtimeSection:
    """``with section.run(enabled): ...`` — time the body; under SCHED_FIFO when ``enabled`` and permitted."""

    def __init__(self) -> None:
        self.available: bool | None = None  # unknown until first tried
        self.error = ""
        self.last: CallTiming | None = None

    def _enter(self) -> tuple[int, os.sched_param] | None:
        if self.available is False or not hasattr(os, "SCHED_FIFO"):
            return None
        try:
            previous = (os.sched_getscheduler(0), os.sched_getparam(0))
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(RT_PRIORITY))
        except OSError as exc:  # EPERM without CAP_SYS_NICE: run normally
            self.available, self.error = False, f"real-time priority unavailable: {exc.strerror or exc}"
            return None
        self.available = True
        return previous

    @staticmethod
    def _leave(previous: tuple[int, os.sched_param] | None) -> None:
        if previous is not None:
            os.sched_setscheduler(0, previous[0], previous[1])

    def run(self, enabled: bool) -> "_Timed":
        return _Timed(self, enabled)


class _Timed:
    def __init__(self, section: RealtimeSection, enabled: bool):
        self.section, self.enabled = section, enabled

    def __enter__(self) -> None:
        self.previous = self.section._enter() if self.enabled else None
        self.switches = resource.getrusage(resource.RUSAGE_THREAD).ru_nivcsw
        self.gc_runs = _gc_runs[0]
        self.cpu0, self.wall0 = time.thread_time(), time.perf_counter()

    def __exit__(self, *exc) -> None:
        wall, cpu = time.perf_counter() - self.wall0, time.thread_time() - self.cpu0
        preempted = resource.getrusage(resource.RUSAGE_THREAD).ru_nivcsw > self.switches
        self.section._leave(self.previous)
        self.section.last = CallTiming(wall, cpu, preempted, self.previous is not None, _gc_runs[0] > self.gc_runs)


__all__ = ["RealtimeSection", "CallTiming", "RT_PRIORITY"]
