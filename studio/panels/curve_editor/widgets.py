"""The curve editor's GUI folder: pickers, knot fields, tangent modes, clipboard, framing, undo keys."""

from __future__ import annotations

import contextlib
import functools
from typing import Any, Callable

import viser

from engine.gait.curve_editing import channel_tail, is_pinned
from engine.gait.curves import TangentMode
from engine.gait.style import PELVIS_CURVES, swing_channels
from engine.gait.velocity_sampler import SAMPLE_NAMES
from studio.panels.curve_editor.appearance import channel_color
from studio.panels.curve_editor.state import EditorBase
from studio.panels.typing_pause import after_typing_pause


TANGENT_LABELS = {
    "auto-clamped": TangentMode.AUTO_CLAMPED,
    "flat": TangentMode.FLAT,
    "linear": TangentMode.LINEAR,
    "aligned": TangentMode.ALIGNED,
    "free (broken)": TangentMode.FREE,
}
MODE_LABEL = {mode: label for label, mode in TANGENT_LABELS.items()}
MIXED = "(mixed)"  # the dropdown's value when the selected knots differ


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


class EditorWidgets(EditorBase):
    """The panel's GUI: sample/channel pickers, knot fields, tangent modes, clipboard, framing, undo."""

    def _gui_cb(self, fn: Callable[[Any], Any]) -> Callable[[Any], None]:
        """A GUI callback: guarded, ignored while the editor itself syncs widget values."""
        def callback(event: Any) -> None:
            with self._lock:  # _sync runs under the lock: a user event waits, a synced echo sees the flag
                if self._syncing or self._closed:  # closed: a typed value's pause ran out after the editor went
                    return
                self._guarded(fn, event)
        return callback

    def _typed(self, fn: Callable[[Any], Any]) -> Callable[[Any], None]:
        """A GUI callback for a typed field: runs once its keys pause (:mod:`studio.panels.typing_pause`)."""
        return after_typing_pause(self._gui_cb(fn), ignore=lambda: self._syncing)

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
                        cb.on_update(self._gui_cb(functools.partial(self._on_checkbox_event, ch)))
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
        self.look_button.on_click(self._gui_cb(self._on_look_at_graph))
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

    def _on_checkbox_event(self, channel: str, event: Any) -> None:
        self._on_checkbox(channel, event.target.value)

    def _on_look_at_graph(self, event: Any) -> None:
        if event.client is not None:
            self.look_at_graph(event.client)

    def _on_checkbox(self, channel: str, value: bool) -> None:
        self.show_channel(channel, value)

    def _on_tangent_dropdown(self, event: Any) -> None:
        if event.target.value not in TANGENT_LABELS:
            return
        mode = TANGENT_LABELS[event.target.value]
        with self._lock:
            ref = self.primary
            curve = self._curve(ref.channel) if ref else None
            if ref is None or curve is None or ref.index >= curve.n_knots:
                return
            if all(self._knot_exists(r) and self._knot(r).mode is mode
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
        if ref is not None and curve is not None and ref.index < curve.n_knots:
            k = curve.knots[ref.index]
            pinned = is_pinned(ref.channel, ref.index, curve.n_knots)
            self._sync(self.time_input, round(k.t_s, 6))
            self._sync(self.value_input, round(k.value, 6))
            modes = {self._knot(r).mode for r in self._selection if self._knot_exists(r)}
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
