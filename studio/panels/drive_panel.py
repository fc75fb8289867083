"""Modes and the virtual joystick.

Edit mode walks the selected sample's cycle at its velocity (paper §6.1); test mode steers
with the joystick (§6.2): two in-scene drag pads that spring back to centre (left: forward /
sideways, right: turn) and hold buttons, plus a stop button. Playback speed gives slow
motion. Commands are sent at most 20 times a second.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING, Callable

import numpy as np
import viser

from engine import protocol as msg

if TYPE_CHECKING:
    from studio.app import Studio

HOLD_TIMEOUT_S = 0.5  # a hold button stops counting this long after its last repeat (spring back)
PAD_RADIUS_M = 0.12
SEND_PERIOD_S = 0.05


class DrivePanel:
    def __init__(self, server: viser.ViserServer, studio: "Studio"):
        self.server = server
        self.studio = studio
        self.mode = server.gui.add_button_group("Mode", options=("Stand", "Edit", "Test"))
        self.speed = server.gui.add_slider("Playback speed", min=0.1, max=1.0, step=0.05, initial_value=1.0,
                                           hint="slow motion for edit mode")
        self.follow = server.gui.add_checkbox("Camera follows robot", initial_value=True)
        self.show_ghost = server.gui.add_checkbox("Reference ghost", initial_value=True)
        self.show_overlays = server.gui.add_checkbox("Ground overlays", initial_value=True)
        self.readout = server.gui.add_markdown("Command: stopped")
        with server.gui.add_folder("Joystick (test mode)"):
            self.fwd = server.gui.add_button("▲ forward")
            self.back = server.gui.add_button("▼ back")
            self.left = server.gui.add_button("◀ strafe left")
            self.right = server.gui.add_button("▶ strafe right")
            self.turn_left = server.gui.add_button("⟲ turn left")
            self.turn_right = server.gui.add_button("⟳ turn right")
            self.stop = server.gui.add_button("■ Stop", color="red")
        self._held: dict[tuple[int, float], float] = {}
        self._pad = np.zeros(3)
        self._sent = np.full(3, np.nan)
        self._lock = threading.Lock()
        for button, axis, sign in ((self.fwd, 0, 1.0), (self.back, 0, -1.0), (self.left, 1, 1.0), (self.right, 1, -1.0),
                                   (self.turn_left, 2, 1.0), (self.turn_right, 2, -1.0)):
            button.on_hold(lambda _, a=axis, s=sign: self.hold(a, s), callback_hz=20.0)
        self.stop.on_click(lambda _: self.stop_now())
        self.mode.on_click(lambda e: self.set_mode(e.target.value.lower()))
        self.speed.on_update(lambda _: studio.link.send(msg.SetPlaybackSpeed(float(self.speed.value))))
        self.show_ghost.on_update(lambda _: studio.set_ghost_visible(self.show_ghost.value))
        self.show_overlays.on_update(lambda _: studio.overlays.set_visible(self.show_overlays.value))
        self.pads_root = server.scene.add_frame("/joystick", show_axes=False)
        self.pads = [self._make_pad("move", (0.0, 0.0)), self._make_pad("turn", (0.0, -0.45))]
        self._stop = threading.Event()
        threading.Thread(target=self._loop, name="joystick", daemon=True).start()

    # ------------------------------------------------------------------ modes
    def set_mode(self, mode: str) -> None:
        self.stop_now()
        self.studio.set_mode(mode)

    # ------------------------------------------------------------------ joystick
    def hold(self, axis: int, sign: float) -> None:
        with self._lock:
            self._held[(axis, sign)] = time.monotonic()

    def stop_now(self) -> None:
        with self._lock:
            self._held.clear()
            self._pad[:] = 0.0
        self._send(np.zeros(3), force=True)

    def command(self) -> np.ndarray:
        """Current joystick command (m/s, m/s, rad/s), scaled to the style's sample velocities."""
        limits = self.studio.velocity_limits()
        now = time.monotonic()
        v = np.zeros(3)
        with self._lock:
            for (axis, sign), t in list(self._held.items()):
                if now - t <= HOLD_TIMEOUT_S:
                    v[axis] += sign
                else:
                    del self._held[(axis, sign)]
            v += self._pad
        return np.clip(v, -1.0, 1.0) * limits

    def _send(self, v: np.ndarray, force: bool = False) -> None:
        if force or not np.allclose(v, self._sent, atol=1e-4):
            self._sent = v.copy()
            self.studio.link.send(msg.SetVelocityCommand(float(v[0]), float(v[1]), float(v[2])))
        self.readout.content = ("Command: stopped" if not np.any(v) else
                                f"Command: vx {v[0]:+.2f} m/s · vy {v[1]:+.2f} m/s · wz {v[2]:+.2f} rad/s")

    def _loop(self) -> None:
        while not self._stop.wait(SEND_PERIOD_S):
            try:
                if self.studio.mode == "test":
                    self._send(self.command())
                self._follow()
            except Exception:  # noqa: BLE001 - keep the joystick alive
                pass

    def _follow(self) -> None:
        """Keep the pads beside the robot (and the camera on it when asked)."""
        pos = self.studio.robot_position()
        if pos is None:
            return
        self.pads_root.position = (pos[0] + 0.5, pos[1] + 0.45, 0.0)
        follow = getattr(self.studio, "follow_robot", None)
        if follow is not None:
            follow(pos)
        if self.follow.value and self.studio.mode != "stand":
            for client in self.server.get_clients().values():
                cam = client.camera
                offset = np.asarray(cam.position) - np.asarray(cam.look_at)
                target = np.array([pos[0], pos[1], 0.6])
                look = np.asarray(cam.look_at)
                new_look = look + 0.2 * (target - look)
                with client.atomic():
                    cam.look_at = tuple(new_look)
                    cam.position = tuple(new_look + offset)

    def _make_pad(self, name: str, offset_xy: tuple[float, float]):
        """A disc with a knob: drag the knob; release springs it back; displacement → command."""
        root = f"/joystick/{name}"
        center = np.array([offset_xy[0], offset_xy[1], 0.01])
        theta = np.linspace(0, 2 * np.pi, 33)
        ring = np.column_stack([PAD_RADIUS_M * np.cos(theta), PAD_RADIUS_M * np.sin(theta), np.zeros(33)]) + center
        self.server.scene.add_line_segments(f"{root}/ring", np.stack([ring[:-1], ring[1:]], axis=1),
                                            colors=(90, 90, 200), thickness=3.0, thickness_units="screen")
        cross = np.array([[[-PAD_RADIUS_M, 0, 0], [PAD_RADIUS_M, 0, 0]], [[0, -PAD_RADIUS_M, 0], [0, PAD_RADIUS_M, 0]]])
        self.server.scene.add_line_segments(f"{root}/cross", cross + center, colors=(150, 150, 220), thickness=1.5, thickness_units="screen")
        self.server.scene.add_label(f"{root}/label", "walk" if name == "move" else "turn",
                                    position=tuple(center + np.array([0.0, 0.0, 0.02]) + [-PAD_RADIUS_M - 0.05, 0, 0]))
        knob = self.server.scene.add_icosphere(f"{root}/knob", radius=0.035, color=(60, 60, 220),
                                               position=tuple(center + [0, 0, 0.03]))
        state = {"center_world": None}

        @knob.on_drag
        def _(event) -> None:
            try:
                base = np.asarray(self.pads_root.position) + center
                if event.phase == "end":
                    knob.position = tuple(center + [0, 0, 0.03])
                    with self._lock:
                        if name == "move":
                            self._pad[0:2] = 0.0
                        else:
                            self._pad[2] = 0.0
                    return
                d = np.asarray(event.end_position)[:2] - base[:2]
                norm = float(np.linalg.norm(d))
                if norm > PAD_RADIUS_M:
                    d *= PAD_RADIUS_M / norm
                knob.position = tuple(center + [d[0], d[1], 0.03])
                with self._lock:
                    if name == "move":
                        self._pad[0:2] = d / PAD_RADIUS_M
                    else:
                        self._pad[2] = d[1] / PAD_RADIUS_M  # drag left to turn left
            except Exception:  # noqa: BLE001
                pass

        del state
        return knob
