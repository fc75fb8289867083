"""The engine process: EngineCore paced to wall-clock real time, talking over a socket pair.

``EngineProcess`` is the parent's handle (start, send, receive, watch); ``engine_main`` is
the child's entry point (``python -m engine``). The child exits by itself when the parent
goes away (EOF on the socket, or re-parenting).
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path

from engine import protocol as msg
from engine.outbox import Outbox
from engine.scheduling import prefer_simulation

REPO_ROOT = Path(__file__).resolve().parents[1]
PUBLISH_HZ = 60.0
TELEMETRY_HZ = 20.0
MAX_BATCH_TICKS = 25  # at most 50 ms of simulation between two looks at commands, frames and telemetry
MAX_BACKLOG_S = 0.25  # behind wall time by more than this: drop the excess (a stall is not replayed at speed)
COMMAND_POLL_TICKS = 4  # read commands every planner tick, even inside a catch-up batch


def engine_main(conn: Connection, robot: str) -> None:
    """Child process entry point."""
    outbox = Outbox(conn)  # events go out from their own thread: the simulation never waits for the studio
    try:
        _simulate(conn, outbox.put, robot)
    finally:
        outbox.close()  # what is pending still goes out (a notice before the end), for at most a second


def _simulate(conn: Connection, emit: Callable[[msg.Event], None], robot: str) -> None:
    """Read commands from ``conn``, tick the simulation paced to wall time, ``emit`` frames and telemetry."""
    from engine.core import CONTROL_RATE_HZ, EngineCore  # heavy imports happen in the child

    try:
        core = EngineCore(robot, emit)
    except Exception as exc:  # a broken robot must not leave the studio without an engine
        emit(msg.Notice("error", f"engine could not load {robot!r}: {exc}"))
        from engine.robot.config import DEFAULT_ROBOT

        core = EngineCore(DEFAULT_ROBOT, emit)

    publish_period = 1.0 / PUBLISH_HZ
    telemetry_period = 1.0 / TELEMETRY_HZ
    next_telemetry = time.perf_counter()
    wall0 = time.perf_counter()
    ticks = 0
    next_publish = wall0
    rtf_wall, rtf_ticks = wall0, 0
    parent = os.getppid()
    publish_now = False
    published_revision = core.style_revision

    def read_commands() -> bool:
        """Apply pending commands; True when the clock must restart or a frame should go out now."""
        nonlocal publish_now
        restart = False
        while conn.poll():
            command = conn.recv()
            if isinstance(command, msg.Shutdown):
                raise _ShutdownRequested
            robot_before = core.robot.name
            core.handle(command)
            if core.robot.name != robot_before or isinstance(command, msg.SetPlaybackSpeed):
                restart = True
            if isinstance(command, (msg.SetMode, msg.Reset)):
                publish_now = True  # show edits at once (edit latency)
            # A style edit goes out with the first frame computed with it (see the tick loop).
        return restart

    try:
        while True:
            if read_commands():
                wall0, ticks = time.perf_counter(), 0
                rtf_wall, rtf_ticks = wall0, 0
            period = 1.0 / (CONTROL_RATE_HZ * core.playback_speed)
            now = time.perf_counter()
            if core.running:
                due, wall0 = ticks_due(now, wall0, ticks, period)
                for i in range(due):
                    core.tick()
                    ticks += 1
                    if core.style_revision != published_revision:
                        break  # the first pose planned with an edit goes out at once (edit latency)
                    if i % COMMAND_POLL_TICKS == COMMAND_POLL_TICKS - 1:
                        read_commands()
                        # An edit, or a frame due: a slow machine still streams at PUBLISH_HZ
                        # (the rest of the batch runs after the frame goes out).
                        if publish_now or time.perf_counter() >= next_publish:
                            break
            else:
                wall0 = now - ticks * period
            for event in core.jobs.drain():  # job workers never write to the pipe themselves
                emit(event)
            now = time.perf_counter()
            if now - rtf_wall >= 1.0:
                core.real_time_factor = (ticks - rtf_ticks) / CONTROL_RATE_HZ / (now - rtf_wall)
                rtf_wall, rtf_ticks = now, ticks
            if now >= next_telemetry:
                telemetry = core.telemetry()
                if telemetry is not None:
                    emit(telemetry)
                next_telemetry = max(next_telemetry + telemetry_period, now)
            if now >= next_publish or publish_now or core.style_revision != published_revision:
                publish_now = False
                published_revision = core.style_revision
                emit(core.frame())
                next_publish = max(next_publish + publish_period, now)
                if os.getppid() != parent:
                    return  # orphaned
            next_tick = wall0 + (ticks + 1) * period if core.running else now + publish_period
            sleep = min(next_tick, next_publish) - time.perf_counter()
            if sleep > 0:
                conn.poll(min(sleep, 0.05))
    except (EOFError, BrokenPipeError, ConnectionResetError, KeyboardInterrupt, _ShutdownRequested):
        return


def ticks_due(now_s: float, wall0_s: float, ticks: int, period_s: float) -> tuple[int, float]:
    """Ticks to run now, and the clock origin, for a fixed-step simulation paced to wall time.

    The simulation owes ``(now - wall0) / period - ticks`` ticks. A backlog up to ``MAX_BACKLOG_S`` is kept
    and paid back in batches of at most ``MAX_BATCH_TICKS`` (a short preemption on a busy machine costs no
    simulated time); beyond it the origin moves forward and the excess is dropped, so a long stall or a
    machine slower than real time never makes the robot race to catch up.
    """
    owed = int((now_s - wall0_s) / period_s) - ticks
    max_owed = max(int(round(MAX_BACKLOG_S / period_s)), MAX_BATCH_TICKS)
    if owed > max_owed:
        wall0_s += (owed - max_owed) * period_s
        owed = max_owed
    return max(0, min(owed, MAX_BATCH_TICKS)), wall0_s


class _ShutdownRequested(Exception):
    pass


class EngineProcess:
    """Parent-side handle on one engine process (``python -m engine`` over a socket pair)."""

    def __init__(self, robot: str):
        self.robot = robot
        self.process: subprocess.Popen | None = None
        self.conn: Connection | None = None

    def start(self) -> None:
        parent_sock, child_sock = socket.socketpair()
        child_fd = child_sock.fileno()
        env = dict(os.environ)
        env.setdefault("PYTHONUNBUFFERED", "1")
        self.process = subprocess.Popen(
            [sys.executable, "-m", "engine", "--robot", self.robot, "--fd", str(child_fd)],
            pass_fds=(child_fd,), env=env, cwd=str(REPO_ROOT),
            # Its own session, hence its own scheduler autogroup on Linux (sched_autogroup_enabled, the default of
            # desktop kernels): CPU is shared between sessions first, then between threads, so the browser's
            # rendering threads and the studio's streaming threads no longer outnumber the one simulation thread.
            # With a software-WebGL tab and three other jobs on 2 cores, simulated ÷ wall time 0.17-0.20 -> 0.33-0.36
            # (`studio bench render`'s walk, alternated twice). The studio still ends it: Shutdown, the socket's
            # EOF when the studio dies, or the orphan check; a terminal's Ctrl-C goes to the studio alone.
            start_new_session=True,
        )
        child_sock.close()
        self.conn = Connection(parent_sock.detach())

    @property
    def pid(self) -> int | None:
        return self.process.pid if self.process else None

    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def send(self, command: msg.Command) -> bool:
        if isinstance(command, msg.SwitchRobot):
            self.robot = command.robot
        if self.conn is None:
            return False
        try:
            self.conn.send(command)
            return True
        except OSError:
            return False

    def recv(self, timeout_s: float) -> msg.Event | None:
        """Next event, or None after ``timeout_s``; raises EOFError when the engine is gone."""
        if self.conn is None:
            raise EOFError("engine not started")
        if self.conn.poll(timeout_s):
            return self.conn.recv()
        return None

    def stop(self, timeout_s: float = 2.0) -> None:
        if self.process is None:
            return
        self.send(msg.Shutdown())
        try:
            self.process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait(2.0)
        if self.conn is not None:
            self.conn.close()
        self.process = None
        self.conn = None


def main(argv: list[str] | None = None) -> int:
    import argparse

    parser = argparse.ArgumentParser(prog="python -m engine", description="motion-studio engine process")
    parser.add_argument("--robot", required=True)
    parser.add_argument("--fd", type=int, required=True, help="inherited socket of the studio")
    args = parser.parse_args(argv)
    prefer_simulation()  # this process leads its own session (EngineProcess.start): the session's CPU share
    engine_main(Connection(args.fd), args.robot)
    return 0
