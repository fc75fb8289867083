"""The graph plane in the 3D scene: drawing and the mapping between graph, world and screen."""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
import viser.transforms as vtf

from engine.gait.curve_editing import (
    KnotRef,
    channel_default,
    channel_interval,
    channel_tail,
    channel_unit,
    handle_points,
    interval_duration,
    is_pinned,
)
from engine.gait.curves import HermiteCurve
from studio.panels.curve_editor.state import EditorBase
from studio.panels.curve_editor.appearance import (
    CURVE_SAMPLES,
    _same,
    BACKDROP,
    EXTENT,
    GHOST_COLOR,
    GRID,
    GRID_ZERO,
    HANDLE_COLOR,
    INTERVAL_BG,
    KNOT_RADIUS_M,
    PALETTE,
    PLAYHEAD,
    PLOT_BG,
    PRIMARY,
    PRIMARY_SCALE,
    SELECTED,
    SELECTED_SCALE,
    _blend,
    _linear_u8,
    _solid_image,
    channel_color,
    nice_ticks,
)


LabelAnchor = Literal["top-left", "top-center", "top-right", "center-left", "center-center", "center-right",
                      "bottom-left", "bottom-center", "bottom-right"]


class GraphView(EditorBase):
    """The graph plane in the 3D scene: frame, grid, curves, knots, handles, playhead, and the camera on it."""

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
                k = self._knot(r)
                ts.append(k.t_s)
                vs.append(self._to_view(r.channel, k.value))
            pad_t = max(0.15 * (max(ts) - min(ts)), 0.12 * d)
            span_v = max(vs) - min(vs)
            pad_v = 0.2 * span_v if span_v > 0 else 0.1 * (self._view[3] - self._view[2])
            pad_v = max(pad_v, 1e-3)
            self._view = (min(ts) - pad_t, max(ts) + pad_t, min(vs) - pad_v, max(vs) + pad_v)
            self._redraw()

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
        k = self._knot(ref)
        return self.world_position(ref.channel, k.t_s, k.value)

    def handle_world_position(self, side: str) -> np.ndarray | None:
        """World position of the primary knot's ``side`` tangent handle (None when not shown)."""
        ref = self.primary
        curve = self._curve(ref.channel) if ref else None
        if ref is None or curve is None or is_pinned(ref.channel, ref.index, curve.n_knots):
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
        default: viser's medium control panel, 330 px, on canvases wider than 800 px). The app's
        :attr:`before_look_at_graph` hook runs first; :attr:`place_camera`, when set, points the camera (the app's
        follow camera, so following goes on from the graph)."""
        if self.before_look_at_graph is not None:
            self.before_look_at_graph(client)
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
        if self.place_camera is not None:
            self.place_camera(client, position, look_at, up)
            return
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

    def _extend_view_to_knots(self) -> None:
        """After an edit, grow the value range so every knot of the visible curves stays in view."""
        t_lo, t_hi, v_lo, v_hi = self._view
        vals = [self._to_view(r.channel, self._knot(r).value)
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
        if sample is None:
            empty = np.zeros((0, 2, 3))
            return empty, empty.copy()
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
                    node: Any
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
        if (ref is not None and curve is not None and ref.index < curve.n_knots and ref.channel in self._visible
                and not is_pinned(ref.channel, ref.index, curve.n_knots)):
            shown = handle_points(curve, ref.index)
        lines = []
        kx = kz = 0.0
        if ref is not None and curve is not None and shown:
            k = curve.knots[ref.index]
            kx, kz = self.graph_point(ref.channel, k.t_s, k.value)
        for side, h in self._handles.items():
            if ref is not None and side in shown:
                hx, hz = self.graph_point(ref.channel, *shown[side])
                self._setp(h, "position", (hx, -0.002, hz))
                self._setp(h, "visible", True)
                lines.append(np.array([[[kx, 0.0, kz], [hx, 0.0, hz]]]))
            elif self._drag is None or self._drag.kind != "handle" or self._drag.side != side:
                self._setp(h, "visible", False)
        self._set_lines(self._tangent_lines, lines, None)

    def _label(self, key: str, text: str, position: tuple[float, float, float], anchor: LabelAnchor,
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
        if sample is None:
            return
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
