"""The engine: core commands, the real-time process, and the studio's restart of a dead engine."""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

from engine import protocol as msg
from engine.core import EngineCore
from engine.process import EngineProcess
from studio.engine_link import EngineLink


def make_core(robot: str = "g1") -> tuple[EngineCore, list]:
    events: list = []
    return EngineCore(robot, events.append), events


def test_core_announces_robot_and_publishes_frames():
    core, events = make_core()
    loaded = events[0]
    assert isinstance(loaded, msg.RobotLoaded) and loaded.robot == "g1" and loaded.simulated
    for _ in range(50):
        core.tick()
    frame = core.frame()
    assert frame.body_pos.shape == (len(loaded.body_names), 3)
    assert frame.body_quat.shape == (len(loaded.body_names), 4)
    assert frame.sim_time_s == pytest.approx(0.1)
    np.testing.assert_allclose(np.linalg.norm(frame.body_quat, axis=1), 1.0, atol=1e-5)


def test_pause_push_reset_and_switch():
    core, events = make_core()
    core.handle(msg.SetPaused(True))
    core.tick()
    assert core.frame().sim_time_s == 0.0
    core.handle(msg.SetPaused(False))
    core.handle(msg.ApplyPush((0.0, 60.0, 0.0), 0.3))
    for _ in range(150):
        core.tick()
    root = core.sim.data.qvel[1]
    assert root > 0.05  # pushed to +y
    core.handle(msg.Reset())
    assert core.frame().sim_time_s == 0.0
    core.handle(msg.SwitchRobot("go2"))
    assert events[-1].robot == "go2" and core.frame().body_pos.shape[0] == len(events[-1].body_names)


def test_bad_commands_become_notices_not_crashes():
    core, events = make_core()
    core.handle(msg.SwitchRobot("nosuch"))
    core.handle(msg.ApplyPush((float("nan"), 0.0, 0.0), 1.0))
    notices = [e for e in events if isinstance(e, msg.Notice)]
    assert len(notices) == 2 and "unknown robot 'nosuch'" in notices[0].message
    assert core.robot.name == "g1"
    core.tick()


def test_fallen_robot_is_reset():
    core, events = make_core()
    core.handle(msg.ApplyPush((0.0, 500.0, 0.0), 0.5))
    for _ in range(2000):
        core.tick()
    assert any(isinstance(e, msg.Notice) and "fell" in e.message for e in events)
    assert not core.sim.fallen  # reset after lying down for a moment


def test_source_skeleton_is_shown_not_simulated():
    core, events = make_core("human")
    assert events[0].simulated is False
    frame = core.frame()
    assert frame.body_pos[:, 2].max() > 1.4  # upright (y-up converted): neck frame 1.45 m up


def test_engine_process_paces_and_publishes():
    """Frames arrive, the simulated clock only moves forward and never runs ahead of the wall clock.

    No speed assertion (a 3x slower machine must pass): the real-time factor and the publish rate are
    figures of `studio bench engine`.
    """
    engine = EngineProcess("g1")
    engine.start()
    try:
        frames, loaded = [], None
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and len(frames) < 30:
            event = engine.recv(0.5)
            if isinstance(event, msg.RobotLoaded):
                loaded = event
            elif isinstance(event, msg.Frame):
                frames.append((time.monotonic(), event))
        assert loaded is not None and len(frames) >= 30
        sim = [f.sim_time_s for _, f in frames]
        assert all(b >= a for a, b in zip(sim, sim[1:])) and sim[-1] > sim[0]  # monotone and advancing
        (w0, f0), (w1, f1) = frames[0], frames[-1]
        assert f1.sim_time_s - f0.sim_time_s <= (w1 - w0) + 0.1  # paced: never ahead of the wall clock
        assert [f.seq for _, f in frames] == sorted(f.seq for _, f in frames)
        # its own session (scheduler autogroup): the browser's and the studio's threads share the CPU with it
        # as groups, not thread by thread
        assert engine.pid is not None and os.getsid(engine.pid) == engine.pid != os.getsid(0)
    finally:
        engine.stop()
    assert not engine.alive()


def test_link_restarts_a_killed_engine_and_replays_state():
    events, statuses = [], []
    loaded = threading.Event()

    def on_event(e):
        events.append(e)
        if isinstance(e, msg.RobotLoaded):
            loaded.set()

    link = EngineLink("g1", on_event, lambda level, text: statuses.append((level, text)))
    link.start()
    try:
        assert loaded.wait(30)
        link.send(msg.SwitchRobot("go1"))
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not any(getattr(e, "robot", "") == "go1" for e in events):
            time.sleep(0.05)
        old_pid = link.pid
        loaded.clear()
        os.kill(old_pid, signal.SIGKILL)
        t_kill = time.monotonic()
        while time.monotonic() - t_kill < 60 and (link.pid == old_pid or link.pid is None):
            time.sleep(0.02)
        assert link.pid not in (None, old_pid)  # how fast: `studio bench engine`
        assert any(level == "error" and "stopped" in text for level, text in statuses)
        assert loaded.wait(30)
        robots = [e.robot for e in events if isinstance(e, msg.RobotLoaded)]
        assert robots[-1] == "go1"  # the user's robot choice survived the crash
    finally:
        link.stop()
