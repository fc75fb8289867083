"""The studio's streaming threads yield the CPU to the engine: their niceness goes up, the caller's only."""

from __future__ import annotations

import os
import threading

import pytest

from studio.thread_priority import yield_to_engine


@pytest.mark.skipif(not hasattr(os, "setpriority"), reason="no per-thread niceness here")
def test_yield_to_engine_raises_only_the_calling_threads_niceness():
    seen: dict[str, int] = {}

    def streaming() -> None:
        tid = threading.get_native_id()
        before = os.getpriority(os.PRIO_PROCESS, tid)
        yield_to_engine(5)
        seen["before"], seen["after"] = before, os.getpriority(os.PRIO_PROCESS, tid)

    main_before = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    t = threading.Thread(target=streaming)
    t.start()
    t.join()
    assert seen["after"] == min(seen["before"] + 5, 19)
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == main_before  # this thread untouched
    yield_to_engine(0)  # nothing asked: nothing changes
    assert os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) == main_before
