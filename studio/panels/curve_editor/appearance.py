"""The graph editor's look: colours, palette, tick placement, screen projection, the scene-node pool."""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np
import numpy.typing as npt
import viser.transforms as vtf


CURVE_SAMPLES = 200  # polyline samples per channel across the view
KNOT_RADIUS_M = 0.014
SELECTED = (255, 215, 0)  # Maya: selected keys are yellow (no channel colour is yellow)
PRIMARY = (255, 215, 0)  # the knot whose handles and values show: drawn larger
HANDLE_COLOR = (45, 45, 45)
GHOST_COLOR = (175, 175, 180)
BACKDROP = (243, 244, 247)
PLOT_BG = (226, 229, 235)  # outside the interval
INTERVAL_BG = (253, 253, 253)
GRID = (214, 217, 224)
GRID_ZERO = (150, 154, 162)
EXTENT = (70, 75, 85)
PLAYHEAD = (200, 30, 190)  # magenta: no curve uses it

#: (rgb, square emoji, round emoji) — emoji chosen to match the line colours.
PALETTE: tuple[tuple[tuple[int, int, int], str, str], ...] = (
    ((214, 39, 40), "🟥", "🔴"),
    ((44, 160, 44), "🟩", "🟢"),
    ((31, 110, 200), "🟦", "🔵"),
    ((245, 125, 10), "🟧", "🟠"),
    ((148, 90, 200), "🟪", "🟣"),
    ((140, 86, 60), "🟫", "🟤"),
    ((50, 50, 55), "⬛", "⚫"),
)
_COMPONENT_COLOR = {"x": 0, "y": 1, "z": 2, "yaw": 3, "heel_pitch": 4, "toe_pitch": 5, "roll": 6, "pitch": 4}
PRIMARY_SCALE, SELECTED_SCALE = 1.35, 1.15

def channel_color(channel: str) -> tuple[tuple[int, int, int], str] | None:
    """Fixed (rgb, emoji) of swing and pelvis channels — components by hue (x red, y green, z blue,
    yaw orange, pitch purple, roll black), round emoji for the right foot. None for joints: the
    editor gives a joint a free palette colour while it is shown (:meth:`CurveEditor.color_of`)."""
    head, tail = channel.split(".", 1)
    if head == "joints":
        return None
    rgb, square, circle = PALETTE[_COMPONENT_COLOR.get(tail, 6)]
    return rgb, circle if head == "right_foot" else square


def nice_ticks(lo: float, hi: float, target: int = 6) -> tuple[list[float], int]:
    """Ticks at 1-2-5 multiples inside [lo, hi] and the decimals to print them with."""
    span = hi - lo
    if not (math.isfinite(span) and span > 0):
        return [lo], 2
    raw = span / max(target, 1)
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step - 1e-9) * step
    ticks = []
    k = 0
    while first + k * step <= hi + 1e-9 * step and k < 100:
        ticks.append(round(first + k * step, 12))
        k += 1
    decimals = max(0, -math.floor(math.log10(step) + 1e-9))
    return ticks, decimals


def project_to_screen(point: npt.ArrayLike, cam_position: npt.ArrayLike, cam_wxyz: npt.ArrayLike,
                      fov: float, aspect: float) -> tuple[float, float] | None:
    """OpenCV screen coordinates (0..1, origin top-left) of a world point, None behind the camera."""
    R = vtf.SO3(np.asarray(cam_wxyz, dtype=float)).as_matrix()  # world_from_camera (+z forward, +y down)
    pc = R.T @ (np.asarray(point, dtype=float) - np.asarray(cam_position, dtype=float))
    if pc[2] <= 1e-6:
        return None
    f = 0.5 / math.tan(fov / 2.0)
    return (0.5 + pc[0] / pc[2] * f / aspect, 0.5 + pc[1] / pc[2] * f)


class NodePool:
    """Scene nodes keyed by name, created once and updated in place (cached props)."""

    def __init__(self) -> None:
        self.nodes: dict[str, Any] = {}
        self.cache: dict[tuple[str, str], Any] = {}

    def set(self, key: str, prop: str, value: Any) -> None:
        node = self.nodes[key]
        cached = self.cache.get((key, prop), _MISSING)
        if cached is not _MISSING and _same(cached, value):
            return
        setattr(node, prop, value)
        self.cache[(key, prop)] = value

    def remove(self, key: str) -> None:
        node = self.nodes.pop(key, None)
        for ck in [ck for ck in self.cache if ck[0] == key]:
            del self.cache[ck]
        if node is not None:
            node.remove()


_MISSING = object()


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and bool(np.all(a == b))
    return a == b


def _blend(rgb: Sequence[int], towards: Sequence[int], amount: float) -> tuple[int, int, int]:
    return tuple(int(round(c + (t - c) * amount)) for c, t in zip(rgb, towards))  # type: ignore[return-value]


def _linear_u8(rgb: npt.ArrayLike) -> np.ndarray:
    """sRGB → linear uint8: viser hands per-vertex line colours to three.js as linear values."""
    c = np.asarray(rgb, dtype=float) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(lin * 255.0).astype(np.uint8)


def _solid_image(rgb: Sequence[int]) -> np.ndarray:
    return np.tile(np.asarray(rgb, dtype=np.uint8), (2, 2, 1))


