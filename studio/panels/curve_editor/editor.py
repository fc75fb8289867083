"""The curve editor panel: its state, its public API (selection, knot edits, clipboard, undo) and applying edits."""

from __future__ import annotations

import collections
import contextlib
import logging
import math
import threading
from typing import (
    Any,
    Callable,
    Iterable,
    Mapping,
    Iterator,
)

import viser

from engine.gait.curve_editing import (
    Clipboard,
    KnotRef,
    all_channels,
    channel_default,
    channel_interval,
    channel_limits,
    interval_duration,
    is_pinned,
    merge_knots,
    move_knots,
    opposite_channel,
    paste_knots,
)
from engine.gait.curves import HermiteCurve, Knot, TangentMode
from engine.gait.style import GaitSample, Style
from engine.gait.velocity_sampler import SAMPLE_NAMES
from studio.style_session import EditResult, StyleSession
from studio.panels.curve_editor.appearance import NodePool
from studio.panels.curve_editor.graph_view import GraphView
from studio.panels.curve_editor.interaction import Drag, DragInteraction, SerialWorker
from studio.panels.curve_editor.widgets import MODE_LABEL, EditorWidgets


log = logging.getLogger(__name__)


class CurveEditor(GraphView, DragInteraction, EditorWidgets):
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
        self._worker = SerialWorker("curve-editor")
        self._sample = SAMPLE_NAMES[0]
        self._channels = all_channels(self.ctx)
        self._active = "left_foot.z"
        self._visible: list[str] = [self._active]
        self._selection: list[KnotRef] = []
        self._view = (0.0, 1.0, -1.0, 1.0)  # t_lo, t_hi, v_lo, v_hi (view units)
        self._norm: dict[str, tuple[float, float]] = {}  # channel -> (centre, half span) when normalising
        self._framed_key: tuple | None = None
        self._playhead: float | None = None
        self._drag: Drag | None = None
        self._closed = False
        self._clipboard: Clipboard | None = None
        self.status = ""
        self.notices: list[str] = []
        self._knots = NodePool()
        self._labels = NodePool()
        self._props: dict[tuple[int, str], Any] = {}
        self._joint_colors: dict[str, int] = {}
        self._syncing = False
        #: called when the animator picks a sample in this panel's Sample menu (the app makes it the one
        #: selected everywhere: the Sample tab, and the sample Edit mode walks)
        self.on_sample_picked: Callable[[str], None] | None = None
        #: run before the camera is pointed at the graph (the app brings the graph beside the robot)
        self.before_look_at_graph: Callable[[Any], None] | None = None
        #: (client, position, look_at, up): points a browser's camera (None: set it directly)
        self.place_camera: Callable[[Any, Any, Any, Any], None] | None = None

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
                if curve is None:
                    continue
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
            if sample is None or ref is None or curve is None or ref.index >= curve.n_knots:
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
            pasted = paste_knots(clip, target, d, mirror, half_cycle)
            try:
                if clip.whole:
                    curve = HermiteCurve(pasted, d, clip.periodic)
                else:
                    curve = merge_knots(target, sample.curve(target), pasted, d)
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

    def _sample_obj(self) -> GaitSample | None:
        style = self.session.style
        return style.sample(self._sample) if style is not None else None

    def _curve(self, channel: str) -> HermiteCurve | None:
        sample = self._sample_obj()
        return sample.curve(channel) if sample is not None else None

    def _knot(self, ref: KnotRef) -> Knot:
        """The knot a reference names (it must exist: see :meth:`_knot_exists`)."""
        curve = self._curve(ref.channel)
        if curve is None:
            raise KeyError(f"{ref.channel} has no curve")
        return curve.knots[ref.index]

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

    @contextlib.contextmanager
    def _quiet(self) -> Iterator[None]:
        """Session notifications caused by this thread's own edits don't trigger a redraw."""
        prev = getattr(self._local, "quiet", False)
        self._local.quiet = True
        try:
            yield
        finally:
            self._local.quiet = prev

    def _style_with(self, curves: Mapping[str, HermiteCurve | None]) -> Style | None:
        style = self.session.style
        if style is None:
            return None
        sample = style.sample(self._sample)
        for ch, curve in curves.items():
            sample = sample.with_curve(ch, curve)
        return style.with_sample(self._sample, sample)

    def _apply(self, curves: Mapping[str, HermiteCurve | None], label: str, client: Any) -> EditResult:
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
