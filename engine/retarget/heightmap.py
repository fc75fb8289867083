"""HeightMap: the ground the anchors are projected onto (§V-A): a flat floor plus axis-aligned boxes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Box:
    x_m: float  # centre
    y_m: float
    width_m: float  # along x
    depth_m: float  # along y
    height_m: float

    def contains(self, x: float, y: float) -> bool:
        return abs(x - self.x_m) <= self.width_m / 2 and abs(y - self.y_m) <= self.depth_m / 2


_STENCIL = np.array([[0, 0], [1, 0], [-1, 0], [0, 1], [0, -1], [0.7, 0.7], [0.7, -0.7], [-0.7, 0.7], [-0.7, -0.7]])


@dataclass(frozen=True)
class HeightMap:
    floor_z_m: float = 0.0
    boxes: tuple[Box, ...] = field(default_factory=tuple)

    def height(self, x: float, y: float) -> float:
        h = self.floor_z_m
        for b in self.boxes:
            if b.contains(x, y):
                h = max(h, self.floor_z_m + b.height_m)
        return h

    def heights(self, xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=float)
        h = np.full(xy.shape[:-1], self.floor_z_m)
        for b in self.boxes:
            inside = (np.abs(xy[..., 0] - b.x_m) <= b.width_m / 2) & (np.abs(xy[..., 1] - b.y_m) <= b.depth_m / 2)
            h = np.where(inside, np.maximum(h, self.floor_z_m + b.height_m), h)
        return h

    def support_heights(self, xy: np.ndarray, radius_m: np.ndarray | float, margin_m: float = 0.02) -> np.ndarray:
        """Highest ground under a disc (radius + margin) around each point: what a foot sphere there rests on
        (a foot overhanging a box edge rests on the box)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=float))
        if not self.boxes:
            return np.full(len(xy), self.floor_z_m)
        r = np.broadcast_to(np.asarray(radius_m, dtype=float), (len(xy),))
        pts = xy[:, None, :] + _STENCIL[None, :, :] * (r[:, None, None] + margin_m)
        return self.heights(pts).max(axis=1)

    def project(self, p: np.ndarray, radius_m: float = 0.0) -> np.ndarray:
        """ProjectGround: where a foot sphere of ``radius_m`` above/below p rests on the surface."""
        return np.array([p[0], p[1], float(self.support_heights(p[:2], radius_m)[0]) + radius_m])

    def to_json(self) -> dict:
        return {"floor_z_m": self.floor_z_m, "boxes": [b.__dict__ for b in self.boxes]}


def parse_terrain(specs: list[str] | tuple[str, ...] | None) -> HeightMap:
    """``box:x,y,w,d,h`` (metres; repeatable) → HeightMap. Raises ValueError naming the spec."""
    boxes = []
    for spec in specs or ():
        kind, _, rest = spec.partition(":")
        if kind != "box":
            raise ValueError(f"--terrain {spec!r}: expected box:x,y,w,d,h")
        try:
            x, y, w, d, h = (float(v) for v in rest.split(","))
        except ValueError:
            raise ValueError(f"--terrain {spec!r}: expected box:x,y,w,d,h (five numbers, metres)") from None
        if not all(np.isfinite([x, y, w, d, h])) or w <= 0 or d <= 0 or not (0 < h <= 2):
            raise ValueError(f"--terrain {spec!r}: expected w, d > 0 and 0 < h ≤ 2 m")
        boxes.append(Box(x, y, w, d, h))
    return HeightMap(0.0, tuple(boxes))
