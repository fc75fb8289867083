"""The robot in the 3D view: one frame per body, one recolourable mesh under each."""

from __future__ import annotations

import threading

import numpy as np
import viser

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
            with self.server.atomic():
                for handle, pos, quat in zip(self.frames, frame.body_pos, frame.body_quat):
                    handle.position = pos
                    handle.wxyz = quat
            self.last_frame = frame
            self.frames_shown += 1

    def tint(self, body: str, color: tuple[int, int, int] | None) -> None:
        """Recolour one body (None: back to its own colour) — one small message."""
        with self._lock:
            mesh = self.meshes.get(body)
            if mesh is not None:
                mesh.color = color if color is not None else self.base_colors[body]
