"""The simulation first: CPU priorities of the engine process's session and of its job threads (Linux).

The engine runs in its own session (``EngineProcess.start``), hence its own scheduler autogroup: the kernel shares
the CPU between sessions first, then between the threads of each. On two cores beside a software-WebGL tab the
paced simulation, which needs about half a core, still lost 50–170 ms at a time to the browser, and the status
line's real-time factor dipped to 0.89–0.97 in some seconds. ``prefer_simulation`` gives the engine's session the
niceness ``SESSION_NICENESS`` (a weight about three times a default session's). `studio bench render`'s 60 s walk,
idle (2026-11-30): at niceness 0, ten runs, 96.3–100 % of the status line's readings ≥ 0.98, the lowest reading of a
run 0.88–0.99; at −5, six runs, 100 %, every reading 1.00; the tab drew 6.0–6.7 frames per second instead of 6.3–7.1.
A lower niceness needs CAP_SYS_NICE (root, or the capability); without it the session keeps its niceness and
nothing else changes. Job threads (retargeting, TMR, libraries) run inside the engine process: they
take a higher niceness (``JOB_THREAD_NICENESS``, a thread's own, which needs no privilege), so the session's share
goes to the simulation first.
"""

from __future__ import annotations

import logging
import os
import threading
from pathlib import Path

SESSION_NICENESS = -5  # the engine session's autogroup niceness, where permitted
JOB_THREAD_NICENESS = 10  # added to a job thread's own niceness

log = logging.getLogger(__name__)

AUTOGROUP = Path("/proc/self/autogroup")


def prefer_simulation(niceness: int = SESSION_NICENESS, autogroup: Path = AUTOGROUP) -> bool:
    """Set this session's autogroup niceness (call it in the engine process, which leads its own session);
    True when it was set, False where autogroups are absent or the niceness is not permitted."""
    try:
        autogroup.write_text(f"{int(niceness)}\n")
    except OSError as exc:  # no autogroups (not Linux, or switched off), or no CAP_SYS_NICE for a negative niceness
        log.debug("engine session priority unchanged: %s", exc)
        return False
    return True


def lower_thread_priority(niceness: int) -> None:
    """Raise the calling thread's niceness by ``niceness`` (a no-op where threads have no niceness of their own)."""
    if niceness <= 0 or not hasattr(os, "setpriority"):
        return
    tid = threading.get_native_id()
    try:
        current = os.getpriority(os.PRIO_PROCESS, tid)
        os.setpriority(os.PRIO_PROCESS, tid, min(current + niceness, 19))
    except OSError as exc:  # not permitted somewhere: keep the priority
        log.debug("thread priority unchanged: %s", exc)
