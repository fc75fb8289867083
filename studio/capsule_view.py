"""LWL2's self-collision capsules drawn on the robot, tinted by signed distance.

Each capsule is a mesh child of the robot body it rides on (``/robot/<body>/capsule_<name>``, placed by
:func:`engine.retarget.humanoid_arm.capsules.capsules_on_bodies`), so the robot's own pose stream
(:class:`studio.robot_view.RobotView`) carries it: drawing the capsules adds no pose message at all. What
streams is the tint — per capsule its smallest signed distance to the capsules it is checked against (the
engine's ``puppet_capsule_min_distance``): red when colliding (< 0), orange when closer than
:data:`NEAR_M`, neutral otherwise; a telemetry sample sends only the capsules whose tint changed, in one
atomic block.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING

import numpy as np
import viser

if TYPE_CHECKING:
    from engine.retarget.humanoid_arm.capsules import CapsuleOnBody

NEAR_M = 0.02  # closer than this (but not touching): orange
FREE, NEAR, COLLIDING = 0, 1, 2
COLORS = {FREE: (60, 200, 120), NEAR: (250, 160, 30), COLLIDING: (235, 25, 25)}
OPACITY = 0.55


def capsule_mesh(length: float, radius: float, segments: int = 16, rings: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) float32, faces (F, 3) uint32) of a capsule along z, centred, sphere centres ±length/2;
    faces wound counter-clockwise seen from outside."""
    half = 0.5 * max(float(length), 0.0)
    phi = np.linspace(0.0, 0.5 * np.pi, rings + 1)[1:]  # from the pole to the equator
    profile = [(radius * np.sin(p), half + radius * np.cos(p)) for p in phi]
    profile += [(radius * np.sin(p), -half - radius * np.cos(p)) for p in phi[::-1]]
    ang = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    verts = [(0.0, 0.0, half + radius)]
    for r, z in profile:
        verts += [(r * np.cos(a), r * np.sin(a), z) for a in ang]
    verts.append((0.0, 0.0, -half - radius))
    n_rings, bottom = len(profile), 1 + len(profile) * segments
    faces = []
    for s in range(segments):
        s1 = (s + 1) % segments
        faces.append((0, 1 + s, 1 + s1))  # top fan
        for k in range(n_rings - 1):
            a, b = 1 + k * segments, 1 + (k + 1) * segments
            faces += [(a + s, b + s, b + s1), (a + s, b + s1, a + s1)]
        last = 1 + (n_rings - 1) * segments
        faces.append((bottom, last + s1, last + s))  # bottom fan
    return np.array(verts, dtype=np.float32), np.array(faces, dtype=np.uint32)


def tint_states(min_distance_m: np.ndarray, near_m: float = NEAR_M) -> np.ndarray:
    """(C,) FREE / NEAR / COLLIDING of each capsule's smallest signed distance."""
    d = np.asarray(min_distance_m, dtype=float)
    return np.where(d < 0.0, COLLIDING, np.where(d < near_m, NEAR, FREE))


class CapsuleView:
    """The capsules of one robot under the body frames of a :class:`RobotView` rooted at ``root``."""

    def __init__(self, server: viser.ViserServer, root: str = "/robot"):
        self.server, self.root = server, root
        self.capsules: list[CapsuleOnBody] = []
        self.meshes: list[viser.MeshHandle] = []
        self.states = np.zeros(0, dtype=int)
        self.visible = False
        self.tints_sent = 0  # colour messages queued (only changed capsules)
        self._lock = threading.Lock()

    @property
    def names(self) -> list[str]:
        return [c.name for c in self.capsules]

    def build(self, capsules: list[CapsuleOnBody], visible: bool) -> None:
        """(Re)create the capsule meshes (after the robot's body frames were (re)built), neutral."""
        with self._lock, self.server.atomic():
            self._clear_locked()
            self.capsules = list(capsules)
            self.visible = visible
            for c in self.capsules:
                verts, faces = capsule_mesh(c.length, c.radius)
                self.meshes.append(self.server.scene.add_mesh_simple(
                    f"{self.root}/{c.body}/capsule_{c.name}", verts, faces, color=COLORS[FREE], opacity=OPACITY,
                    position=np.asarray(c.position, dtype=float), wxyz=np.asarray(c.wxyz, dtype=float),
                    cast_shadow=False, receive_shadow=False, visible=visible))
            self.states = np.full(len(self.capsules), FREE, dtype=int)

    def clear(self) -> None:
        with self._lock:
            self._clear_locked()

    def _clear_locked(self) -> None:
        for mesh in self.meshes:
            if not getattr(getattr(mesh, "_impl", None), "removed", False):  # gone with its body frame already
                mesh.remove()
        self.meshes.clear()
        self.capsules = []
        self.states = np.zeros(0, dtype=int)

    def set_visible(self, visible: bool) -> None:
        with self._lock:
            if visible == self.visible:
                return
            self.visible = visible
            with self.server.atomic():
                for mesh in self.meshes:
                    mesh.visible = visible

    def tint(self, min_distance_m: np.ndarray | None) -> int:
        """Tint by each capsule's smallest signed distance (None: all neutral); returns how many changed."""
        with self._lock:
            if not self.meshes:
                return 0
            if min_distance_m is None:
                states = np.full(len(self.meshes), FREE, dtype=int)
            else:
                if len(min_distance_m) != len(self.meshes):
                    return 0  # another robot's capsules
                states = tint_states(min_distance_m)
            changed = np.flatnonzero(states != self.states)
            if len(changed):
                with self.server.atomic():
                    for i in changed:
                        self.meshes[i].color = COLORS[int(states[i])]
                self.tints_sent += len(changed)
                self.states = states
            return len(changed)
