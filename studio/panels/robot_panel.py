"""Robot panel: pick the robot, reset, pause, push; shows engine status."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import viser

from engine import protocol as msg
from engine.robot.config import load_robot_config, robot_names

if TYPE_CHECKING:
    from studio.app import Studio

PUSH_DIRECTIONS = {"front": (1.0, 0.0), "back": (-1.0, 0.0), "left": (0.0, 1.0), "right": (0.0, -1.0)}


class RobotPanel:
    def __init__(self, server: viser.ViserServer, studio: "Studio"):
        self.studio = studio
        names = robot_names()
        labels = {}
        for n in names:
            try:
                labels[n] = load_robot_config(n).display_name
            except Exception:
                labels[n] = n
        self.names = names
        with server.gui.add_folder("Robot"):
            self.robot = server.gui.add_dropdown("Robot", options=tuple(names), initial_value=studio.robot_name,
                                                 hint=" · ".join(f"{n}: {labels[n]}" for n in names))
            self.reset = server.gui.add_button("Reset", icon=viser.Icon.REFRESH, hint="Stand the robot up again")
            self.pause = server.gui.add_button("Pause", icon=viser.Icon.PLAYER_PAUSE)
            self.push_force = server.gui.add_slider("Push force (N/kg)", min=0.0, max=4.0, step=0.1, initial_value=1.5)
            self.push_direction = server.gui.add_dropdown("Push from", options=tuple(PUSH_DIRECTIONS), initial_value="front")
            self.push = server.gui.add_button("Push (1 s)", icon=viser.Icon.HAND_STOP, hint="Push the pelvis for one second")
            self.status = server.gui.add_markdown("Engine: starting…")

        self.robot.on_update(lambda _: studio.switch_robot(self.robot.value))
        def reset(_event: object) -> None:
            studio.link.send(msg.Reset())

        self.reset.on_click(reset)
        self.pause.on_click(lambda _: self.toggle_pause())
        self.push.on_click(lambda _: self.apply_push())

    def toggle_pause(self) -> None:
        paused = self.pause.label == "Pause"
        self.studio.link.send(msg.SetPaused(paused))
        self.pause.label = "Resume" if paused else "Pause"
        self.pause.icon = viser.Icon.PLAYER_PLAY if paused else viser.Icon.PLAYER_PAUSE

    def apply_push(self) -> None:
        """Push toward the robot from the chosen side: "front" pushes backwards, and so on."""
        mass = self.studio.robot_mass_kg
        dx, dy = PUSH_DIRECTIONS[self.push_direction.value]
        yaw = self.studio.robot_yaw_rad()
        c, s = np.cos(yaw), np.sin(yaw)
        magnitude = float(self.push_force.value) * mass
        fx, fy = -magnitude * (c * dx - s * dy), -magnitude * (s * dx + c * dy)
        self.studio.link.send(msg.ApplyPush((fx, fy, 0.0), 1.0))

    def show_status(self, text: str) -> None:
        self.status.content = text
