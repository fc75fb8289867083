"""The studio's link to the engine process: reader thread, watchdog and restart.

Events from the engine are delivered to ``on_event`` on the link's thread (frames are
coalesced: only the newest pending frame is delivered). If the engine process dies, the
link reports it through ``on_status``, tells ``on_lost(pid)`` (what ran only in that process —
retargeting, import and export jobs, a recording — is gone: the panels say so and let the user
start it again) and starts a new engine at once, replaying the commands that define the engine's
state (robot, style, mode, ...), so the user loses no edits.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import Callable

from engine import protocol as msg
from engine.process import EngineProcess

LOG = logging.getLogger(__name__)

# Commands whose latest value defines engine state and is replayed after a restart.
STICKY_KINDS = ("switch_robot", "set_style", "set_mode", "set_velocity_command", "set_paused")


class EngineLink:
    def __init__(
        self,
        robot: str,
        on_event: Callable[[msg.Event], None],
        on_status: Callable[[str, str], None] = lambda level, text: None,
        on_lost: Callable[[int | None], None] = lambda pid: None,
    ):
        self.robot = robot
        self.on_event = on_event
        self.on_status = on_status
        self.on_lost = on_lost
        self.engine: EngineProcess | None = None
        self.restarts = 0
        self.last_event_time = 0.0
        self._sticky: dict[str, msg.Command] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> None:
        self._spawn()
        self._thread = threading.Thread(target=self._run, name="engine-link", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        with self._lock:
            if self.engine is not None:
                self.engine.stop()
                self.engine = None

    @property
    def pid(self) -> int | None:
        with self._lock:
            return self.engine.pid if self.engine else None

    def send(self, command: msg.Command) -> bool:
        if command.kind in STICKY_KINDS:
            self._sticky[command.kind] = command
            if isinstance(command, msg.SwitchRobot):
                self.robot = command.robot
        with self._lock:
            return self.engine.send(command) if self.engine else False

    # ------------------------------------------------------------------ internals
    def _spawn(self) -> None:
        engine = EngineProcess(self.robot)
        engine.start()
        for command in self._sticky.values():
            if not isinstance(command, msg.SwitchRobot):
                engine.send(command)
        with self._lock:
            self.engine = engine

    def _run(self) -> None:
        while not self._stop.is_set():
            engine = self.engine
            try:
                if engine is None:
                    raise EOFError
                event = engine.recv(0.1)
                if event is None:
                    if not engine.alive():
                        raise EOFError
                    continue
                # Coalesce frames: deliver only the newest of a backlog, other events in order.
                pending_frame = event if isinstance(event, msg.Frame) else None
                if pending_frame is None:
                    self._deliver(event)
                while True:
                    more = engine.recv(0.0)
                    if more is None:
                        break
                    if isinstance(more, msg.Frame):
                        pending_frame = more
                    else:
                        self._deliver(more)
                if pending_frame is not None:
                    self._deliver(pending_frame)
            except (EOFError, OSError):
                if self._stop.is_set():
                    break
                self._handle_death(engine)

    def _deliver(self, event: msg.Event) -> None:
        self.last_event_time = time.monotonic()
        try:
            self.on_event(event)
        except Exception as exc:  # a UI bug must not kill the link
            LOG.exception("studio failed to show %s", event.kind)  # the traceback, for the log and the soak
            self.on_status("error", f"studio failed to show {event.kind}: {exc}")

    def _handle_death(self, engine: EngineProcess | None) -> None:
        code = None
        if engine is not None and engine.process is not None:
            try:
                code = engine.process.wait(1.0)
            except Exception:
                engine.process.kill()
        pid = engine.pid if engine else None
        self.restarts += 1
        self.on_status("error", f"The engine process (pid {pid}) stopped (exit code {code}); restarting it.")
        try:
            self.on_lost(pid)  # its jobs died with it (every event it sent has been delivered: we read to EOF)
        except Exception as exc:  # a UI bug must not stop the restart
            LOG.exception("studio failed to report the jobs lost with engine %s", pid)
            self.on_status("error", f"studio failed to report the lost jobs: {exc}")
        try:
            self._spawn()
            self.on_status("info", f"Engine restarted (pid {self.pid}).")
        except Exception as exc:
            self.on_status("error", f"Could not restart the engine: {exc}")
            time.sleep(1.0)
