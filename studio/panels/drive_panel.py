"""Modes and the virtual joystick.

Edit mode walks the selected sample's cycle at its velocity (paper §6.1); test mode steers
with the joystick (§6.2): two in-scene drag pads beside the robot that turn with it and spring
back to centre (left: forward / sideways, right: turn), hold buttons (walk while held; a tap
latches the direction until ■ Stop), and a stop button. Playback speed gives slow motion.
Commands are sent at most 20 times a second.
"""

from __future__ import annotations

import functools
import threading
import time
from typing import TYPE_CHECKING, Callable

import numpy as np
import viser

from engine import protocol as msg
from studio.camera_follow import CameraFollow

if TYPE_CHECKING:
    from studio.app import Studio

HOLD_TIMEOUT_S = 2.0  # a hold with no repeat for this long ends (its release was lost) — when repeats come fast
HOLD_TIMEOUT_MAX_S = 10.0  # ... and at most this long, however slow the browser's repeats have been
HOLD_GAP_FACTOR = 3.0  # the timeout is this many of the browser's recent repeat gaps (a slow browser's gaps are long)
TAP_MAX_S = 0.35  # a press released sooner than this is a tap: it latches that direction (cruise) until ■ Stop
PAD_RADIUS_M = 0.12
SEND_PERIOD_S = 0.05
#: Where the reference ghost is drawn, in the robot's heading frame (m, forward / left): on the robot by
#: default (as in the paper), or beside it when the animator picks that in "Ghost offset".
GHOST_OFFSETS = {"on robot": (0.0, 0.0), "beside (right)": (0.0, -0.9), "beside (left)": (0.0, 0.9)}


class JoystickState:
    """What the joystick asks for, from hold buttons, taps and the two pads (unit-free, in [-1, 1] per axis).

    The browser sends a hold message when a button is pressed and then about 20 times a second while it
    stays down, and a click when it is released. Under software WebGL on a slow machine the repeats can be
    seconds apart (the page's main thread draws a frame between two of them), so a press lasts until its
    release (the click); the timeout is only a safety net for a lost release, and it adapts to the gaps
    this browser's repeats have shown (``HOLD_GAP_FACTOR`` of them, between ``HOLD_TIMEOUT_S`` and
    ``HOLD_TIMEOUT_MAX_S``). A late repeat continues its press, it does not start a new one, so the end
    of a long hold is never mistaken for a tap. A release within ``TAP_MAX_S`` of the press is a tap, and
    so is a release with no repeat between (a slow browser delivers a quick click's press and release up to
    a frame, ~0.7 s, apart): it latches that direction until ■ Stop, a tap on the same button again, or a
    tap in the opposite direction. Axes: 0 forward, 1 left, 2 turn left.
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic):
        self.clock = clock
        self._lock = threading.Lock()
        self._pressed_at: dict[tuple[int, float], float] = {}  # (axis, sign) → time the press began
        self._last_repeat: dict[tuple[int, float], float] = {}
        self._repeats: dict[tuple[int, float], int] = {}  # hold messages after the press
        self._repeat_gap_s = SEND_PERIOD_S  # recent gap between this browser's repeats: fast up, slow down
        self.latched = np.zeros(3)
        self.pad = np.zeros(3)

    @property
    def hold_timeout_s(self) -> float:
        """How long a press stays held without a repeat (a lost release ends after this)."""
        return float(min(HOLD_TIMEOUT_MAX_S, max(HOLD_TIMEOUT_S, HOLD_GAP_FACTOR * self._repeat_gap_s)))

    def hold(self, axis: int, sign: float) -> None:
        now = self.clock()
        key = (axis, sign)
        with self._lock:
            last = self._last_repeat.get(key)
            if key not in self._pressed_at or last is None or now - last > HOLD_TIMEOUT_MAX_S:
                self._pressed_at[key] = now  # a new press (or one whose release was lost long ago)
                self._repeats[key] = 0
            else:  # a repeat of the press, however late: learn how far apart this browser sends them
                gap = now - last
                self._repeat_gap_s = gap if gap > self._repeat_gap_s else 0.9 * self._repeat_gap_s + 0.1 * gap
                self._repeats[key] = self._repeats.get(key, 0) + 1
            self._last_repeat[key] = now

    def release(self, axis: int, sign: float) -> None:
        """The button was released (its click arrived): a tap toggles the latch; a hold ends, latch cleared."""
        now = self.clock()
        with self._lock:
            began = self._pressed_at.pop((axis, sign), None)
            self._last_repeat.pop((axis, sign), None)
            repeats = self._repeats.pop((axis, sign), 0)
            tap = (began is None or now - began <= TAP_MAX_S
                   or (repeats == 0 and now - began <= max(HOLD_TIMEOUT_S, self._repeat_gap_s)))
            self.latched[axis] = (0.0 if self.latched[axis] == sign else sign) if tap else 0.0

    def set_pad(self, axes: slice | int, values) -> None:
        with self._lock:
            self.pad[axes] = values

    def stop(self) -> None:
        with self._lock:
            self._pressed_at.clear()
            self._last_repeat.clear()
            self._repeats.clear()
            self.latched[:] = 0.0
            self.pad[:] = 0.0

    def unit_command(self) -> np.ndarray:
        """Latched directions, overridden on an axis while one of its buttons is held, plus the pads."""
        now = self.clock()
        with self._lock:
            held = np.zeros(3)
            pressed = set()
            timeout_s = self.hold_timeout_s
            for (axis, sign), t in self._last_repeat.items():
                if now - t <= timeout_s:  # else no repeat for long: its release was lost
                    held[axis] += sign
                    pressed.add(axis)
            v = np.array([held[a] if a in pressed else self.latched[a] for a in range(3)]) + self.pad
        return np.clip(v, -1.0, 1.0)

    @property
    def latched_any(self) -> bool:
        return bool(np.any(self.latched))


class DrivePanel:
    def __init__(self, server: viser.ViserServer, studio: "Studio"):
        self.server = server
        self.studio = studio
        self.mode = server.gui.add_button_group("Mode", options=("Stand", "Edit", "Test"))
        self.speed = server.gui.add_slider("Playback speed", min=0.1, max=1.0, step=0.05, initial_value=1.0,
                                           hint="slow motion for edit mode")
        self.follow = server.gui.add_checkbox("Camera follows robot", initial_value=True,
                                              hint="the camera moves with the robot; zoom and orbit stay yours")
        self.camera = CameraFollow(server)
        self.show_ghost = server.gui.add_checkbox("Reference ghost", initial_value=True,
                                                  hint="the kinematic reference the controller tracks")
        self.ghost_offset = server.gui.add_dropdown("Ghost offset", options=tuple(GHOST_OFFSETS),
                                                    initial_value="on robot",
                                                    hint="draw the reference ghost on the robot or beside it")
        self.show_overlays = server.gui.add_checkbox("Ground overlays", initial_value=True)
        self.shadows = server.gui.add_checkbox("Shadows", initial_value=studio.shadows,
                                               hint="shadow maps: fine on a GPU; without one (software WebGL) the "
                                                    "page draws 1.7-5x fewer frames (studio bench render)")
        self.readout = server.gui.add_markdown("Command: stopped")
        with server.gui.add_folder("Joystick (test mode)"):
            self.fwd = server.gui.add_button("▲ forward")
            self.back = server.gui.add_button("▼ back")
            self.left = server.gui.add_button("◀ strafe left")
            self.right = server.gui.add_button("▶ strafe right")
            self.turn_left = server.gui.add_button("⟲ turn left")
            self.turn_right = server.gui.add_button("⟳ turn right")
            self.stop = server.gui.add_button("■ Stop", color="red")
        self.joystick = JoystickState()
        self._sent = np.full(3, np.nan)
        for button, axis, sign in ((self.fwd, 0, 1.0), (self.back, 0, -1.0), (self.left, 1, 1.0), (self.right, 1, -1.0),
                                   (self.turn_left, 2, 1.0), (self.turn_right, 2, -1.0)):
            button.on_hold(functools.partial(self._on_hold, axis, sign), callback_hz=20.0)
            button.on_click(functools.partial(self._on_release, axis, sign))  # the click arrives on release
        self.stop.on_click(lambda _: self.stop_now())
        self.mode.on_click(lambda e: self.set_mode(e.target.value.lower()))
        self.speed.on_update(self._on_speed)
        self.follow.on_update(lambda _: self._on_follow_toggled())
        self.show_ghost.on_update(lambda _: studio.set_ghost_visible(self.show_ghost.value))
        self.ghost_offset.on_update(lambda _: studio.set_ghost_offset(self.ghost_offset.value))
        self.show_overlays.on_update(lambda _: studio.overlays.set_visible(self.show_overlays.value))
        self.shadows.on_update(lambda _: studio.set_shadows(self.shadows.value))
        self.pads_root = server.scene.add_frame("/joystick", show_axes=False)
        self.pads = [self._make_pad("move", (0.0, 0.0)), self._make_pad("turn", (0.0, -0.45))]
        self._stop = threading.Event()
        threading.Thread(target=self._loop, name="joystick", daemon=True).start()

    # ------------------------------------------------------------------ modes
    def set_mode(self, mode: str) -> None:
        self.stop_now()
        self.studio.set_mode(mode)

    # ------------------------------------------------------------------ joystick
    def _on_hold(self, axis: int, sign: float, _event: object) -> None:
        self.hold(axis, sign)

    def _on_release(self, axis: int, sign: float, _event: object) -> None:
        self.release(axis, sign)

    def _on_speed(self, _event: object) -> None:
        self.studio.link.send(msg.SetPlaybackSpeed(float(self.speed.value)))

    def hold(self, axis: int, sign: float) -> None:
        self.joystick.hold(axis, sign)

    def release(self, axis: int, sign: float) -> None:
        self.joystick.release(axis, sign)
        if self.studio.mode == "test":
            self._send(self.command())

    def stop_now(self) -> None:
        self.joystick.stop()
        self._send(np.zeros(3), force=True)

    def command(self) -> np.ndarray:
        """Current joystick command (m/s, m/s, rad/s), scaled to the style's sample velocities."""
        return self.joystick.unit_command() * self.studio.velocity_limits()

    def _send(self, v: np.ndarray, force: bool = False) -> None:
        if force or not np.allclose(v, self._sent, atol=1e-4):
            self._sent = v.copy()
            self.studio.link.send(msg.SetVelocityCommand(float(v[0]), float(v[1]), float(v[2])))
        text = ("Command: stopped" if not np.any(v) else
                f"Command: vx {v[0]:+.2f} m/s · vy {v[1]:+.2f} m/s · wz {v[2]:+.2f} rad/s")
        if self.joystick.latched_any:
            text += " (latched: ■ Stop or tap the button again to release)"
        self.readout.content = text

    def _loop(self) -> None:
        from studio.thread_priority import yield_to_engine

        yield_to_engine()  # the joystick and the camera follow yield to the engine's simulation
        while not self._stop.wait(SEND_PERIOD_S):
            try:
                if self.studio.mode == "test":
                    self._send(self.command())
                self._follow()
            except Exception:  # noqa: BLE001 - keep the joystick alive
                pass

    @property
    def following(self) -> bool:
        """The camera (and the curve graph) move with the robot."""
        return bool(self.follow.value) and self.studio.mode != "stand"

    def _on_follow_toggled(self) -> None:
        if self.follow.value:
            self.camera.recentre()
            pos = self.studio.robot_position()
            if pos is not None:
                self.studio.place_graph(self.camera._ground(pos))

    def _follow(self) -> None:
        """Keep the pads beside the robot; move the camera and the curve graph with it when following
        (never during a knot drag: the graph must stay under the pointer)."""
        pos = self.studio.robot_position()
        if pos is None:
            return
        yaw = float(self.studio.robot_yaw_rad())
        c, s = np.cos(yaw), np.sin(yaw)
        self.pads_root.position = (pos[0] + 0.5 * c - 0.45 * s, pos[1] + 0.5 * s + 0.45 * c, 0.0)
        self.pads_root.wxyz = (np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2))  # pad axes = robot forward / left
        ground = self.camera.step(pos, self.following, frozen=self.studio.dragging)
        if ground is not None:
            self.studio.place_graph(ground)

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

        @knob.on_drag
        def _(event) -> None:
            try:
                if event.phase == "end":
                    knob.position = tuple(center + [0, 0, 0.03])
                    self.joystick.set_pad(slice(0, 2) if name == "move" else 2, 0.0)
                    return
                # The pad turns with the robot: its local x is the robot's forward, y its left.
                w, _, _, z = self.pads_root.wxyz
                yaw = 2.0 * np.arctan2(z, w)
                c, s = np.cos(yaw), np.sin(yaw)
                world = np.asarray(event.end_position)[:2] - np.asarray(self.pads_root.position)[:2]
                d = np.array([c * world[0] + s * world[1], -s * world[0] + c * world[1]]) - center[:2]
                norm = float(np.linalg.norm(d))
                if norm > PAD_RADIUS_M:
                    d *= PAD_RADIUS_M / norm
                knob.position = tuple(center + [d[0], d[1], 0.03])
                if name == "move":
                    self.joystick.set_pad(slice(0, 2), d / PAD_RADIUS_M)
                else:
                    self.joystick.set_pad(2, d[1] / PAD_RADIUS_M)  # drag left to turn left
            except Exception:  # noqa: BLE001
                pass

        return knob
