"""The studio: a viser server showing the engine's robot, with the editing panels.

Studio code only views and edits engine state: numerics live in the engine process.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import viser

from engine import protocol as msg
from engine.robot.config import load_robot_config
from engine.robot.model import load_robot
from studio.engine_link import EngineLink
from studio.panels.robot_panel import RobotPanel
from studio.robot_view import RobotView

STATUS_PERIOD_S = 0.5


class Studio:
    def __init__(self, robot: str, host: str = "127.0.0.1", port: int = 8080):
        load_robot_config(robot)  # fail fast, before any server or process starts
        self.robot_name = robot
        self.server = viser.ViserServer(host=host, port=port, label="Motion Studio", verbose=False)
        self.server.scene.set_up_direction("+z")
        self.server.gui.configure_theme(control_layout="fixed", control_width="medium", dark_mode=False,
                                        show_logo=False)
        self.server.scene.add_grid("/ground", width=12.0, height=12.0, plane="xy", cell_size=0.25,
                                   section_size=1.0, shadow_opacity=0.2)
        self.server.initial_camera.position = (2.0, -2.2, 1.3)
        self.server.initial_camera.look_at = (0.0, 0.0, 0.6)
        self.view = RobotView(self.server)
        self.robot_panel = RobotPanel(self.server, self)
        self.events_seen: dict[str, int] = {}
        self.robot_simulated = True
        self.notices: list[tuple[str, str]] = []
        self._last_notice_time = 0.0
        self.loaded = threading.Event()
        self.link = EngineLink(robot, self._on_event, self._on_status)
        self.server.on_client_connect(self._on_client)
        self._stop = threading.Event()
        self._status_thread = threading.Thread(target=self._status_loop, name="studio-status", daemon=True)

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> "Studio":
        self.link.start()
        self._status_thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self.link.stop()
        self.server.stop()

    @property
    def url(self) -> str:
        return f"http://{self.server.get_host()}:{self.server.get_port()}"

    # ------------------------------------------------------------------ engine events
    def _on_event(self, event: msg.Event) -> None:
        self.events_seen[event.kind] = self.events_seen.get(event.kind, 0) + 1
        if isinstance(event, msg.Frame):
            self.view.update(event)
        elif isinstance(event, msg.RobotLoaded):
            self.robot_name = event.robot
            self.robot_simulated = event.simulated
            self.view.load(event.robot, event.body_names)
            if self.robot_panel.robot.value != event.robot:
                self.robot_panel.robot.value = event.robot
            self.loaded.set()
        elif isinstance(event, msg.Notice):
            self._notify(event.level, event.message)

    def _on_status(self, level: str, text: str) -> None:
        self._notify(level, text)

    def _notify(self, level: str, text: str) -> None:
        self.notices.append((level, text))
        self._last_notice_time = time.monotonic()
        color = {"error": "red", "warning": "yellow", "info": "blue"}.get(level, "blue")
        title = {"error": "Engine", "warning": "Heads up", "info": "Engine"}.get(level, "Studio")
        for client in self.server.get_clients().values():
            client.add_notification(title, text, color=color, auto_close_seconds=6.0)

    def _on_client(self, client: viser.ClientHandle) -> None:
        for level, text in self.notices[-1:]:
            if level == "error" and time.monotonic() - self._last_notice_time < 10.0:
                client.add_notification("Engine", text, color="red", auto_close_seconds=6.0)

    # ------------------------------------------------------------------ actions
    def switch_robot(self, robot: str) -> None:
        if robot == self.robot_name:
            return
        self.loaded.clear()
        self.link.send(msg.SwitchRobot(robot))

    @property
    def robot_mass_kg(self) -> float:
        return load_robot(self.robot_name).mass_kg

    def robot_yaw_rad(self) -> float:
        frame = self.view.last_frame
        if frame is None or len(frame.body_quat) == 0:
            return 0.0
        root = load_robot(self.robot_name).config.root_link
        try:
            idx = self.view.body_names.index(root)
        except ValueError:
            return 0.0
        w, x, y, z = (float(c) for c in frame.body_quat[idx])
        return float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))

    def _status_loop(self) -> None:
        while not self._stop.wait(STATUS_PERIOD_S):
            frame = self.view.last_frame
            pid = self.link.pid
            if frame is None:
                text = f"Engine: starting (pid {pid})…"
            elif not self.robot_simulated:
                text = f"Engine running · pid {pid} · {self.robot_name} is a source skeleton: shown, not simulated"
            else:
                state = "paused" if frame.paused else ("fallen" if frame.fallen else "running")
                text = (f"Engine {state} · pid {pid} · t = {frame.sim_time_s:.1f} s · "
                        f"real-time factor {frame.real_time_factor:.2f}")
            self.robot_panel.show_status(text)


def serve(robot: str, host: str, port: int) -> None:
    studio = Studio(robot, host, port).start()
    print(f"Motion Studio: {studio.url}  (robot {robot}; Ctrl+C to stop)", flush=True)
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        studio.stop()
