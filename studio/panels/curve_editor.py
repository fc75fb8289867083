"""Function-curve editor (paper §4.3 "Function Curves", §6.1, Fig. 10): a Maya/Blender-style graph editor.

The graph is a vertical plane in the 3D scene under ``root`` (a frame the app may move):
time runs along the frame's +x axis, values along +z, and the graph faces the frame's −y
side (a camera placed on −y looking toward +y sees it head-on; :meth:`CurveEditor.camera_pose`
computes such a pose). Geometry in the frame, in metres: the plot area is
``[0, width_m] × [0, height_m]``; tick labels sit left of and below it.

Editing goes through :class:`~studio.style_session.StyleSession` only. A knot drag applies
throttled previews (every :data:`PREVIEW_PERIOD_S`) so the engine follows the edit, then
collapses them into one undo entry at release (:class:`UndoGroup`, public session methods
only). Refused edits show the validator's message and snap back to the pre-drag style.

Mouse interactions (viser 1.1.1, verified in ``viser/_scene_handles.py`` / ``DragLayer.tsx``):
knots and tangent handles are icospheres/boxes with ``handle.on_drag`` (start/update/end,
~20 Hz; ``end_position`` is the pointer on a camera-parallel plane through the grab point —
the editor intersects the camera ray through it with the graph plane); click selects,
Ctrl/Cmd+click toggles; Shift+drag on the canvas draws a selection rectangle
(``scene.on_rect_select``; Ctrl/Cmd+Shift adds to the selection). Ctrl+Z / Ctrl+Shift+Z /
Ctrl+Y click the Undo/Redo buttons through a keydown listener installed by an ``add_html``
snippet (an ``<img onerror>`` handler: React's ``innerHTML`` never runs ``<script>`` tags).
"""

from __future__ import annotations

import collections
import contextlib
import logging
import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Sequence

import numpy as np
import viser
import viser.transforms as vtf

from engine.gait.curves import MIN_KNOT_GAP_S, HermiteCurve, Knot, TangentMode
from engine.gait.style import (
    MAX_FOOT_ANGLE_RAD,
    MAX_FOOT_OFFSET_M,
    MAX_PELVIS_ANGLE_RAD,
    MAX_PELVIS_Z_OFFSET_M,
    PELVIS_CURVES,
    GaitSample,
    Style,
    StyleContext,
    channel_side,
    swing_channels,
)
from engine.gait.velocity_sampler import SAMPLE_NAMES
from studio.style_session import EditResult, StyleSession

log = logging.getLogger(__name__)

PREVIEW_PERIOD_S = 0.1  # throttled session.apply while dragging (the engine sees edits at ~10 Hz)
TYPING_PAUSE_S = 0.4  # a typed knot time/value applies once the keys pause this long
AXIS_LOCK_RATIO = 4.0  # a knot drag this much more vertical than horizontal (~14°) keeps its time (and vice versa)
DRAG_EDGE = 0.0  # a dragged knot this close (fraction of the range) to the view's edge, or beyond it, …
DRAG_GROW = 0.25  # … grows the value range by this fraction beyond it, so the drag goes on past the view
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

TANGENT_LABELS = {
    "auto-clamped": TangentMode.AUTO_CLAMPED,
    "flat": TangentMode.FLAT,
    "linear": TangentMode.LINEAR,
    "aligned": TangentMode.ALIGNED,
    "free (broken)": TangentMode.FREE,
}
MODE_LABEL = {mode: label for label, mode in TANGENT_LABELS.items()}
MIXED = "(mixed)"  # the dropdown's value when the selected knots differ

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

# ----------------------------------------------------------------------------- pure helpers


@dataclass(frozen=True, order=True)
class KnotRef:
    """One knot of the edited sample: channel name and knot index (knots never reorder)."""

    channel: str
    index: int


def channel_interval(channel: str) -> str:
    """"left" / "right" (that foot's swing interval) or "cycle"."""
    return channel_side(channel) or "cycle"


def interval_duration(sample: GaitSample, interval: str) -> float:
    """Duration [s] of an interval of a sample ("left", "right" or "cycle")."""
    return sample.intervals.cycle_s if interval == "cycle" else sample.intervals.swing_duration_s(interval)


def all_channels(ctx: StyleContext) -> list[str]:
    """Every curve channel of the robot, in the editor's list order."""
    return [*swing_channels("left"), *swing_channels("right"), *PELVIS_CURVES,
            *(f"joints.{j}" for j in ctx.upper_joints)]


def channel_tail(channel: str) -> str:
    return channel.split(".", 1)[1]


def channel_unit(channel: str) -> str:
    tail = channel_tail(channel)
    return "m" if tail in ("x", "y", "z") and not channel.startswith("joints.") else "rad"


def channel_limits(channel: str, sample: GaitSample, ctx: StyleContext) -> tuple[float, float]:
    """The value range validation allows for a channel (what knot drags clamp to)."""
    tail = channel_tail(channel)
    if channel_side(channel) is not None:
        if tail == "z":
            return (0.0, ctx.max_swing_height_m)
        if tail == "heel_pitch":
            return (-math.pi / 2, 0.0)
        if tail == "toe_pitch":
            return (0.0, math.pi / 2)
        if tail in ("x", "y"):
            return (-MAX_FOOT_OFFSET_M, MAX_FOOT_OFFSET_M)
        return (-MAX_FOOT_ANGLE_RAD, MAX_FOOT_ANGLE_RAD)
    if channel == "pelvis.z":
        lo, hi = ctx.pelvis_height_range_m
        height = sample.attributes.pelvis_height_m
        return (max(-MAX_PELVIS_Z_OFFSET_M, lo - height), min(MAX_PELVIS_Z_OFFSET_M, hi - height))
    if channel.startswith("pelvis."):
        return (-MAX_PELVIS_ANGLE_RAD, MAX_PELVIS_ANGLE_RAD)
    return ctx.joint_limits.get(tail, (-math.pi, math.pi))


def channel_default(channel: str, ctx: StyleContext) -> float:
    """Value a channel holds without a curve: the joint's standing angle, else 0."""
    if channel.startswith("joints."):
        return float(ctx.standing_angles.get(channel_tail(channel), 0.0))
    return 0.0


def opposite_channel(channel: str) -> str | None:
    """left ↔ right counterpart (``left_foot.y`` ↔ ``right_foot.y``, ``joints.arm_left_1_joint`` ↔
    ``joints.arm_right_1_joint``), None if unpaired (pelvis, waist, head)."""
    head, tail = channel.split(".", 1)
    swap = {"left": "right", "right": "left"}
    if head in ("left_foot", "right_foot"):
        return f"{swap[head[:-5]]}_foot.{tail}"
    if head != "joints":
        return None
    parts = tail.split("_")
    sides = [i for i, part in enumerate(parts) if part in swap]
    if not sides:
        return None
    parts[sides[0]] = swap[parts[sides[0]]]
    return "joints." + "_".join(parts)


def mirror_sign(channel: str) -> float:
    """−1 for lateral components (y, yaw, roll and roll/yaw joints) when mirrored left ↔ right."""
    tail = channel_tail(channel)
    if channel.startswith("joints."):
        return -1.0 if ("roll" in tail or "yaw" in tail) else 1.0
    return -1.0 if tail in ("y", "yaw", "roll") else 1.0


def channel_color(channel: str) -> tuple[tuple[int, int, int], str] | None:
    """Fixed (rgb, emoji) of swing and pelvis channels — components by hue (x red, y green, z blue,
    yaw orange, pitch purple, roll black), round emoji for the right foot. None for joints: the
    editor gives a joint a free palette colour while it is shown (:meth:`CurveEditor.color_of`)."""
    head, tail = channel.split(".", 1)
    if head == "joints":
        return None
    rgb, square, circle = PALETTE[_COMPONENT_COLOR.get(tail, 6)]
    return rgb, circle if head == "right_foot" else square


def is_pinned(channel: str, index: int, n_knots: int) -> bool:
    """Swing boundary knots (liftoff / touchdown) are pinned in time (and at 0 except pitch)."""
    return channel_side(channel) is not None and index in (0, n_knots - 1)


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


def project_to_screen(point: Sequence[float], cam_position: Sequence[float], cam_wxyz: Sequence[float],
                      fov: float, aspect: float) -> tuple[float, float] | None:
    """OpenCV screen coordinates (0..1, origin top-left) of a world point, None behind the camera."""
    R = vtf.SO3(np.asarray(cam_wxyz, dtype=float)).as_matrix()  # world_from_camera (+z forward, +y down)
    pc = R.T @ (np.asarray(point, dtype=float) - np.asarray(cam_position, dtype=float))
    if pc[2] <= 1e-6:
        return None
    f = 0.5 / math.tan(fov / 2.0)
    return (0.5 + pc[0] / pc[2] * f / aspect, 0.5 + pc[1] / pc[2] * f)


def handle_points(curve: HermiteCurve, index: int) -> dict[str, tuple[float, float]]:
    """Tangent handles of a knot — the adjacent Bézier control points ``P ± m·h/3`` as (t, v).

    ``"in"`` is the previous segment's P2, ``"out"`` the next segment's P1 (periodic curves
    wrap: the first knot's in-handle comes from the wrap segment, shifted by −duration).
    """
    cps = curve.bezier_control_points()
    n = curve.n_knots
    out: dict[str, tuple[float, float]] = {}
    if curve.n_segments == 0:
        return out
    if index < curve.n_segments:
        out["out"] = (float(cps[index, 1, 0]), float(cps[index, 1, 1]))
    if index > 0:
        out["in"] = (float(cps[index - 1, 2, 0]), float(cps[index - 1, 2, 1]))
    elif curve.periodic and n > 1:
        out["in"] = (float(cps[-1, 2, 0]) - curve.duration_s, float(cps[-1, 2, 1]))
    elif curve.periodic and n == 1:
        out["in"] = (float(cps[0, 2, 0]) - curve.duration_s, float(cps[0, 2, 1]))
    return out


def move_knots(channel: str, curve: HermiteCurve, indices: Iterable[int], dt: float, dv: float,
               limits: tuple[float, float]) -> tuple[HermiteCurve, list[str]]:
    """Move knots by (dt, dv) from ``curve`` under the editor's constraints; returns (curve, notes).

    Swing boundary knots keep their time (and value 0, pitch channels: clamped value); other
    knots stay inside the interval (periodic: ``[0, duration)``) and between their
    neighbours; values clamp to ``limits``. Knots move far side first so a group keeps order.
    """
    knots = curve.knots
    n = len(knots)
    d = curve.duration_s
    pitch = channel.endswith("_pitch")
    notes: list[str] = []
    result = curve
    for i in sorted(set(indices), reverse=bool(dt > 0)):
        k = knots[i]
        t, v = k.t_s + dt, k.value + dv
        if is_pinned(channel, i, n):
            t = k.t_s
            if not pitch:
                if abs(dv) > 0 or abs(dt) > 0:
                    notes.append("swing boundary knots stay at 0 at liftoff/touchdown")
                v = k.value
            elif abs(dt) > 0:
                notes.append("swing boundary knots keep their time")
        elif curve.periodic and not 0.0 <= t < d:
            notes.append(f"knots stay inside the cycle [0, {d:.3f}) s")
        elif not curve.periodic and not 0.0 < t < d:
            notes.append(f"knots stay inside the swing (0, {d:.3f}) s")
        lo, hi = limits
        if v < lo or v > hi:
            notes.append(f"{channel} clamped to [{lo:.3g}, {hi:.3g}]")
            v = min(max(v, lo), hi)
        result = result.with_knot_moved(i, t, v)
        got = result.knots[i].t_s
        if abs(got - t) > 1e-9 and not notes and not is_pinned(channel, i, n):
            notes.append("knot times stay between their neighbours")
    return result, list(dict.fromkeys(notes))


def slope_from_handle(curve: HermiteCurve, index: int, side: str, t_h: float, v_h: float) -> float:
    """Slope implied by dragging a knot's ``side`` handle to (t_h, v_h); the handle cannot cross the knot."""
    k = curve.knots[index]
    eps = 1e-3 * curve.duration_s
    dt = t_h - k.t_s
    dt = max(dt, eps) if side == "out" else min(dt, -eps)
    return (v_h - k.value) / dt


def with_handle_slope(curve: HermiteCurve, index: int, side: str, slope: float) -> HermiteCurve:
    """Blender semantics: automatic modes become ALIGNED, ALIGNED mirrors, FREE keeps sides independent."""
    mode = curve.knots[index].mode
    if mode is TangentMode.FREE:
        return curve.with_tangent(index, TangentMode.FREE, **({"in_slope": slope} if side == "in" else {"out_slope": slope}))
    return curve.with_tangent(index, TangentMode.ALIGNED, in_slope=slope)


# ----------------------------------------------------------------------------- undo grouping


class UndoGroup:
    """Several ``session.apply`` calls that end up as ONE undo entry.

    Live previews and the final edit share the session's ``merge_key``: the engine follows
    every preview, and undo returns to the style before the drag.
    """

    def __init__(self, session: StyleSession, label: str, quiet: Callable[[], contextlib.AbstractContextManager]):
        self.session = session
        self.label = label
        self.base = session.style
        self.previews = 0
        self._key = object()
        self._quiet = quiet

    def preview(self, style: Style) -> EditResult:
        if style == self.session.style:
            return EditResult(True, "no change")
        result = self.session.apply(style, self.label, merge_key=self._key)
        if result.ok:
            self.previews += 1
        return result

    def commit(self, style: Style | None) -> EditResult:
        """Apply ``style`` as the group's one edit (None: back to the base). Refused: back to the base."""
        if style is None or style == self.base:
            if self.previews:
                self.session.apply(self.base, self.label, merge_key=self._key)
            return EditResult(True, "reverted" if style is None else "no change")
        result = self.session.apply(style, self.label, merge_key=self._key)
        if not result.ok and self.previews:
            self.session.apply(self.base, self.label, merge_key=self._key)
        return result

class _SerialWorker:
    """Runs posted callables in order on one thread; a queued item with the same key is replaced."""

    def __init__(self, name: str):
        self._queue: collections.deque[tuple[Any, Callable[[], None]]] = collections.deque()
        self._cv = threading.Condition()
        self._busy = False
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def post(self, fn: Callable[[], None], key: Any = None) -> None:
        with self._cv:
            if key is not None:
                for i, (k, _) in enumerate(self._queue):
                    if k == key:
                        self._queue[i] = (key, fn)
                        return
            self._queue.append((key, fn))
            self._cv.notify_all()

    def wait_idle(self, timeout_s: float = 5.0) -> bool:
        deadline = time.monotonic() + timeout_s
        with self._cv:
            while self._queue or self._busy:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cv.wait(left)
        return True

    def close(self) -> None:
        with self._cv:
            self._closed = True
            self._cv.notify_all()

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._queue and not self._closed:
                    self._cv.wait()
                if self._closed:
                    return
                _, fn = self._queue.popleft()
                self._busy = True
            try:
                fn()
            except Exception:  # the callables are guarded; never let the worker die
                log.exception("curve editor worker")
            finally:
                with self._cv:
                    self._busy = False
                    self._cv.notify_all()


# ----------------------------------------------------------------------------- editor state


@dataclass
class Clipboard:
    """Copied knots with the interval they came from (times are rescaled on paste)."""

    channel: str
    sample: str
    duration_s: float
    periodic: bool
    knots: tuple[Knot, ...]
    whole: bool


@dataclass
class _Drag:
    kind: str  # "knot" | "handle"
    ref: KnotRef
    side: str  # handle side ("in"/"out"); "" for knots
    anchor: np.ndarray  # graph-plane point (x, z) where the drag started
    group: UndoGroup
    base_curves: dict[str, HermiteCurve]
    moves: dict[str, list[int]]
    client: Any
    last_curves: dict[str, HermiteCurve] = field(default_factory=dict)
    view0: tuple[float, float, float, float] | None = None  # the view when the drag began (its scale)
    last_pt: np.ndarray | None = None  # graph-plane point of the latest pointer event
    last_preview_t: float = 0.0
    last_error: str = ""


class _Pool:
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


def _linear_u8(rgb: Sequence[int]) -> np.ndarray:
    """sRGB → linear uint8: viser hands per-vertex line colours to three.js as linear values."""
    c = np.asarray(rgb, dtype=float) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(lin * 255.0).astype(np.uint8)


def _solid_image(rgb: Sequence[int]) -> np.ndarray:
    return np.tile(np.asarray(rgb, dtype=np.uint8), (2, 2, 1))


_KEYS_SCRIPT = (
    "var m=window.__msCurveKeys=window.__msCurveKeys||{};m.undo='{undo}';m.redo='{redo}';m.del='{delete}';"
    "if(!m.installed){m.installed=1;"
    # the button may still be disabled for a moment (its state comes from the server): retry ~1 s
    "m.press=function(id,n){var b=document.getElementById(id);if(!b)return;"
    "if(b.disabled){if(n>0)setTimeout(function(){m.press(id,n-1);},100);return;}b.click();m.last=id;};"
    "window.addEventListener('keydown',function(e){"
    "var t=e.target;if(t&&(t.tagName==='INPUT'||t.tagName==='TEXTAREA'||t.isContentEditable))return;"
    "var k=(e.key||'').toLowerCase(),id=null;"
    "if((e.ctrlKey||e.metaKey)&&!e.altKey){if(k==='z'&&!e.shiftKey)id=m.undo;"
    "else if((k==='z'&&e.shiftKey)||k==='y')id=m.redo;}"
    "else if(!e.ctrlKey&&!e.metaKey&&!e.altKey&&(k==='delete'||k==='backspace'))id=m.del;"
    "if(!id)return;e.preventDefault();e.stopPropagation();m.press(id,10);},true);}"
)


class CurveEditor:
    """The function-curve editor panel: GUI controls plus a graph plane in the 3D scene."""

    def __init__(self, server: viser.ViserServer, session: StyleSession, root: str = "/curve_editor",
                 width_m: float = 1.6, height_m: float = 0.9):
        self.server = server
        self.session = session
        self.ctx = session.ctx
        self.root = root.rstrip("/") or "/curve_editor"
        self.width_m = float(width_m)
        self.height_m = float(height_m)
        self._lock = threading.RLock()
        self._local = threading.local()
        self._worker = _SerialWorker("curve-editor")
        self._sample = SAMPLE_NAMES[0]
        self._channels = all_channels(self.ctx)
        self._active = "left_foot.z"
        self._visible: list[str] = [self._active]
        self._selection: list[KnotRef] = []
        self._view = (0.0, 1.0, -1.0, 1.0)  # t_lo, t_hi, v_lo, v_hi (view units)
        self._norm: dict[str, tuple[float, float]] = {}  # channel -> (centre, half span) when normalising
        self._framed_key: tuple | None = None
        self._playhead: float | None = None
        self._drag: _Drag | None = None
        self._closed = False
        self._clipboard: Clipboard | None = None
        self.status = ""
        self.notices: list[str] = []
        self._knots = _Pool()
        self._labels = _Pool()
        self._props: dict[tuple[int, str], Any] = {}
        self._joint_colors: dict[str, int] = {}
        self._syncing = False
        #: called when the animator picks a sample in this panel's Sample menu (the app makes it the one
        #: selected everywhere: the Sample tab, and the sample Edit mode walks)
        self.on_sample_picked: Callable[[str], None] | None = None

        self.root_frame = server.scene.add_frame(self.root, show_axes=False)
        self._build_scene()
        self._build_gui()
        server.scene.on_rect_select(modifier="shift")(self._on_rect_select)
        server.scene.on_rect_select(modifier="cmd/ctrl+shift")(self._on_rect_select_add)
        session.subscribe(self._on_session_change)
        with self._lock:
            if session.style is not None:
                self._pick_initial_channel()
            self._frame_all_locked()
            self._redraw()

    # ================================================================== public API
    @property
    def sample(self) -> str:
        return self._sample

    @property
    def active_channel(self) -> str:
        return self._active

    @property
    def visible_channels(self) -> tuple[str, ...]:
        return tuple(self._visible)

    @property
    def interval(self) -> str:
        """The shown interval: "left" / "right" swing (t from liftoff) or "cycle"."""
        return channel_interval(self._active)

    @property
    def selection(self) -> tuple[KnotRef, ...]:
        return tuple(self._selection)

    @property
    def primary(self) -> KnotRef | None:
        return self._selection[-1] if self._selection else None

    @property
    def view(self) -> tuple[float, float, float, float]:
        """(t_lo, t_hi, v_lo, v_hi) of the graph; values in view units (native unless normalised)."""
        return self._view

    @property
    def dragging(self) -> bool:
        """A knot or tangent handle is being dragged."""
        return self._drag is not None

    @property
    def clipboard(self) -> Clipboard | None:
        return self._clipboard

    def set_sample(self, sample: str) -> None:
        """Edit one of the nine gait samples."""
        if sample not in SAMPLE_NAMES:
            raise ValueError(f"unknown sample {sample!r}; expected one of {', '.join(SAMPLE_NAMES)}")
        with self._lock:
            if sample == self._sample:
                return
            self._end_drag_now()
            self._sample = sample
            self._selection.clear()
            self._sync(self.sample_dropdown, sample)
            self._frame_all_locked()
            self._redraw()

    def set_playhead(self, t_s: float | None) -> None:
        """Playhead time in the shown interval's time [s]; None hides it."""
        with self._lock:
            self._playhead = None if t_s is None or not math.isfinite(float(t_s)) else float(t_s)
            self._draw_playhead()

    def playhead_from_cycle_time(self, t_cycle_s: float) -> float | None:
        """Convert time since left liftoff (mod cycle) to the shown interval's time (None: foot in stance)."""
        sample = self._sample_obj()
        if sample is None:
            return None
        cycle = sample.intervals.cycle_s
        t = float(t_cycle_s) % cycle
        if self.interval == "cycle":
            return t
        t0, t1 = sample.intervals.swing_s(self.interval)
        local = (t - t0) % cycle
        return local if local <= t1 - t0 else None

    def refresh(self) -> None:
        """Redraw everything from ``session.style``."""
        with self._lock:
            self._redraw()

    def close(self) -> None:
        """Stop the worker thread and remove the graph from the scene (session notifications are ignored)."""
        self._closed = True
        self._worker.close()
        with contextlib.suppress(Exception):
            self.root_frame.remove()

    def wait_idle(self, timeout_s: float = 5.0) -> bool:
        """Wait until queued mouse events have been processed (tests)."""
        return self._worker.wait_idle(timeout_s)

    # ---------------------------------------------------------------- channels
    def set_active_channel(self, channel: str) -> None:
        """Edit ``channel``; it becomes visible, channels of other intervals are hidden."""
        if channel not in self._channels:
            raise ValueError(f"unknown channel {channel!r}")
        with self._lock:
            self._set_active_locked(channel)
            # the knot fields show the edited channel's knot: keep only its knots selected
            self._selection = [r for r in self._selection if r.channel == channel]
            self._redraw()

    def show_channel(self, channel: str, visible: bool = True) -> None:
        """Show/hide a channel; showing one of another interval switches the shown interval."""
        with self._lock:
            self._show_channel_locked(channel, visible)
            self._redraw()

    # ---------------------------------------------------------------- selection
    def select(self, refs: Iterable[KnotRef], add: bool = False) -> None:
        """Select knots (the last one is the primary knot whose handles and values show)."""
        with self._lock:
            refs = [r for r in refs if self._knot_exists(r) and r.channel in self._visible]
            self._selection = ([r for r in self._selection if r not in refs] if add else []) + refs
            if self.primary is not None and self.primary.channel != self._active:
                self._active = self.primary.channel
            self._redraw()

    def select_all(self) -> None:
        """Every knot of the active channel."""
        with self._lock:
            curve = self._curve(self._active)
            self._selection = [KnotRef(self._active, i) for i in range(curve.n_knots)] if curve else []
            self._redraw()

    def clear_selection(self) -> None:
        with self._lock:
            self._selection.clear()
            self._redraw()

    def select_in_screen_rect(self, camera: Any, screen_min: Sequence[float], screen_max: Sequence[float],
                              add: bool = False) -> list[KnotRef]:
        """Box select: knots of visible channels whose projection lies in the rectangle (OpenCV 0..1)."""
        with self._lock:
            fov, aspect = float(camera.fov), float(camera.aspect)
            pos, wxyz = np.asarray(camera.position), np.asarray(camera.wxyz)
            found = []
            for ref in self._displayed_knots():
                uv = project_to_screen(self.knot_world_position(ref), pos, wxyz, fov, aspect)
                if uv and screen_min[0] <= uv[0] <= screen_max[0] and screen_min[1] <= uv[1] <= screen_max[1]:
                    found.append(ref)
            active_first = sorted(found, key=lambda r: (r.channel == self._active, r))
            self._selection = ([r for r in self._selection if r not in found] if add else []) + active_first
            if self._selection:
                self._active = self._selection[-1].channel
            self._status(f"{len(self._selection)} knot(s) selected" if self._selection else "nothing selected")
            self._redraw()
            return found

    # ---------------------------------------------------------------- editing actions
    def add_knot_at_playhead(self, client: Any = None) -> EditResult:
        """Insert a knot on the active channel at the playhead (a new curve if the channel has none)."""
        with self._lock:
            if self._playhead is None:
                return self._refuse("no playhead: play or scrub the gait first", client, notify=False)
            sample = self._sample_obj()
            if sample is None:
                return self._refuse("no style open", client)
            ch = self._active
            d = interval_duration(sample, channel_interval(ch))
            periodic = channel_interval(ch) == "cycle"
            t = self._playhead % d if periodic else self._playhead
            if not periodic and not 0.0 < t < d:
                return self._refuse(f"the playhead ({t:.3f} s) is outside the swing (0, {d:.3f}) s", client)
            curve = sample.curve(ch)
            try:
                if curve is None:
                    value = channel_default(ch, self.ctx)
                    if periodic:
                        curve = HermiteCurve([Knot(t, value)], d, periodic=True)
                    else:
                        curve = HermiteCurve([Knot(0.0, 0.0, mode=TangentMode.FLAT), Knot(t, value),
                                              Knot(d, 0.0, mode=TangentMode.FLAT)], d)
                else:
                    curve = curve.with_knot_added(t)
            except ValueError as exc:
                return self._refuse(str(exc), client)
            result = self._apply({ch: curve}, f"add knot on {ch}", client)
            if result.ok:
                idx = min(range(curve.n_knots), key=lambda i: abs(curve.knots[i].t_s - t))
                self._selection = [KnotRef(ch, idx)]
                self._redraw()
            return result

    def delete_selected(self, client: Any = None) -> EditResult:
        """Delete the selected knots (never the pinned swing boundary knots)."""
        with self._lock:
            sample = self._sample_obj()
            if sample is None or not self._selection:
                return self._refuse("select knots to delete", client, notify=False)
            by_channel: dict[str, list[int]] = collections.defaultdict(list)
            skipped = 0
            for ref in self._selection:
                curve = sample.curve(ref.channel)
                if curve is None:
                    continue
                if is_pinned(ref.channel, ref.index, curve.n_knots):
                    skipped += 1
                else:
                    by_channel[ref.channel].append(ref.index)
            if not by_channel:
                return self._refuse("swing boundary knots cannot be deleted (liftoff and touchdown are pinned)",
                                    client)
            curves: dict[str, HermiteCurve | None] = {}
            count = 0
            for ch, idx in by_channel.items():
                curve = sample.curve(ch)
                for i in sorted(idx, reverse=True):
                    curve = curve.with_knot_removed(i)
                    count += 1
                curves[ch] = curve if curve.n_knots else None
            result = self._apply(curves, f"delete {count} knot(s)", client)
            if result.ok:
                self._selection.clear()
                note = f" (kept {skipped} pinned boundary knot(s))" if skipped else ""
                self._status(f"deleted {count} knot(s){note}")
                self._redraw()
            return result

    def set_tangent_mode(self, mode: TangentMode | str, client: Any = None) -> EditResult:
        """Tangent mode of the selected knots (pinned swing boundary knots stay flat)."""
        mode = TangentMode(mode)
        with self._lock:
            sample = self._sample_obj()
            if sample is None or not self._selection:
                return self._refuse("select a knot first", client, notify=False)
            curves: dict[str, HermiteCurve] = {}
            skipped = 0
            for ref in self._selection:
                curve = curves.get(ref.channel) or sample.curve(ref.channel)
                if curve is None:
                    continue
                if is_pinned(ref.channel, ref.index, curve.n_knots):
                    skipped += 1
                    continue
                curves[ref.channel] = curve.with_tangent(ref.index, mode)
            if not curves:
                return self._refuse("swing boundary knots keep flat tangents", client)
            result = self._apply(curves, f"tangent {mode.value}", client)
            if result.ok:
                self._status(f"tangents: {MODE_LABEL[mode]}" + (f" ({skipped} pinned knot(s) stay flat)" if skipped else ""))
                self._redraw()
            return result

    def set_knot_values(self, t_s: float | None = None, value: float | None = None, client: Any = None) -> EditResult:
        """Type exact time and/or value for the primary selected knot (constraints as for drags)."""
        with self._lock:
            ref = self.primary
            sample = self._sample_obj()
            curve = sample.curve(ref.channel) if (sample is not None and ref is not None) else None
            if curve is None or ref.index >= curve.n_knots:
                return self._refuse("select a knot first", client, notify=False)
            k = curve.knots[ref.index]
            dt = 0.0 if t_s is None else float(t_s) - k.t_s
            dv = 0.0 if value is None else float(value) - k.value
            moved, notes = move_knots(ref.channel, curve, [ref.index], dt, dv,
                                      channel_limits(ref.channel, sample, self.ctx))
            result = self._apply({ref.channel: moved}, f"set knot on {ref.channel}", client)
            if result.ok:
                self._status("clamped: " + "; ".join(notes) if notes else f"knot set on {ref.channel}",
                             "warn" if notes else "info")
            self._redraw()
            return result

    def copy(self) -> Clipboard | None:
        """Copy the selected knots of the active channel (or its whole curve when none is selected)."""
        with self._lock:
            sample = self._sample_obj()
            curve = sample.curve(self._active) if sample is not None else None
            if curve is None:
                self._status(f"{self._active} has no curve to copy", "warn")
                return None
            picked = sorted(r.index for r in self._selection if r.channel == self._active and r.index < curve.n_knots)
            knots = curve.knots
            whole = not picked or len(picked) == len(knots)
            chosen = knots if whole else tuple(knots[i] for i in picked)
            self._clipboard = Clipboard(self._active, self._sample, curve.duration_s, curve.periodic, chosen, whole)
            self._status(f"copied {'the curve' if whole else f'{len(chosen)} knot(s)'} of {self._active} "
                         f"({self._sample})")
            self._redraw_gui_state()
            return self._clipboard

    def paste(self, to_other_side: bool = False, mirror: bool | None = None, half_cycle: bool | None = None,
              client: Any = None) -> EditResult:
        """Paste the clipboard onto the active channel, or onto the opposite side's channel.

        Times rescale to the target interval (normalised time); ``mirror`` negates lateral
        components when sides change; ``half_cycle`` shifts cycle knots by half a period.
        """
        with self._lock:
            clip = self._clipboard
            sample = self._sample_obj()
            if clip is None or sample is None:
                return self._refuse("nothing copied", client, notify=False)
            mirror = self.mirror_checkbox.value if mirror is None else mirror
            half_cycle = self.half_cycle_checkbox.value if half_cycle is None else half_cycle
            target = opposite_channel(clip.channel) if to_other_side else self._active
            if target is None:
                return self._refuse(f"{clip.channel} has no other side", client)
            if (channel_interval(target) == "cycle") != clip.periodic:
                kind = "cycle" if clip.periodic else "swing"
                return self._refuse(f"the clipboard holds {kind} knots; paste them onto a {kind} channel", client)
            d = interval_duration(sample, channel_interval(target))
            scale = d / clip.duration_s
            crosses = target == opposite_channel(clip.channel)
            sign = mirror_sign(clip.channel) if (mirror and crosses) else 1.0
            pasted = []
            for k in clip.knots:
                t = k.t_s * scale
                if clip.periodic:
                    if half_cycle and crosses:
                        t += 0.5 * d
                    t %= d
                    if t >= d:
                        t = 0.0
                else:
                    t = d if k.t_s == clip.duration_s else min(t, d)
                pasted.append(Knot(t, sign * k.value, sign * k.in_slope / scale, sign * k.out_slope / scale, k.mode))
            pasted.sort(key=lambda k: k.t_s)
            try:
                if clip.whole:
                    curve = HermiteCurve(pasted, d, clip.periodic)
                else:
                    curve = self._merge_knots(target, sample.curve(target), pasted, d)
            except ValueError as exc:
                return self._refuse(f"cannot paste: {exc}", client)
            result = self._apply({target: curve}, f"paste onto {target}", client)
            if result.ok:
                self._set_active_locked(target)
                times = {round(k.t_s, 9) for k in pasted}
                self._selection = [KnotRef(target, i) for i, k in enumerate(curve.knots) if round(k.t_s, 9) in times]
                self._status(f"pasted {len(pasted)} knot(s) onto {target} ({self._sample})")
                self._redraw()
            return result

    def frame_all(self) -> None:
        """Fit the view to the interval and the value range of the visible channels."""
        with self._lock:
            self._frame_all_locked()
            self._redraw()

    def frame_selected(self) -> None:
        """Fit the view around the selected knots (all visible curves when nothing is selected)."""
        with self._lock:
            sample = self._sample_obj()
            refs = [r for r in self._selection if self._knot_exists(r)]
            if sample is None or not refs:
                self._frame_all_locked()
                self._redraw()
                return
            d = interval_duration(sample, self.interval)
            ts, vs = [], []
            for r in refs:
                k = sample.curve(r.channel).knots[r.index]
                ts.append(k.t_s)
                vs.append(self._to_view(r.channel, k.value))
            pad_t = max(0.15 * (max(ts) - min(ts)), 0.12 * d)
            span_v = max(vs) - min(vs)
            pad_v = 0.2 * span_v if span_v > 0 else 0.1 * (self._view[3] - self._view[2])
            pad_v = max(pad_v, 1e-3)
            self._view = (min(ts) - pad_t, max(ts) + pad_t, min(vs) - pad_v, max(vs) + pad_v)
            self._redraw()

    def undo(self, client: Any = None) -> EditResult:
        with self._lock:
            self._end_drag_now()
            result = self.session.undo()
            self._status(result.message, "info" if result.ok else "warn")
            return result

    def redo(self, client: Any = None) -> EditResult:
        with self._lock:
            self._end_drag_now()
            result = self.session.redo()
            self._status(result.message, "info" if result.ok else "warn")
            return result

    # ---------------------------------------------------------------- mouse handlers (also used by tests)
    def handle_knot_drag(self, ref: KnotRef, event: Any) -> None:
        """Knot drag lifecycle: ``event`` has phase, start_position, end_position (world) and client."""
        with self._lock:
            phase = event.phase
            drag = self._drag
            if phase == "start" or drag is None or drag.kind != "knot" or drag.ref != ref:
                if phase == "end" and drag is None:
                    return
                self._start_knot_drag(ref, event)
                if phase == "start":
                    return
            self._update_drag(event)
            if phase == "end":
                self._finish_drag()

    def handle_tangent_drag(self, side: str, event: Any) -> None:
        """Tangent handle drag of the primary knot (``side`` "in" / "out")."""
        with self._lock:
            phase = event.phase
            drag = self._drag
            if phase == "start" or drag is None or drag.kind != "handle" or drag.side != side:
                if phase == "end" and drag is None:
                    return
                if not self._start_handle_drag(side, event):
                    return
                if phase == "start":
                    return
            self._update_drag(event)
            if phase == "end":
                self._finish_drag()

    def handle_knot_click(self, ref: KnotRef, toggle: bool = False) -> None:
        """Click selects a knot (toggle: add/remove it from the selection)."""
        with self._lock:
            if not self._knot_exists(ref):
                return
            if toggle:
                if ref in self._selection:
                    self._selection.remove(ref)
                else:
                    self._selection.append(ref)
            else:
                self._selection = [ref]
            if self.primary is not None:
                self._active = self.primary.channel
            self._redraw()

    # ---------------------------------------------------------------- geometry
    def graph_point(self, channel: str, t_s: float, value: float) -> tuple[float, float]:
        """(x, z) in the root frame of a curve point (t in the interval's time, value in channel units)."""
        t_lo, t_hi, v_lo, v_hi = self._view
        x = (t_s - t_lo) / (t_hi - t_lo) * self.width_m
        z = (self._to_view(channel, value) - v_lo) / (v_hi - v_lo) * self.height_m
        return x, z

    def world_position(self, channel: str, t_s: float, value: float) -> np.ndarray:
        """World coordinates of a curve point of ``channel``."""
        x, z = self.graph_point(channel, t_s, value)
        R, p = self._root_pose()
        return p + R @ np.array([x, 0.0, z])

    def knot_world_position(self, ref: KnotRef) -> np.ndarray:
        k = self._curve(ref.channel).knots[ref.index]
        return self.world_position(ref.channel, k.t_s, k.value)

    def handle_world_position(self, side: str) -> np.ndarray | None:
        """World position of the primary knot's ``side`` tangent handle (None when not shown)."""
        ref = self.primary
        curve = self._curve(ref.channel) if ref else None
        if curve is None or is_pinned(ref.channel, ref.index, curve.n_knots):
            return None
        pts = handle_points(curve, ref.index)
        return self.world_position(ref.channel, *pts[side]) if side in pts else None

    def camera_pose(self, fov: float = 0.9, aspect: float = 16 / 9, margin_m: float = 0.08,
                    right_inset: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position, look_at, up) of a camera seeing the whole graph head-on.

        ``right_inset``: fraction of the canvas width hidden on the right (viser's control
        panel floats over the canvas); the graph is centred in the uncovered part.
        """
        R, p = self._root_pose()
        left, bottom, top = -0.17, -0.09, 0.07  # tick labels and title
        cx, cz = (left + self.width_m) / 2, (bottom + self.height_m + top) / 2
        half_w = (self.width_m - left) / 2 + margin_m
        half_h = (self.height_m + top - bottom) / 2 + margin_m
        tan = math.tan(fov / 2)
        visible = min(max(1.0 - right_inset, 0.2), 1.0)
        dist = max(half_h / tan, half_w / (tan * aspect * visible))
        shift = (1.0 - visible) / 2 * 2 * dist * tan * aspect  # graph centre at the uncovered part's centre
        look_at = p + R @ np.array([cx + shift, 0.0, cz])
        return look_at + R @ np.array([0.0, -dist, 0.0]), look_at, R @ np.array([0.0, 0.0, 1.0])

    def look_at_graph(self, client: Any, right_inset_px: float | None = None) -> None:
        """Point ``client``'s camera at the graph (``right_inset_px``: canvas pixels under the panel;
        default: viser's medium control panel, 330 px, on canvases wider than 800 px)."""
        cam = client.camera
        try:
            fov, aspect, width = float(cam.fov), float(cam.aspect), float(cam.image_width)
        except (AssertionError, ZeroDivisionError, ValueError):
            fov, aspect, width = 0.9, 16 / 9, 0.0
        if not (fov > 0 and aspect > 0 and math.isfinite(aspect)):
            fov, aspect = 0.9, 16 / 9
        if right_inset_px is None:
            right_inset_px = 330.0 if width > 800 else 0.0
        inset = right_inset_px / width if width > 0 else 0.0
        position, look_at, up = self.camera_pose(fov, aspect, right_inset=inset)
        with client.atomic():
            cam.up_direction = up
            cam.position = position
            cam.look_at = look_at

    def color_of(self, channel: str) -> tuple[tuple[int, int, int], str]:
        """(rgb, emoji) a channel is drawn with: fixed for swing/pelvis channels; a shown joint keeps
        the palette colour it got when it appeared, one no other visible channel uses."""
        fixed = channel_color(channel)
        if fixed is not None:
            return fixed
        index = self._joint_colors.get(channel)
        if index is None:
            used = {self._palette_index(c) for c in self._visible if c != channel}
            index = next((i for i in range(len(PALETTE)) if i not in used), len(self._joint_colors) % len(PALETTE))
            if channel in self._visible:
                self._joint_colors[channel] = index
        rgb, square, circle = PALETTE[index]
        return rgb, circle if "right" in channel_tail(channel).split("_") else square

    def _palette_index(self, channel: str) -> int:
        fixed = channel_color(channel)
        if fixed is not None:
            return next(i for i, entry in enumerate(PALETTE) if entry[0] == fixed[0])
        return self._joint_colors.get(channel, -1)

    def _release_colors(self) -> None:
        """Free the colours of hidden joints; a joint clashing with a fixed-colour channel or an
        earlier joint is given another free colour (fixed colours win)."""
        taken = {self._palette_index(c) for c in self._visible if channel_color(c) is not None}
        for ch in list(self._joint_colors):
            index = self._joint_colors[ch]
            if ch not in self._visible or index in taken:
                del self._joint_colors[ch]
            else:
                taken.add(index)
        for ch in self._visible:
            self.color_of(ch)

    # ================================================================== internals: state
    def _sample_obj(self) -> GaitSample | None:
        style = self.session.style
        return style.sample(self._sample) if style is not None else None

    def _curve(self, channel: str) -> HermiteCurve | None:
        sample = self._sample_obj()
        return sample.curve(channel) if sample is not None else None

    def _knot_exists(self, ref: KnotRef) -> bool:
        curve = self._curve(ref.channel)
        return curve is not None and 0 <= ref.index < curve.n_knots

    def _pick_initial_channel(self) -> None:
        sample = self._sample_obj()
        if sample is not None and sample.curve(self._active) is None:
            for ch in self._channels:
                if sample.curve(ch) is not None:
                    self._active = ch
                    self._visible = [ch]
                    break

    def _set_active_locked(self, channel: str) -> None:
        if channel not in self._channels:
            raise ValueError(f"unknown channel {channel!r}")
        switched = channel_interval(channel) != channel_interval(self._active)
        self._active = channel
        if switched:
            self._visible = [c for c in self._visible if channel_interval(c) == channel_interval(channel)]
            self._selection.clear()
        if channel not in self._visible:
            self._visible.append(channel)
        self._selection = [r for r in self._selection if r.channel in self._visible]
        if switched:
            self._frame_all_locked()

    def _show_channel_locked(self, channel: str, visible: bool) -> None:
        if visible:
            if channel_interval(channel) != self.interval or channel not in self._visible:
                self._set_active_locked(channel)
                self._norm.pop(channel, None)
        else:
            if channel in self._visible and len(self._visible) > 1:
                self._visible.remove(channel)
                self._selection = [r for r in self._selection if r.channel != channel]
                if self._active == channel:
                    self._active = self._visible[-1]

    def _to_view(self, channel: str, value: float) -> float:
        c, s = self._norm_of(channel)
        return (value - c) / s

    def _from_view(self, channel: str, value: float) -> float:
        c, s = self._norm_of(channel)
        return value * s + c

    def _norm_of(self, channel: str) -> tuple[float, float]:
        if not self.normalize_checkbox.value:
            return (0.0, 1.0)
        if channel not in self._norm:
            lo, hi = self._channel_range(channel)
            half = max((hi - lo) / 2, 1e-3)
            self._norm[channel] = ((lo + hi) / 2, half)
        return self._norm[channel]

    def _channel_range(self, channel: str) -> tuple[float, float]:
        curve = self._curve(channel)
        if curve is None or curve.n_knots == 0:
            v = channel_default(channel, self.ctx)
            return (v, v)
        return curve.value_range()

    def _frame_all_locked(self) -> None:
        sample = self._sample_obj()
        if sample is None:
            return
        d = interval_duration(sample, self.interval)
        if self.interval == "cycle":
            t_lo, t_hi = ((-0.5 * d, 1.5 * d) if self.cyclic_checkbox.value else (-0.04 * d, 1.04 * d))
        else:
            t_lo, t_hi = -0.05 * d, 1.05 * d
        self._norm.clear()
        los, his = [], []
        for ch in self._visible:
            lo, hi = self._channel_range(ch)
            los.append(self._to_view(ch, lo))
            his.append(self._to_view(ch, hi))
        lo, hi = (min(los), max(his)) if los else (-1.0, 1.0)
        if self.interval != "cycle":
            lo, hi = min(lo, self._to_view(self._active, 0.0)), max(hi, self._to_view(self._active, 0.0))
        span = hi - lo
        if span < 1e-6:
            pad = max(0.1 * abs(hi), 0.05)
        else:
            pad = 0.12 * span
        self._view = (t_lo, t_hi, lo - pad, hi + pad)
        self._framed_key = (self._sample, self.interval, round(d, 9))

    # ================================================================== internals: applying edits
    @contextlib.contextmanager
    def _quiet(self):
        """Session notifications caused by this thread's own edits don't trigger a redraw."""
        prev = getattr(self._local, "quiet", False)
        self._local.quiet = True
        try:
            yield
        finally:
            self._local.quiet = prev

    def _style_with(self, curves: dict[str, HermiteCurve | None]) -> Style | None:
        style = self.session.style
        if style is None:
            return None
        sample = style.sample(self._sample)
        for ch, curve in curves.items():
            sample = sample.with_curve(ch, curve)
        return style.with_sample(self._sample, sample)

    def _apply(self, curves: dict[str, HermiteCurve | None], label: str, client: Any) -> EditResult:
        style = self._style_with(curves)
        if style is None:
            return self._refuse("no style open", client)
        with self._quiet():
            result = self.session.apply(style, label)
        if not result.ok:
            self._refuse(result.message, client)
            self._redraw()
        else:
            self._status(label)
        self._update_undo_buttons()
        return result

    def _refuse(self, message: str, client: Any = None, notify: bool = True) -> EditResult:
        self._status(message, "error")
        if notify:
            self._notify(message, client)
        return EditResult(False, message)

    def _notify(self, message: str, client: Any) -> None:
        self.notices.append(message)
        clients = [client] if client is not None else list(self.server.get_clients().values())
        for c in clients:
            with contextlib.suppress(Exception):
                c.add_notification("Curve editor", message, color="red", auto_close_seconds=6.0)

    def _status(self, text: str, level: str = "info") -> None:
        icon = {"info": "ℹ️", "warn": "⚠️", "error": "⛔"}.get(level, "")
        self.status = text
        with contextlib.suppress(Exception):
            self.status_md.content = f"{icon} {text}" if text else ""

    def _on_session_change(self, style: Style, reason: str) -> None:
        if self._closed or getattr(self._local, "quiet", False):
            return
        try:
            with self._lock:
                if self._drag is not None:
                    return  # redrawn when the drag ends
                sample = self._sample_obj()
                if sample is not None:
                    key = (self._sample, self.interval, round(interval_duration(sample, self.interval), 9))
                    if key != self._framed_key:
                        self._frame_all_locked()
                self._selection = [r for r in self._selection if self._knot_exists(r)]
                self._redraw()
        except Exception:
            log.exception("curve editor: redraw after %s", reason)

    # ================================================================== internals: drags
    def _plane_point(self, world: Sequence[float], client: Any) -> np.ndarray:
        """Graph-plane (x, z) where the camera ray through ``world`` meets the plane (orthogonal fallback)."""
        R, p = self._root_pose()
        q = R.T @ (np.asarray(world, dtype=float) - p)
        cam = None
        if client is not None:
            with contextlib.suppress(Exception):
                cam = np.asarray(client.camera.position, dtype=float)
        if cam is not None:
            qc = R.T @ (cam - p)
            denom = qc[1] - q[1]
            if abs(denom) > 1e-9:
                s = qc[1] / denom
                if s > 0:
                    hit = qc + s * (q - qc)
                    return np.array([hit[0], hit[2]])
        return np.array([q[0], q[2]])

    def _delta(self, drag: _Drag, event: Any) -> tuple[float, float]:
        """(dt [s], dv [view units]) of the pointer since the drag started.

        The pointer maps to time and value at the scale the view had when the drag began, so the knot
        follows it anywhere on the canvas — past the graph's range, which grows to keep the knot in
        sight (:meth:`_follow_drag_out_of_view`). A knot drag moves along one axis when the pointer went
        mostly one way (:data:`AXIS_LOCK_RATIO`): a vertical drag keeps the knot's time, a horizontal
        one its value.
        """
        pt = self._plane_point(event.end_position, getattr(event, "client", None) or drag.client)
        drag.last_pt = pt
        dx, dz = (float(c) for c in pt - drag.anchor)
        t_lo, t_hi, v_lo, v_hi = drag.view0 or self._view
        dt, dv = dx / self.width_m * (t_hi - t_lo), dz / self.height_m * (v_hi - v_lo)
        if drag.kind == "knot":
            if abs(dz) >= AXIS_LOCK_RATIO * abs(dx):
                dt = 0.0
            elif abs(dx) >= AXIS_LOCK_RATIO * abs(dz):
                dv = 0.0
        return dt, dv

    def _follow_drag_out_of_view(self, drag: _Drag, curves: dict[str, HermiteCurve]) -> bool:
        """Grow the value range when the dragged knot nears its top or bottom (True: the view changed)."""
        if drag.kind != "knot" or drag.ref.channel not in curves:
            return False
        curve = curves[drag.ref.channel]
        if drag.ref.index >= curve.n_knots:
            return False
        v = self._to_view(drag.ref.channel, curve.knots[drag.ref.index].value)
        t_lo, t_hi, v_lo, v_hi = self._view
        span = v_hi - v_lo
        if v > v_hi - DRAG_EDGE * span:
            self._view = (t_lo, t_hi, v_lo, v + DRAG_GROW * span)
        elif v < v_lo + DRAG_EDGE * span:
            self._view = (t_lo, t_hi, v - DRAG_GROW * span, v_hi)
        else:
            return False
        return True

    def _start_knot_drag(self, ref: KnotRef, event: Any) -> None:
        self._end_drag_now()
        sample = self._sample_obj()
        if sample is None or not self._knot_exists(ref):
            return
        if ref not in self._selection:
            self._selection = [ref]
        else:
            self._selection.remove(ref)
            self._selection.append(ref)
        self._active = ref.channel
        moves: dict[str, list[int]] = collections.defaultdict(list)
        for r in self._selection:
            if self._knot_exists(r):
                moves[r.channel].append(r.index)
        base = {ch: sample.curve(ch) for ch in moves}
        client = getattr(event, "client", None)
        label = f"move {sum(map(len, moves.values()))} knot(s) on {', '.join(moves)}"
        self._drag = _Drag("knot", ref, "", self._plane_point(event.start_position, client),
                           UndoGroup(self.session, label, self._quiet), base, dict(moves), client, view0=self._view)
        self._draw_ghost(base)
        self._redraw()

    def _start_handle_drag(self, side: str, event: Any) -> bool:
        self._end_drag_now()
        ref = self.primary
        curve = self._curve(ref.channel) if ref else None
        if curve is None or ref.index >= curve.n_knots or is_pinned(ref.channel, ref.index, curve.n_knots):
            return False
        if side not in handle_points(curve, ref.index):
            return False
        client = getattr(event, "client", None)
        label = f"tangent on {ref.channel}"
        self._drag = _Drag("handle", ref, side, self._plane_point(event.start_position, client),
                           UndoGroup(self.session, label, self._quiet), {ref.channel: curve},
                           {ref.channel: [ref.index]}, client, view0=self._view)
        self._draw_ghost({ref.channel: curve})
        return True

    def _drag_curves(self, drag: _Drag, dt: float, dv_view: float) -> tuple[dict[str, HermiteCurve], list[str]]:
        sample = self._sample_obj()
        notes: list[str] = []
        out: dict[str, HermiteCurve] = {}
        if drag.kind == "knot":
            for ch, idx in drag.moves.items():
                _, s = self._norm_of(ch)
                curve, n = move_knots(ch, drag.base_curves[ch], idx, dt, dv_view * s,
                                      channel_limits(ch, sample, self.ctx))
                out[ch] = curve
                notes += n
        else:
            ch, i = drag.ref.channel, drag.ref.index
            base = drag.base_curves[ch]
            t_h, v_h = handle_points(base, i)[drag.side]
            _, s = self._norm_of(ch)
            slope = slope_from_handle(base, i, drag.side, t_h + dt, v_h + dv_view * s)
            out[ch] = with_handle_slope(base, i, drag.side, slope)
        return out, list(dict.fromkeys(notes))

    def _update_drag(self, event: Any) -> None:
        drag = self._drag
        if drag is None or self.session.style is None:  # no drag, or the style was closed mid-drag
            return
        dt, dv = self._delta(drag, event)
        curves, notes = self._drag_curves(drag, dt, dv)
        drag.last_curves = curves
        if self._follow_drag_out_of_view(drag, curves):
            with self.server.atomic():
                self._draw_frame()
                self._draw_ghost(drag.base_curves)
        if notes:
            self._status("clamped: " + "; ".join(notes), "warn")
        now = time.monotonic()
        if event.phase == "update" and now - drag.last_preview_t >= PREVIEW_PERIOD_S:
            drag.last_preview_t = now
            style = self._style_with(curves)
            if style is not None:
                result = drag.group.preview(style)
                drag.last_error = "" if result.ok else result.message
                if not result.ok:
                    self._status(f"release here and the edit is refused: {result.message}", "error")
                self._update_undo_buttons()
        self._draw_dynamic(curves)

    def _finish_drag(self) -> None:
        drag = self._drag
        self._drag = None
        if drag is None:
            return
        final = self._style_with(drag.last_curves) if drag.last_curves else None
        if final is None:
            drag.group.commit(None)  # the style was closed mid-drag: back to the base (there is no cancel())
            result = EditResult(True, "no change")
        else:
            result = drag.group.commit(final)
        self._draw_ghost(None)
        if not result.ok:
            self._refuse(f"{result.message} — the knot snapped back", drag.client)
        elif drag.last_curves and result.message != "no change":
            if not self.status.startswith("clamped"):
                self._status(drag.group.label)
        self._selection = [r for r in self._selection if self._knot_exists(r)]
        self._update_undo_buttons()
        self._redraw()

    def _end_drag_now(self) -> None:
        """Finish a drag still in progress (e.g. the sample changes mid-drag) with its last state."""
        if self._drag is not None:
            self._finish_drag()

    # ================================================================== internals: paste
    def _merge_knots(self, channel: str, target: HermiteCurve | None, pasted: list[Knot], d: float) -> HermiteCurve:
        periodic = channel_interval(channel) == "cycle"
        if target is None:
            base = [] if periodic else [Knot(0.0, 0.0, mode=TangentMode.FLAT), Knot(d, 0.0, mode=TangentMode.FLAT)]
        else:
            base = list(target.knots)
        lo, hi = pasted[0].t_s, pasted[-1].t_s
        n = len(base)
        kept = [k for i, k in enumerate(base)
                if not (lo - 1e-9 <= k.t_s <= hi + 1e-9) or (is_pinned(channel, i, n)
                                                            and all(abs(p.t_s - k.t_s) > 1e-9 for p in pasted))]
        merged = kept + [p for p in pasted if all(abs(p.t_s - k.t_s) >= MIN_KNOT_GAP_S for k in kept)]
        return HermiteCurve(sorted(merged, key=lambda k: k.t_s), d, periodic)

    # ================================================================== internals: scene
    def _root_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """World rotation and translation of the root frame (composed through its parents)."""
        R = vtf.SO3(np.asarray(self.root_frame.wxyz, dtype=float)).as_matrix()
        p = np.asarray(self.root_frame.position, dtype=float)
        name = self.root
        while "/" in name.strip("/"):
            name = name.rsplit("/", 1)[0]
            parent = self.server.scene.get_handle_by_name(name)
            if parent is None:
                break
            Rp = vtf.SO3(np.asarray(parent.wxyz, dtype=float)).as_matrix()
            R, p = Rp @ R, Rp @ p + np.asarray(parent.position, dtype=float)
        return R, p

    def _build_scene(self) -> None:
        s = self.server.scene
        r = self.root
        W, H = self.width_m, self.height_m
        face = vtf.SO3.from_x_radians(math.pi / 2).wxyz  # image XY plane -> graph XZ plane, facing -y
        s.add_image(f"{r}/backdrop", _solid_image(BACKDROP), W + 0.32, H + 0.3, wxyz=face,
                    position=(W / 2 - 0.1, 0.012, H / 2 - 0.03), cast_shadow=False, receive_shadow=False)
        s.add_image(f"{r}/plot", _solid_image(PLOT_BG), W, H, wxyz=face, position=(W / 2, 0.009, H / 2),
                    cast_shadow=False, receive_shadow=False)
        self._interval_bg = s.add_image(f"{r}/interval", _solid_image(INTERVAL_BG), W, H, wxyz=face,
                                        position=(W / 2, 0.006, H / 2), cast_shadow=False, receive_shadow=False)
        empty = np.zeros((1, 2, 3), dtype=np.float32)
        self._grid = s.add_line_segments(f"{r}/grid", empty, (0, 0, 0), thickness=1.2, thickness_units="screen",
                                         position=(0, 0.003, 0))
        self._extent = s.add_line_segments(f"{r}/extent", empty, EXTENT, thickness=2.2, thickness_units="screen",
                                           position=(0, 0.002, 0))
        self._ghost = s.add_line_segments(f"{r}/ghost", empty, GHOST_COLOR, thickness=2.5,
                                          thickness_units="screen", position=(0, 0.001, 0), visible=False)
        self._curves = s.add_line_segments(f"{r}/curves", empty, (0, 0, 0), thickness=2.8, thickness_units="screen")
        self._tangent_lines = s.add_line_segments(f"{r}/tangent_lines", empty, HANDLE_COLOR, thickness=1.5,
                                                  thickness_units="screen", position=(0, -0.002, 0), visible=False)
        self._playhead_line = s.add_line_segments(f"{r}/playhead", np.array([[[0, 0, 0], [0, 0, H]]], np.float32),
                                                  PLAYHEAD, thickness=2.0, thickness_units="screen",
                                                  position=(0, -0.004, 0), visible=False)
        self._playhead_label = s.add_label(f"{r}/playhead_label", "", position=(0, -0.02, H + 0.005),
                                           anchor="bottom-center", font_screen_scale=0.8, visible=False)
        self._handles: dict[str, Any] = {}
        for side in ("in", "out"):
            h = s.add_icosphere(f"{r}/handle_{side}", radius=0.62 * KNOT_RADIUS_M, color=HANDLE_COLOR,
                                subdivisions=2, cast_shadow=False, receive_shadow=False, visible=False)
            self._register_handle_drag(h, side)
            self._handles[side] = h

    def _register_handle_drag(self, handle: Any, side: str) -> None:
        async def on_drag(event: viser.SceneNodeDragEvent) -> None:  # ordered on the event loop, no blocking
            key = ("handle", side) if event.phase == "update" else None
            self._worker.post(lambda: self._guarded(self.handle_tangent_drag, side, event), key=key)

        handle.on_drag(on_drag)

    def _register_knot_callbacks(self, node: Any, ref: KnotRef) -> None:
        async def on_drag(event: viser.SceneNodeDragEvent) -> None:
            key = ("knot", ref) if event.phase == "update" else None
            self._worker.post(lambda: self._guarded(self.handle_knot_drag, ref, event), key=key)

        async def on_click(event: Any) -> None:
            self._worker.post(lambda: self._guarded(self.handle_knot_click, ref, False))

        async def on_toggle(event: Any) -> None:
            self._worker.post(lambda: self._guarded(self.handle_knot_click, ref, True))

        node.on_drag(on_drag)
        node.on_click(on_click)
        node.on_click(modifier="cmd/ctrl")(on_toggle)

    def _on_rect_select(self, event: Any) -> None:
        self._guarded(self.select_in_screen_rect, event.client.camera, event.screen_min, event.screen_max, False)

    def _on_rect_select_add(self, event: Any) -> None:
        self._guarded(self.select_in_screen_rect, event.client.camera, event.screen_min, event.screen_max, True)

    def _guarded(self, fn: Callable[..., Any], *args: Any) -> Any:
        """Run a callback; an exception is logged, shown, and leaves a consistent editor."""
        try:
            return fn(*args)
        except Exception as exc:
            log.exception("curve editor callback %s", getattr(fn, "__name__", fn))
            with self._lock:
                if self._drag is not None:
                    with contextlib.suppress(Exception):
                        self._drag.group.cancel()
                    self._drag = None
                self._status(f"internal error ({type(exc).__name__}: {exc}); the style is unchanged", "error")
                with contextlib.suppress(Exception):
                    self._draw_ghost(None)
                    self._redraw()
            return None

    # ---------------------------------------------------------------- drawing
    def _extend_view_to_knots(self) -> None:
        """After an edit, grow the value range so every knot of the visible curves stays in view."""
        t_lo, t_hi, v_lo, v_hi = self._view
        vals = [self._to_view(r.channel, self._curve(r.channel).knots[r.index].value)
                for r in self._displayed_knots()]
        if not vals or (min(vals) >= v_lo and max(vals) <= v_hi):
            return
        lo, hi = min(min(vals), v_lo), max(max(vals), v_hi)
        pad = 0.08 * (hi - lo)
        self._view = (t_lo, t_hi, lo - pad if lo < v_lo else v_lo, hi + pad if hi > v_hi else v_hi)

    def _redraw(self) -> None:
        if self.session.style is None:
            self._status("no style open", "warn")
            return
        if self._drag is None:
            self._extend_view_to_knots()
        self._release_colors()
        with self.server.atomic():
            self._draw_frame()
            self._draw_dynamic({})
            self._draw_playhead()
        self._redraw_gui_state()

    def _draw_dynamic(self, override: dict[str, HermiteCurve]) -> None:
        """Curves, knots and handles (``override``: curves being dragged)."""
        with self.server.atomic():
            self._draw_curves(override)
            self._draw_knots(override)
            self._draw_handles(override)

    def _curve_or_override(self, channel: str, override: dict[str, HermiteCurve]) -> HermiteCurve | None:
        return override[channel] if channel in override else self._curve(channel)

    def _polyline(self, channel: str, curve: HermiteCurve | None, ghost: bool = False
                  ) -> tuple[np.ndarray, np.ndarray]:
        """Segments (N,2,3) and per-vertex colours (N,2,3) of one channel clipped to the view."""
        sample = self._sample_obj()
        d = interval_duration(sample, channel_interval(channel))
        periodic = channel_interval(channel) == "cycle"
        t_lo, t_hi, v_lo, v_hi = self._view
        rgb, _ = self.color_of(channel)
        faint = _blend(rgb, INTERVAL_BG, 0.65)
        pieces = []
        ranges = [(-d, 0.0, True), (0.0, d, False), (d, 2 * d, True)] if periodic else [(0.0, d, False)]
        for a, b, outside in ranges:
            a, b = max(a, t_lo), min(b, t_hi)
            if b <= a:
                continue
            n = max(8, int(CURVE_SAMPLES * (b - a) / (t_hi - t_lo)))
            ts = np.linspace(a, b, n)
            if curve is not None and curve.n_knots:
                kt = np.array([k.t_s for k in curve.knots])
                if periodic:
                    kt = np.concatenate([kt - d, kt, kt + d])
                ts = np.unique(np.concatenate([ts, kt[(kt > a) & (kt < b)]]))
            if curve is None or curve.n_knots == 0:
                vs = np.full(ts.shape, channel_default(channel, self.ctx))
                color = faint
            else:
                vs = np.asarray(curve.evaluate(ts), dtype=float)
                color = faint if outside else rgb
            if ghost:
                color = GHOST_COLOR
            c, s = self._norm_of(channel)
            x = (ts - t_lo) / (t_hi - t_lo) * self.width_m
            z = ((vs - c) / s - v_lo) / (v_hi - v_lo) * self.height_m
            p0 = np.stack([x[:-1], np.zeros(len(x) - 1), z[:-1]], axis=1)
            p1 = np.stack([x[1:], np.zeros(len(x) - 1), z[1:]], axis=1)
            keep = ~(((p0[:, 2] < 0) & (p1[:, 2] < 0)) | ((p0[:, 2] > self.height_m) & (p1[:, 2] > self.height_m)))
            seg = np.stack([p0[keep], p1[keep]], axis=1)
            seg[:, :, 2] = np.clip(seg[:, :, 2], 0.0, self.height_m)
            cols = np.empty(seg.shape, dtype=np.uint8)
            cols[:] = _linear_u8(color)
            pieces.append((seg, cols))
        if not pieces:
            return np.zeros((0, 2, 3)), np.zeros((0, 2, 3), dtype=np.uint8)
        return np.concatenate([p[0] for p in pieces]), np.concatenate([p[1] for p in pieces])

    def _setp(self, node: Any, prop: str, value: Any) -> None:
        """Assign a node property only when it changed (each assignment is a websocket message)."""
        key = (id(node), prop)
        if key in self._props and _same(self._props[key], value):
            return
        setattr(node, prop, value)
        self._props[key] = value

    def _set_lines(self, node: Any, segs: list[np.ndarray], cols: list[np.ndarray] | None) -> None:
        pts = np.concatenate(segs).astype(np.float32) if segs else np.zeros((0, 2, 3), np.float32)
        if len(pts) == 0:
            self._setp(node, "visible", False)
            return
        self._setp(node, "points", pts)
        if cols is not None:
            self._setp(node, "colors", np.concatenate(cols))
        self._setp(node, "visible", True)

    def _draw_curves(self, override: dict[str, HermiteCurve]) -> None:
        segs, cols = [], []
        order = [c for c in self._visible if c != self._active] + [self._active]  # active drawn last (on top)
        for ch in order:
            s, c = self._polyline(ch, self._curve_or_override(ch, override))
            segs.append(s)
            cols.append(c)
        self._set_lines(self._curves, segs, cols)

    def _draw_ghost(self, curves: dict[str, HermiteCurve] | None) -> None:
        if not curves:
            self._setp(self._ghost, "visible", False)
            return
        segs, cols = [], []
        for ch, curve in curves.items():
            s, c = self._polyline(ch, curve, ghost=True)
            segs.append(s)
            cols.append(c)
        self._set_lines(self._ghost, segs, cols)

    def _displayed_knots(self, override: dict[str, HermiteCurve] | None = None) -> list[KnotRef]:
        refs = []
        for ch in self._visible:
            curve = self._curve_or_override(ch, override or {})
            if curve is not None:
                refs += [KnotRef(ch, i) for i in range(curve.n_knots)]
        return refs

    def _knot_key(self, ref: KnotRef, pinned: bool) -> str:
        return f"{ref.channel.replace('.', '_')}_{ref.index}_{'pin' if pinned else 'key'}"

    def _draw_knots(self, override: dict[str, HermiteCurve]) -> None:
        wanted: set[str] = set()
        primary = self.primary
        selected = set(self._selection)
        for ch in self._visible:
            curve = self._curve_or_override(ch, override)
            if curve is None:
                continue
            rgb, _ = self.color_of(ch)
            knots = curve.knots
            for i, k in enumerate(knots):
                ref = KnotRef(ch, i)
                pinned = is_pinned(ch, i, len(knots))
                key = self._knot_key(ref, pinned)
                wanted.add(key)
                x, z = self.graph_point(ch, k.t_s, k.value)
                inside = (-1e-6 <= x <= self.width_m + 1e-6 and -1e-6 <= z <= self.height_m + 1e-6
                          or (self._drag is not None and ref.channel in self._drag.moves))
                color = PRIMARY if ref == primary else SELECTED if ref in selected else _blend(rgb, (0, 0, 0), 0.15)
                scale = PRIMARY_SCALE if ref == primary else SELECTED_SCALE if ref in selected else 1.0
                if key not in self._knots.nodes:
                    name = f"{self.root}/knots/{key}"
                    if pinned:
                        node = self.server.scene.add_box(name, color=color, dimensions=(1.5 * KNOT_RADIUS_M,) * 3,
                                                         cast_shadow=False, receive_shadow=False,
                                                         position=(x, 0.0, z))
                    else:
                        node = self.server.scene.add_icosphere(name, radius=KNOT_RADIUS_M, color=color,
                                                               subdivisions=2, cast_shadow=False,
                                                               receive_shadow=False, position=(x, 0.0, z))
                    self._register_knot_callbacks(node, ref)
                    self._knots.nodes[key] = node
                    self._knots.cache[(key, "color")] = color
                    self._knots.cache[(key, "position")] = (x, 0.0, z)
                self._knots.set(key, "position", (x, 0.0, z))
                self._knots.set(key, "color", color)
                self._knots.set(key, "scale", scale)
                self._knots.set(key, "visible", inside)
        for key in [k for k in self._knots.nodes if k not in wanted]:
            if self._drag is not None:  # never remove a node mid-drag (its drag must still end)
                self._knots.set(key, "visible", False)
                continue
            self._knots.remove(key)

    def _draw_handles(self, override: dict[str, HermiteCurve]) -> None:
        ref = self.primary
        curve = self._curve_or_override(ref.channel, override) if ref else None
        shown: dict[str, tuple[float, float]] = {}
        if (curve is not None and ref.index < curve.n_knots and ref.channel in self._visible
                and not is_pinned(ref.channel, ref.index, curve.n_knots)):
            shown = handle_points(curve, ref.index)
        lines = []
        if shown:
            k = curve.knots[ref.index]
            kx, kz = self.graph_point(ref.channel, k.t_s, k.value)
        for side, h in self._handles.items():
            if side in shown:
                hx, hz = self.graph_point(ref.channel, *shown[side])
                self._setp(h, "position", (hx, -0.002, hz))
                self._setp(h, "visible", True)
                lines.append(np.array([[[kx, 0.0, kz], [hx, 0.0, hz]]]))
            elif self._drag is None or self._drag.kind != "handle" or self._drag.side != side:
                self._setp(h, "visible", False)
        self._set_lines(self._tangent_lines, lines, None)

    def _label(self, key: str, text: str, position: tuple[float, float, float], anchor: str,
               scale: float = 0.75) -> None:
        if key not in self._labels.nodes:
            self._labels.nodes[key] = self.server.scene.add_label(
                f"{self.root}/labels/{key}", text, position=position, anchor=anchor, font_screen_scale=scale)
            self._labels.cache[(key, "text")] = text
            self._labels.cache[(key, "position")] = position
        self._labels.set(key, "text", text)
        self._labels.set(key, "position", position)
        self._labels.set(key, "visible", True)

    def _draw_frame(self) -> None:
        sample = self._sample_obj()
        W, H = self.width_m, self.height_m
        t_lo, t_hi, v_lo, v_hi = self._view
        interval = self.interval
        d = interval_duration(sample, interval)
        used: set[str] = set()

        def x_of(t: float) -> float:
            return (t - t_lo) / (t_hi - t_lo) * W

        # interval extent
        x0, x1 = max(0.0, x_of(0.0)), min(W, x_of(d))
        if x1 > x0:
            self._setp(self._interval_bg, "render_width", x1 - x0)
            self._setp(self._interval_bg, "position", ((x0 + x1) / 2, 0.006, H / 2))
            self._setp(self._interval_bg, "visible", True)
        else:
            self._setp(self._interval_bg, "visible", False)
        grid, gcols, extent = [], [], []
        t_ticks, t_dec = nice_ticks(t_lo, t_hi, 8)
        for i, t in enumerate(t_ticks):
            x = x_of(t)
            grid.append([[x, 0, 0], [x, 0, H]])
            gcols.append(GRID)
            key = f"t{i}"
            self._label(key, f"{t:.{t_dec}f}", (x, -0.02, -0.012), "top-center")
            used.add(key)
        ch = self._active
        c, s = self._norm_of(ch)
        native_lo, native_hi = v_lo * s + c, v_hi * s + c
        v_ticks, v_dec = nice_ticks(native_lo, native_hi, 6)
        for i, v in enumerate(v_ticks):
            z = ((v - c) / s - v_lo) / (v_hi - v_lo) * H
            grid.append([[0, 0, z], [W, 0, z]])
            gcols.append(GRID_ZERO if abs(v) < 1e-12 else GRID)
            key = f"v{i}"
            self._label(key, f"{v:.{v_dec}f}", (-0.015, -0.02, z), "center-right")
            used.add(key)
        for t in (0.0, d):
            if t_lo <= t <= t_hi:
                extent.append([[x_of(t), 0, 0], [x_of(t), 0, H]])
        border = [[[0, 0, 0], [W, 0, 0]], [[W, 0, 0], [W, 0, H]], [[W, 0, H], [0, 0, H]], [[0, 0, H], [0, 0, 0]]]
        pts = np.array(grid + border, dtype=np.float32)
        cols = _linear_u8(np.array([[g, g] for g in gcols] + [[GRID_ZERO, GRID_ZERO]] * 4))
        self._setp(self._grid, "points", pts)
        self._setp(self._grid, "colors", cols)
        self._set_lines(self._extent, [np.array(extent, dtype=np.float32).reshape(-1, 2, 3)], None)
        names = {"left": "left swing · t from left liftoff", "right": "right swing · t from right liftoff",
                 "cycle": "cycle · t from left liftoff"}
        unit = channel_unit(ch)
        norm = " (normalised view)" if self.normalize_checkbox.value and len(self._visible) > 1 else ""
        # one label for the title and the value axis: two labels at the graph's corners overlap when the
        # graph is small on screen (labels keep their pixel size)
        self._label("title", f"{self._sample} · {names[interval]} · {d:.3f} s — {ch} [{unit}]{norm}",
                    (0.0, -0.02, H + 0.045), "bottom-left", 0.85)
        self._label("taxis", "t [s]", (W + 0.015, -0.02, -0.012), "top-left", 0.8)
        used |= {"title", "taxis"}
        for key in self._labels.nodes:
            if key not in used:
                self._labels.set(key, "visible", False)

    def _draw_playhead(self) -> None:
        t = self._playhead
        t_lo, t_hi, _, _ = self._view
        if t is None or not t_lo <= t <= t_hi or self.session.style is None:
            self._setp(self._playhead_line, "visible", False)
            self._setp(self._playhead_label, "visible", False)
            return
        x = (t - t_lo) / (t_hi - t_lo) * self.width_m
        with self.server.atomic():
            self._setp(self._playhead_line, "position", (x, -0.004, 0.0))
            self._setp(self._playhead_line, "visible", True)
            self._setp(self._playhead_label, "position", (x, -0.02, self.height_m + 0.005))
            self._setp(self._playhead_label, "text", f"{t:.3f} s")
            self._setp(self._playhead_label, "visible", True)

    # ================================================================== GUI
    def _gui_cb(self, fn: Callable[[Any], Any]) -> Callable[[Any], None]:
        """A GUI callback: guarded, ignored while the editor itself syncs widget values."""
        def callback(event: Any) -> None:
            with self._lock:  # _sync runs under the lock: a user event waits, a synced echo sees the flag
                if self._syncing:
                    return
                self._guarded(fn, event)
        return callback

    def _typed(self, fn: Callable[[Any], Any]) -> Callable[[Any], None]:
        """A GUI callback for a typed field: runs :data:`TYPING_PAUSE_S` after the last keystroke."""
        callback = self._gui_cb(fn)
        timer: list[threading.Timer | None] = [None]

        def on_update(event: Any) -> None:
            if self._syncing:
                return
            if timer[0] is not None:
                timer[0].cancel()
            if TYPING_PAUSE_S <= 0:
                callback(event)
                return
            timer[0] = threading.Timer(TYPING_PAUSE_S, callback, args=(event,))
            timer[0].daemon = True
            timer[0].start()

        return on_update

    def _sync(self, handle: Any, value: Any) -> None:
        """Set a widget value from the editor without running its edit callback."""
        prev = self._syncing
        self._syncing = True
        try:
            handle.value = value
        finally:
            self._syncing = prev

    def _build_gui(self) -> None:
        gui = self.server.gui
        self.status_md = gui.add_markdown("")
        self.sample_dropdown = gui.add_dropdown("Sample", options=tuple(SAMPLE_NAMES), initial_value=self._sample,
                                                hint="the sample edited here is the one Edit mode walks "
                                                     "(the same as in the Sample tab)")
        self.channel_dropdown = gui.add_dropdown("Edit channel", options=tuple(self._channels),
                                                 initial_value=self._active,
                                                 hint="The channel knots are added to and pasted onto")
        self.legend_md = gui.add_markdown("")
        self.channel_checkboxes: dict[str, Any] = {}
        groups = (("Left foot (left swing)", list(swing_channels("left"))),
                  ("Right foot (right swing)", list(swing_channels("right"))),
                  ("Pelvis (cycle)", list(PELVIS_CURVES)),
                  ("Upper body (cycle)", [f"joints.{j}" for j in self.ctx.upper_joints]))
        with gui.add_folder("Channels", expand_by_default=False):
            self.normalize_checkbox = gui.add_checkbox("Normalise view", False,
                                                       hint="Scale each visible curve to the view (mixed units)")
            self.cyclic_checkbox = gui.add_checkbox("Cyclic view", True,
                                                    hint="Show the neighbouring periods of cycle curves (faint)")
            for title, channels in groups:
                with gui.add_folder(title, expand_by_default=title.startswith("Left")):
                    for ch in channels:
                        cb = gui.add_checkbox(self._channel_label(ch), ch in self._visible)
                        cb.on_update(self._gui_cb(lambda e, ch=ch: self._on_checkbox(ch, e.target.value)))
                        self.channel_checkboxes[ch] = cb
        with gui.add_folder("Knot"):
            self.time_input = gui.add_number("Time (s)", 0.0, step=0.001, disabled=True)
            self.value_input = gui.add_number("Value", 0.0, step=0.001, disabled=True)
            self.tangent_dropdown = gui.add_dropdown("Tangents", options=(*TANGENT_LABELS, MIXED),
                                                     initial_value="auto-clamped", disabled=True)
            self.add_button = gui.add_button("Add knot at playhead", icon=viser.Icon.PLUS)
            self.delete_button = gui.add_button("Delete knots", icon=viser.Icon.TRASH,
                                                hint="Delete / Backspace; pinned swing boundary knots stay")
            self.select_all_button = gui.add_button("Select all keys", icon=viser.Icon.SELECT_ALL,
                                                    hint="Click a knot to select it, Ctrl+click to toggle, "
                                                         "Shift+drag on the canvas to box-select")
            self.deselect_button = gui.add_button("Deselect", icon=viser.Icon.DESELECT)
        with gui.add_folder("Copy / paste", expand_by_default=False):
            self.copy_button = gui.add_button("Copy", icon=viser.Icon.COPY,
                                              hint="Selected knots of the edited channel, or its whole curve")
            self.paste_button = gui.add_button("Paste", icon=viser.Icon.CLIPBOARD,
                                               hint="Onto the edited channel of this sample")
            self.paste_other_button = gui.add_button("Paste to other side", icon=viser.Icon.ARROWS_LEFT_RIGHT,
                                                     hint="left ↔ right counterpart of the copied channel")
            self.mirror_checkbox = gui.add_checkbox("Mirror lateral (y, yaw, roll)", True)
            self.half_cycle_checkbox = gui.add_checkbox("Other side ½ cycle later", True,
                                                        hint="Cycle curves (arms) pasted to the other side")
            self.clipboard_md = gui.add_markdown("")
        with gui.add_folder("View"):
            self.frame_all_button = gui.add_button("Frame all", icon=viser.Icon.MAXIMIZE)
            self.frame_selected_button = gui.add_button("Frame selected", icon=viser.Icon.FOCUS_2)
            self.look_button = gui.add_button("Camera to graph", icon=viser.Icon.CAMERA)
        self.undo_button = gui.add_button("Undo", icon=viser.Icon.ARROW_BACK_UP, disabled=True,
                                          hint="Ctrl+Z")
        self.redo_button = gui.add_button("Redo", icon=viser.Icon.ARROW_FORWARD_UP, disabled=True,
                                          hint="Ctrl+Shift+Z / Ctrl+Y")
        self.keys_html = gui.add_html(self.keyboard_snippet())

        self.sample_dropdown.on_update(self._gui_cb(lambda e: self._pick_sample(e.target.value)))
        self.channel_dropdown.on_update(self._gui_cb(lambda e: self.set_active_channel(e.target.value)))
        self.normalize_checkbox.on_update(self._gui_cb(lambda e: self.frame_all()))
        self.cyclic_checkbox.on_update(self._gui_cb(lambda e: self.frame_all()))
        # Typed numbers apply when the typing pauses, not on every keystroke: each applied edit is
        # validated, autosaved, sent to the engine and redrawn (under software WebGL the browser
        # then lagged seconds behind the keys).
        self.time_input.on_update(self._typed(lambda e: self.set_knot_values(t_s=e.target.value, client=e.client)))
        self.value_input.on_update(self._typed(lambda e: self.set_knot_values(value=e.target.value,
                                                                             client=e.client)))
        self.tangent_dropdown.on_update(self._gui_cb(self._on_tangent_dropdown))
        self.add_button.on_click(self._gui_cb(lambda e: self.add_knot_at_playhead(e.client)))
        self.delete_button.on_click(self._gui_cb(lambda e: self.delete_selected(e.client)))
        self.select_all_button.on_click(self._gui_cb(lambda e: self.select_all()))
        self.deselect_button.on_click(self._gui_cb(lambda e: self.clear_selection()))
        self.copy_button.on_click(self._gui_cb(lambda e: self.copy()))
        self.paste_button.on_click(self._gui_cb(lambda e: self.paste(False, client=e.client)))
        self.paste_other_button.on_click(self._gui_cb(lambda e: self.paste(True, client=e.client)))
        self.frame_all_button.on_click(self._gui_cb(lambda e: self.frame_all()))
        self.frame_selected_button.on_click(self._gui_cb(lambda e: self.frame_selected()))
        self.look_button.on_click(self._gui_cb(lambda e: e.client is not None and self.look_at_graph(e.client)))
        self.undo_button.on_click(self._gui_cb(lambda e: self.undo(e.client)))
        self.redo_button.on_click(self._gui_cb(lambda e: self.redo(e.client)))

    def keyboard_snippet(self) -> str:
        """HTML whose ``<img onerror>`` installs the Ctrl+Z / Ctrl+Shift+Z / Ctrl+Y / Delete listener.

        Buttons are found by their DOM id (viser renders ``<button id=uuid>``); keys typed in
        text fields are left alone.
        """
        ids = {"undo": self.undo_button._impl.uuid, "redo": self.redo_button._impl.uuid,
               "delete": self.delete_button._impl.uuid}
        script = _KEYS_SCRIPT
        for k, v in ids.items():
            script = script.replace("{" + k + "}", v)
        return (f'<img src="data:," alt="" style="display:none" onerror="{script}">'
                '<small style="opacity:.6">Keys: Ctrl+Z undo · Ctrl+Shift+Z / Ctrl+Y redo · Delete knots · '
                'Shift+drag box-select</small>')

    def _channel_label(self, channel: str) -> str:
        _, emoji = self.color_of(channel) if channel in self._visible or channel_color(channel) else ((0, 0, 0), "⬜")
        name = channel_tail(channel)
        curve = self._curve(channel) if self.session.style is not None else None
        count = f" · {curve.n_knots} keys" if curve is not None else " · —"
        return f"{emoji} {name}{count}"

    def _pick_sample(self, sample: str) -> None:
        self.set_sample(sample)
        if self.on_sample_picked is not None:
            self.on_sample_picked(sample)

    def _on_checkbox(self, channel: str, value: bool) -> None:
        self.show_channel(channel, value)

    def _on_tangent_dropdown(self, event: Any) -> None:
        if event.target.value not in TANGENT_LABELS:
            return
        mode = TANGENT_LABELS[event.target.value]
        with self._lock:
            ref = self.primary
            curve = self._curve(ref.channel) if ref else None
            if curve is None or ref.index >= curve.n_knots:
                return
            if all(self._knot_exists(r) and self._curve(r.channel).knots[r.index].mode is mode
                   for r in self._selection):
                return
            self.set_tangent_mode(mode, event.client)

    def _update_undo_buttons(self) -> None:
        with contextlib.suppress(Exception):
            self.undo_button.disabled = not self.session.can_undo
            self.redo_button.disabled = not self.session.can_redo

    def _redraw_gui_state(self) -> None:
        """Widgets that mirror the state: channel list, legend, knot fields, clipboard, undo."""
        self._sync(self.sample_dropdown, self._sample)
        self._sync(self.channel_dropdown, self._active)
        for ch, cb in self.channel_checkboxes.items():
            self._sync(cb, ch in self._visible)
            label = self._channel_label(ch)
            if cb.label != label:
                cb.label = label
        legend = []
        for ch in self._visible:
            rgb, _ = self.color_of(ch)
            swatch = (f'<span style="display:inline-block;width:1.6em;height:.5em;border-radius:2px;'
                      f'background:rgb{tuple(rgb)};margin-right:.35em"></span>')
            name = f"<b>{ch}</b>" if ch == self._active else ch
            legend.append(f"{swatch}{name}")
        text = "<br>".join(legend)
        if self.legend_md.content != text:
            self.legend_md.content = text
        ref = self.primary
        curve = self._curve(ref.channel) if ref else None
        if curve is not None and ref.index < curve.n_knots:
            k = curve.knots[ref.index]
            pinned = is_pinned(ref.channel, ref.index, curve.n_knots)
            self._sync(self.time_input, round(k.t_s, 6))
            self._sync(self.value_input, round(k.value, 6))
            modes = {self._curve(r.channel).knots[r.index].mode for r in self._selection if self._knot_exists(r)}
            self._sync(self.tangent_dropdown, MODE_LABEL[k.mode] if len(modes) <= 1 else MIXED)
            self.time_input.disabled = pinned
            self.value_input.disabled = pinned and not ref.channel.endswith("_pitch")
            self.tangent_dropdown.disabled = pinned and len(self._selection) == 1
        else:  # nothing selected (e.g. an empty channel): no stale values of another knot
            self._sync(self.time_input, 0.0)
            self._sync(self.value_input, 0.0)
            self.time_input.disabled = self.value_input.disabled = self.tangent_dropdown.disabled = True
        clip = self._clipboard
        clip_text = (f"Clipboard: {'curve' if clip.whole else f'{len(clip.knots)} knot(s)'} of `{clip.channel}` "
                     f"({clip.sample})") if clip else "Clipboard: empty"
        if self.clipboard_md.content != clip_text:
            self.clipboard_md.content = clip_text
        self._update_undo_buttons()


__all__ = [
    "CurveEditor",
    "Clipboard",
    "KnotRef",
    "UndoGroup",
    "all_channels",
    "channel_color",
    "channel_default",
    "channel_interval",
    "channel_limits",
    "handle_points",
    "interval_duration",
    "is_pinned",
    "mirror_sign",
    "move_knots",
    "nice_ticks",
    "opposite_channel",
    "project_to_screen",
    "slope_from_handle",
    "with_handle_slope",
]
