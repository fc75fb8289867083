"""The robot in the 3D view: one frame per body, one recolourable mesh under each.

Streaming a frame costs the studio per body and per property (viser checks each assigned pose against the
node's last one, queues one message, then serialises it once per connected browser). So a frame sends only
the bodies that moved by more than :data:`POSITION_TOL_M` or turned by more than :data:`WXYZ_TOL` since the
pose last sent for them — compared for all bodies at once in numpy — and queues those poses directly
(what viser's own setter does after its check), each converted to its wire form once for all browsers
instead of once per browser. Every browser still ends on each body's latest pose to
within those tolerances (0.1 mm, ≈ 0.01°: invisible), tested by a headless client that decodes the stream.
"""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import viser
from viser import _messages as viser_messages

POSITION_TOL_M = 1e-4  # a body that moved less since the pose last sent keeps it (0.1 mm)
WXYZ_TOL = 1e-4  # per quaternion component (≈ 0.01°)

from engine import protocol as msg
from engine.robot.model import load_robot


def _rgb(rgba: tuple[float, ...]) -> tuple[int, int, int]:
    return tuple(int(round(255 * float(np.clip(c, 0.0, 1.0)))) for c in rgba[:3])  # type: ignore[return-value]


class RobotView:
    """Shows a robot streamed from the engine under ``root`` in the scene."""

    def __init__(self, server: viser.ViserServer, root: str = "/robot", opacity: float | None = None):
        self.server = server
        self.root = root
        self.opacity = opacity
        self.robot_name: str | None = None
        self.body_names: tuple[str, ...] = ()
        self.frames: list[viser.FrameHandle] = []
        self.meshes: dict[str, viser.MeshHandle] = {}
        self.base_colors: dict[str, tuple[int, int, int]] = {}
        self.last_frame: msg.Frame | None = None
        self.frames_shown = 0
        self.poses_sent = 0  # position and orientation messages queued (two per moved body)
        self._sent_pos = np.zeros((0, 3))  # the pose last sent for each body (NaN: never)
        self._sent_wxyz = np.zeros((0, 4))
        self._lock = threading.Lock()

    def load(self, robot: str, body_names: tuple[str, ...]) -> None:
        """(Re)build the scene nodes of ``robot``; ``body_names`` is the engine's frame order."""
        model = load_robot(robot)
        meshes = {bm.body: bm for bm in model.body_meshes}
        with self._lock, self.server.atomic():
            self.clear_locked()
            self.robot_name = robot
            self.body_names = body_names
            for name in body_names:
                frame = self.server.scene.add_frame(f"{self.root}/{name}", show_axes=False)
                self.frames.append(frame)
                bm = meshes.get(name)
                if bm is not None:
                    color = _rgb(bm.rgba)
                    self.base_colors[name] = color
                    self.meshes[name] = self.server.scene.add_mesh_simple(
                        f"{self.root}/{name}/mesh", bm.vertices, bm.faces, color=color, opacity=self.opacity,
                        cast_shadow=self.opacity is None,
                    )
            self._sent_pos = np.full((len(self.frames), 3), np.nan)
            self._sent_wxyz = np.full((len(self.frames), 4), np.nan)

    def clear_locked(self) -> None:
        for handle in [*self.meshes.values(), *self.frames]:
            handle.remove()
        self.frames.clear()
        self.meshes.clear()
        self.base_colors.clear()

    def update(self, frame: msg.Frame) -> None:
        with self._lock:
            if len(frame.body_pos) != len(self.frames):
                return  # a frame of the previous robot
            pos = np.asarray(frame.body_pos, dtype=float).reshape(-1, 3)
            wxyz = np.asarray(frame.body_quat, dtype=float).reshape(-1, 4)
            moved = ~(np.abs(pos - self._sent_pos) <= POSITION_TOL_M).all(axis=1)  # NaN (never sent): moved
            turned = ~(np.abs(wxyz - self._sent_wxyz) <= WXYZ_TOL).all(axis=1)
            if moved.any() or turned.any():
                with self.server.atomic():
                    for i in np.flatnonzero(moved):
                        self._send(self.frames[i], "position", pos[i])
                    for i in np.flatnonzero(turned):
                        self._send(self.frames[i], "wxyz", wxyz[i])
                self._sent_pos[moved] = pos[moved]
                self._sent_wxyz[turned] = wxyz[turned]
                self.poses_sent += int(moved.sum() + turned.sum())
            self.last_frame = frame
            self.frames_shown += 1

    @staticmethod
    def _send(handle: viser.FrameHandle, prop: str, value: np.ndarray) -> None:
        """Queue one pose property of one node, already known to differ from what the browsers have."""
        impl: Any = getattr(handle, "_impl", None)
        queue = getattr(getattr(impl, "api", None), "_queue_scene_message", None)
        if impl is None or queue is None:  # not viser 1.1.1's layout: the public setter (checks the value again)
            setattr(handle, prop, value)
            return
        value_cast = tuple(float(v) for v in value)
        getattr(impl, prop)[:] = value_cast  # the handle reads back what was sent
        message: viser_messages.Message
        if prop == "position":
            message = viser_messages.SetPositionMessage(impl.name, value_cast)  # type: ignore[arg-type]
        else:
            message = viser_messages.SetOrientationMessage(impl.name, value_cast)  # type: ignore[arg-type]
        queue(_serialised_once(message))

    def tint(self, body: str, color: tuple[int, int, int] | None) -> None:
        """Recolour one body (None: back to its own colour) — one small message."""
        with self._lock:
            mesh = self.meshes.get(body)
            if mesh is not None:
                mesh.color = color if color is not None else self.base_colors[body]


def _serialised_once(message: viser_messages.Message) -> viser_messages.Message:
    """``message`` converting itself to its wire dict once for all browsers: viser converts each queued
    message for every connection (≈ 6 µs per pose message here, the largest per-client cost of a frame);
    a pose message has no binary buffers, so one dict serves every connection. Computed on first use,
    after :meth:`_queue_scene_message` stamped the message's owner."""
    convert = message.as_serializable_dict
    done: list[dict] = []

    def once(binary_buffers: Any = None) -> dict:
        if not done:
            done.append(convert(binary_buffers))
        return done[0]

    object.__setattr__(message, "as_serializable_dict", once)
    return message
