"""Bench section for the engine process as the studio runs it: timing figures that tests must not assert.

``studio bench engine``: real-time factor and publish rate of ``python -m engine`` (paced to wall clock),
and the time the studio's link takes to notice a kill -9 of the engine and have a new one publishing.
"""

from __future__ import annotations

import os
import signal
import threading
import time


def bench_engine(robot: str = "g1", seconds: float = 4.0) -> list[dict]:
    from engine import protocol as msg
    from engine.process import EngineProcess
    from studio.engine_link import EngineLink

    engine = EngineProcess(robot)
    engine.start()
    frames: list[tuple[float, float]] = []
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            event = engine.recv(0.5)
            if isinstance(event, msg.Frame):
                frames.append((time.monotonic(), event.sim_time_s))
                if frames[-1][0] - frames[0][0] > seconds + 1.0:
                    break
    finally:
        engine.stop()
    warm = [f for f in frames if f[0] - frames[0][0] >= 1.0]  # skip the first second (start-up)
    (w0, s0), (w1, s1) = warm[0], warm[-1]
    rows = [_row(robot, "paced run", wall_s=round(w1 - w0, 2), real_time_factor=round((s1 - s0) / (w1 - w0), 3),
                 frames_per_s=round((len(warm) - 1) / (w1 - w0), 1))]

    loaded = threading.Event()
    link = EngineLink(robot, lambda e: loaded.set() if isinstance(e, msg.RobotLoaded) else None)
    link.start()
    try:
        loaded.wait(60)
        old = link.pid
        assert old is not None
        loaded.clear()
        t0 = time.monotonic()
        os.kill(old, signal.SIGKILL)
        while link.pid in (None, old) and time.monotonic() - t0 < 30:
            time.sleep(0.01)
        respawn_s = time.monotonic() - t0
        loaded.wait(60)
        rows.append(_row(robot, "kill -9, new engine", respawn_s=round(respawn_s, 3),
                         robot_loaded_s=round(time.monotonic() - t0, 3)))
    finally:
        link.stop()
    return rows


def _row(robot: str, what: str, **figures: float) -> dict:
    keys = ("wall_s", "real_time_factor", "frames_per_s", "respawn_s", "robot_loaded_s")
    return {"section": "engine", "robot": robot, "what": what, **{k: figures.get(k, "") for k in keys}}
