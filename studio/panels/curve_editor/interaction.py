"""Pointer interaction with the graph: knot and handle drags, clicks, rectangle selection, undo grouping."""

from __future__ import annotations

import collections
import contextlib
import logging
import threading
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np
import viser

from engine.gait.curve_editing import (
    KnotRef,
    channel_limits,
    handle_points,
    is_pinned,
    move_knots,
    slope_from_handle,
    with_handle_slope,
)
from engine.gait.curves import HermiteCurve
from engine.gait.style import Style
from studio.style_session import EditResult, StyleSession
from studio.panels.curve_editor.state import EditorBase
from studio.panels.curve_editor.appearance import project_to_screen


log = logging.getLogger(__name__)

PREVIEW_PERIOD_S = 0.1  # throttled session.apply while dragging (the engine sees edits at ~10 Hz)
AXIS_LOCK_RATIO = 4.0  # a knot drag this much more vertical than horizontal (~14°) keeps its time (and vice versa)
DRAG_EDGE = 0.0  # a dragged knot this close (fraction of the range) to the view's edge, or beyond it, …
DRAG_GROW = 0.25  # … grows the value range by this fraction beyond it, so the drag goes on past the view


class UndoGroup:
    """Several ``session.apply`` calls that end up as ONE undo entry.

    Live previews and the final edit share the session's ``merge_key``: the engine follows
    every preview, and undo returns to the style before the drag.
    """

    def __init__(self, session: StyleSession, label: str, quiet: Callable[[], contextlib.AbstractContextManager]):
        if session.style is None:
            raise ValueError("no style open")
        self.session = session
        self.label = label
        self.base: Style = session.style
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

    def cancel(self) -> EditResult:
        """Abandon the group: back to the style before it (a drag cut short by a closed style or an error)."""
        return self.commit(None)

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


class SerialWorker:
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


@dataclass
class Drag:
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
    anchor_screen: np.ndarray | None = None  # where the press was on the canvas (OpenCV 0..1), for the axis lock
    aspect: float = 1.0  # the canvas' width ÷ height when the drag began


def _screen_point(event: Any) -> np.ndarray | None:
    """The press on the canvas (OpenCV 0..1) of a drag's "start" event, None when the event has none."""
    pos = getattr(event, "start_screen_pos", None)
    return None if pos is None else np.asarray(pos, dtype=float)


def _canvas_aspect(client: Any) -> float:
    """The canvas' width ÷ height as the client reports it (1 when it cannot say)."""
    with contextlib.suppress(Exception):
        aspect = float(client.camera.aspect)
        if np.isfinite(aspect) and aspect > 0:
            return aspect
    return 1.0


class DragInteraction(EditorBase):
    """Pointer input on the graph: knot and tangent-handle drags (throttled previews, one undo entry),
    clicks, rectangle selection."""

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

    def handle_knot_drag(self, ref: KnotRef, event: Any) -> None:
        """Knot drag lifecycle: ``event`` has phase, start_position, end_position (world) and client."""
        self._drag_lifecycle(event, lambda d: d.kind == "knot" and d.ref == ref,
                             lambda: self._start_knot_drag(ref, event))

    def handle_tangent_drag(self, side: str, event: Any) -> None:
        """Tangent handle drag of the primary knot (``side`` "in" / "out")."""
        self._drag_lifecycle(event, lambda d: d.kind == "handle" and d.side == side,
                             lambda: self._start_handle_drag(side, event))

    def _drag_lifecycle(self, event: Any, continues: Callable[[Any], bool], start: Callable[[], bool]) -> None:
        """One drag event: a "start" (or a move/end of a drag this one does not ``continues``) starts it, unless
        ``start`` refuses; moves update it; "end" finishes it (an "end" with no drag at all is ignored)."""
        with self._lock:
            phase = event.phase
            drag = self._drag
            if phase == "start" or drag is None or not continues(drag):
                if phase == "end" and drag is None:
                    return
                if not start():
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

    def _delta(self, drag: Drag, event: Any) -> tuple[float, float]:
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
            across, up = self._pointer_motion(drag, event, dx, dz)
            if abs(up) >= AXIS_LOCK_RATIO * abs(across):
                dt = 0.0
            elif abs(across) >= AXIS_LOCK_RATIO * abs(up):
                dv = 0.0
        return dt, dv

    @staticmethod
    def _pointer_motion(drag: Drag, event: Any, dx: float, dz: float) -> tuple[float, float]:
        """(sideways, vertical) pointer motion that decides the axis lock: on the canvas, as the user moved
        the mouse (in canvas heights), when the event says where the pointer is; else on the graph plane.

        The screen is what the user sees and aims along: the graph-plane point is re-projected with the
        studio's copy of the camera, which lags the browser's while the camera follows a walking robot, and
        a graph seen at an angle tilts a straight-up drag by several degrees on the plane."""
        end = getattr(event, "end_screen_pos", None)
        if drag.anchor_screen is None or end is None:
            return dx, dz
        d = np.asarray(end, dtype=float) - drag.anchor_screen
        return float(d[0]) * drag.aspect, -float(d[1])

    def _follow_drag_out_of_view(self, drag: Drag, curves: dict[str, HermiteCurve]) -> bool:
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

    def _start_knot_drag(self, ref: KnotRef, event: Any) -> bool:
        self._end_drag_now()
        sample = self._sample_obj()
        if sample is None or not self._knot_exists(ref):
            return False
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
        base = {ch: curve for ch in moves if (curve := sample.curve(ch)) is not None}
        client = getattr(event, "client", None)
        label = f"move {sum(map(len, moves.values()))} knot(s) on {', '.join(moves)}"
        self._drag = Drag("knot", ref, "", self._plane_point(event.start_position, client),
                           UndoGroup(self.session, label, self._quiet), base, dict(moves), client, view0=self._view,
                           anchor_screen=_screen_point(event), aspect=_canvas_aspect(client))
        self._draw_ghost(base)
        self._redraw()
        return True

    def _start_handle_drag(self, side: str, event: Any) -> bool:
        self._end_drag_now()
        ref = self.primary
        curve = self._curve(ref.channel) if ref else None
        if ref is None or curve is None or ref.index >= curve.n_knots or is_pinned(ref.channel, ref.index, curve.n_knots):
            return False
        if side not in handle_points(curve, ref.index):
            return False
        client = getattr(event, "client", None)
        label = f"tangent on {ref.channel}"
        self._drag = Drag("handle", ref, side, self._plane_point(event.start_position, client),
                           UndoGroup(self.session, label, self._quiet), {ref.channel: curve},
                           {ref.channel: [ref.index]}, client, view0=self._view)
        self._draw_ghost({ref.channel: curve})
        return True

    def _drag_curves(self, drag: Drag, dt: float, dv_view: float) -> tuple[dict[str, HermiteCurve], list[str]]:
        sample = self._sample_obj()
        notes: list[str] = []
        out: dict[str, HermiteCurve] = {}
        if sample is None:
            return out, ["no style open"]
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
