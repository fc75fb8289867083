"""Ground overlays of the control stack (paper Fig. 1): footholds, support polygon, CoM/CoP paths.

Drawn from engine telemetry; the studio computes nothing here, it only draws what the
engine planned and measured.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import viser

GROUND_Z = 0.003
PLANNED = (250, 250, 250)
ACHIEVED = (30, 30, 30)
COM_COLOR = (255, 255, 255)
COP_COLOR = (0, 170, 170)
SUPPORT_COLOR = (255, 170, 0)
SEGMENT_BLOCK = 32  # line-segment nodes hold a multiple of this many segments
_NOTHING = np.zeros((0, 2, 3), dtype=np.float32)


def _loop_segments(polygon: np.ndarray, z: float = GROUND_Z) -> np.ndarray:
    pts = np.column_stack([polygon, np.full(len(polygon), z)])
    return np.stack([pts, np.roll(pts, -1, axis=0)], axis=1)


def _rect(x: float, y: float, yaw: float, length: float, width: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    local = np.array([[length / 2, width / 2], [length / 2, -width / 2], [-length / 2, -width / 2], [-length / 2, width / 2]])
    return np.array([x, y]) + local @ np.array([[c, s], [-s, c]])


class Overlays:
    def __init__(self, server: viser.ViserServer, root: str = "/overlays"):
        self.server = server
        self.root = root
        self.visible = True
        self.sole = (0.17, 0.055)
        self.handles: dict[str, Any] = {}  # viser scene-node handles of several kinds
        self._drawn: dict[str, np.ndarray] = {}  # the segments each line node shows

    def set_sole(self, length_m: float, width_m: float) -> None:
        self.sole = (length_m, width_m)

    def clear(self) -> None:
        for handle in self.handles.values():
            handle.remove()
        self.handles.clear()
        self._drawn.clear()

    def set_visible(self, visible: bool) -> None:
        self.visible = visible
        for handle in self.handles.values():
            handle.visible = visible

    def _segments(self, name: str, segments: np.ndarray, color: tuple[int, int, int], width: float = 2.0) -> None:
        """Draw ``segments`` as the node ``name``: nothing is sent when they did not change, and the node is
        made for a capacity (a multiple of :data:`SEGMENT_BLOCK`, padded with copies of the last segment,
        which draw nothing new), so a path that grows by a point updates its points instead of re-creating
        the node every telemetry tick."""
        if len(segments) == 0:
            segments = np.zeros((1, 2, 3))
        segments = segments.astype(np.float32)
        if np.array_equal(self._drawn.get(name, _NOTHING), segments):
            return
        self._drawn[name] = segments
        capacity = -(-len(segments) // SEGMENT_BLOCK) * SEGMENT_BLOCK
        padded = np.concatenate([segments, np.repeat(segments[-1:], capacity - len(segments), axis=0)])
        handle = self.handles.get(name)
        if handle is not None and getattr(handle, "_n", None) == capacity:
            handle.points = padded
        else:
            if handle is not None:
                handle.remove()
            handle = self.server.scene.add_line_segments(f"{self.root}/{name}", padded,
                                                          colors=color, thickness=width, thickness_units="screen", visible=self.visible)
            handle._n = capacity  # type: ignore[attr-defined]
            self.handles[name] = handle

    def _path(self, name: str, xy: np.ndarray, color: tuple[int, int, int], width: float = 3.0) -> None:
        if len(xy) < 2:
            self._segments(name, np.zeros((0, 2, 3)), color, width)
            return
        pts = np.column_stack([xy, np.full(len(xy), GROUND_Z)])
        self._segments(name, np.stack([pts[:-1], pts[1:]], axis=1), color, width)

    def update(self, signals: dict[str, np.ndarray]) -> None:
        if "support_polygon" not in signals:
            return
        with self.server.atomic():
            self._segments("support", _loop_segments(signals["support_polygon"]), SUPPORT_COLOR, 3.0)
            self._path("com_path", signals["com_path_xy"], COM_COLOR)
            self._path("cop_path", signals["cop_path_xy"], COP_COLOR)
            planned = [_loop_segments(_rect(x, y, yaw, *self.sole)) for x, y, yaw in signals["footholds_planned"]]
            self._segments("footholds_planned", np.concatenate(planned) if planned else np.zeros((0, 2, 3)), PLANNED, 2.0)
            achieved = [_loop_segments(_rect(x, y, yaw, *self.sole), 0.004) for x, y, yaw in signals["footholds_latched"]]
            self._segments("footholds_achieved", np.concatenate(achieved), ACHIEVED, 2.5)
            com = np.append(signals["com_xy"], GROUND_Z)
            cop = np.append(signals["cop_ref_xy"], GROUND_Z)
            self._marker("com", com, COM_COLOR)
            self._marker("cop", cop, COP_COLOR)

    def _marker(self, name: str, pos: np.ndarray, color: tuple[int, int, int]) -> None:
        handle = self.handles.get(name)
        if handle is None:
            handle = self.server.scene.add_icosphere(f"{self.root}/{name}", radius=0.015, color=color,
                                                     position=tuple(pos), visible=self.visible)
            self.handles[name] = handle
        else:
            handle.position = pos
