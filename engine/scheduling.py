"""The simulation first: the engine process's session CPU priority, and a thread's own niceness (Linux; the
studio's streaming threads raise theirs with :func:`lower_thread_priority`).

The engine runs in its own session (``EngineProcess.start``), hence its own scheduler autogroup: the kernel shares
the CPU between sessions first, then between the threads of each. On two cores beside a software-WebGL tab the
paced simulation, which needs about half a core, still lost 50–170 ms at a time to the browser, and the status
line's real-time factor dipped to 0.89–0.97 in some seconds. ``prefer_simulation`` gives the engine's session the
niceness ``SESSION_NICENESS`` (a weight about three times a default session's). `studio bench render`'s 60 s walk,
idle (2026-11-30): at niceness 0, ten runs, 96.3–100 % of the status line's readings ≥ 0.98, the lowest reading of a
run 0.88–0.99; at −5, six runs, 100 %, every reading 1.00; the tab drew 6.0–6.7 frames per second instead of 6.3–7.1.
A lower niceness needs CAP_SYS_NICE (root, or the capability); without it the session keeps its niceness and
nothing else changes. Only a process that leads its own session sets it (a hand-started ``python -m engine`` in a
terminal leaves the terminal's session alone). The engine's job threads (retarget, import, export, poses) keep the
session's priority: at a higher niceness of their own, one preempted while holding the GIL would keep the simulation
thread waiting where autogroups do not apply (a process in a non-root CPU cgroup).
"""

from __future__ import annotations

import logging
import os
import threading
import time
from pathlib import Path

SESSION_NICENESS = -5  # the engine session's autogroup niceness, where permitted
AUTOGROUP_RETRY_S = 0.11  # without CAP_SYS_ADMIN the kernel takes one autogroup write per 100 ms, system-wide

log = logging.getLogger(__name__)

AUTOGROUP = Path("/proc/self/autogroup")


def autogroup_niceness(autogroup: Path = AUTOGROUP) -> int | None:
    """This session's autogroup niceness; None where there is none to read: no autogroups, or a process left in the
    kernel's default group (the file then reads empty, as in some containers whose processes never started a
    session of their own)."""
    try:
        fields = autogroup.read_text().split()
    except OSError:
        return None
    try:
        return int(fields[-1]) if len(fields) >= 3 and fields[-2] == "nice" else None
    except ValueError:
        return None


def prefer_simulation(niceness: int = SESSION_NICENESS, autogroup: Path = AUTOGROUP) -> bool:
    """Set this session's autogroup niceness when this process leads its session (the engine process does);
    True when it was set, False where it is not the session leader, autogroups are absent or the niceness is not
    permitted."""
    if hasattr(os, "getsid") and os.getsid(0) != os.getpid():
        log.debug("engine session priority unchanged: not the leader of its session")
        return False
    for attempt in range(2):
        try:
            autogroup.write_text(f"{int(niceness)}\n")
            return True
        except BlockingIOError:  # EAGAIN: another process wrote an autogroup niceness within the last 100 ms
            if attempt == 0:
                time.sleep(AUTOGROUP_RETRY_S)
        except OSError as exc:  # no autogroups (not Linux, or switched off), or no CAP_SYS_NICE for a negative niceness
            log.debug("engine session priority unchanged: %s", exc)
            return False
    log.info("engine session priority unchanged: the kernel refused two autogroup writes 100 ms apart")
    return False


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
