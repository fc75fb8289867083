"""Sample editor: pick one of the nine samples, edit its time intervals and attributes.

The timeline is a multi-slider over the cycle with the four event handles (t_LTD, t_RLO,
t_RTD, T_S; t_LLO is 0) and a bar showing swing and support phases. Every edit goes through
the style session: one that breaks a constraint (event order, minimum single/double
support, attribute ranges) is refused with the validator's message and the controls snap
back (as in the paper's Fig. 10). Curve knots rescale with their interval.

Below the controls, the engine's edit-time feasibility check (engine/gait/feasibility.py) of
the selected sample, rerun in the background after every edit (latest wins): the phase and
what to change when the robot could not walk it, before Test is pressed.
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import replace
from typing import TYPE_CHECKING, Callable

import viser

from engine.gait.style import (ATTRIBUTE_NAMES, MAX_SPLAY_RAD, MAX_TRANSITION_S, MAX_X_BIAS_M, GaitSample, Intervals,
                               Style)
from engine.gait.velocity_sampler import SAMPLE_DISPLAY_NAMES, SAMPLE_NAMES

if TYPE_CHECKING:
    from studio.style_session import StyleSession

ATTRIBUTE_LABELS = {
    "stance_width_m": "Stance width (m)", "stance_splay_rad": "Splay (rad)", "stance_x_bias_m": "X-bias (m)",
    "liftoff_transition_s": "Toe/heel-off Δt (s)", "touchdown_transition_s": "Heel/toe-strike Δt (s)",
    "pelvis_height_m": "Pelvis height (m)",
}


SLIDER_INSET_LEFT, SLIDER_INSET_RIGHT = "6.8rem", "0.7rem"  # where the Events slider's track begins / ends


def timeline_max_s(cycle_s: float, max_cycle_s: float) -> float:
    """The Events slider's end: room to lengthen the cycle by half, in tenths of a second, so the four
    handles spread over the slider instead of crowding its left end."""
    return float(min(max_cycle_s, math.ceil(1.5 * cycle_s * 10.0 - 1e-9) / 10.0))


def phase_bar_html(iv: Intervals, span_s: float | None = None) -> str:
    """The walk cycle as coloured blocks: left swing, double support, right swing, double support — over
    ``span_s`` (the Events slider's range, so the blocks line up with its handles; default the cycle)."""
    t_ltd, t_rlo, t_rtd, cycle = iv.events_s
    parts = [("LS", 0.0, t_ltd, "#4c8bf5"), ("DS", t_ltd, t_rlo, "#bbbbbb"), ("RS", t_rlo, t_rtd, "#f5a04c"),
             ("DS", t_rtd, cycle, "#bbbbbb")]
    if span_s is not None and span_s > cycle:
        parts.append(("", cycle, span_s, "transparent"))
    cells = "".join(
        f'<div title="{name} {a:.2f}–{b:.2f} s" style="flex:{max(b - a, 1e-3):.4f};background:{c};color:#fff;'
        f'font-size:11px;text-align:center;overflow:hidden">{f"{name} {b - a:.2f}" if name else ""}</div>'
        for name, a, b, c in parts)
    # indented like the slider's track (viser puts a 7.25em − 0.6375em per folder level label on its left)
    return (f'<div style="display:flex;height:20px;border-radius:4px;overflow:hidden;'
            f'margin:2px {SLIDER_INSET_RIGHT} 2px {SLIDER_INSET_LEFT}">{cells}</div>'
            f'<div style="font-size:11px;color:#666">cycle {cycle:.2f} s · LLO 0 · LTD {t_ltd:.2f} · '
            f'RLO {t_rlo:.2f} · RTD {t_rtd:.2f}</div>')


class SampleEditor:
    def __init__(self, server: viser.ViserServer, session: "StyleSession", notify: Callable[[str, str], None],
                 on_sample: Callable[[str], None] = lambda name: None):
        self.server = server
        self.session = session
        self.notify = notify
        self.on_sample = on_sample
        self.sample_name = "in_place"
        self._syncing = False
        self._timeline_sample = self.sample_name
        ctx = session.ctx
        labels = dict(zip(SAMPLE_NAMES, SAMPLE_DISPLAY_NAMES))
        self.dropdown = server.gui.add_dropdown("Sample", options=SAMPLE_NAMES, initial_value=self.sample_name,
                                                hint=" · ".join(f"{n} = {labels[n]}" for n in SAMPLE_NAMES))
        self.velocity = server.gui.add_markdown("")
        self.phase_bar = server.gui.add_html("")
        iv = self._sample().intervals
        self.timeline = server.gui.add_multi_slider(
            "Events (s)", min=0.0, max=timeline_max_s(iv.cycle_s, ctx.max_cycle_s), step=0.01,
            initial_value=(*iv.events_s,),
            min_range=min(ctx.min_double_support_s, ctx.min_single_support_s),
            hint="t_LTD, t_RLO, t_RTD, cycle T_S (left liftoff is 0); the slider ends at 1.5× the cycle "
                 "(pick the sample again to extend it)")
        self.message = server.gui.add_markdown("")
        self.feasibility = server.gui.add_markdown("")
        self._check_wanted: tuple | None = None  # (style, sample) the check should look at next
        self._check_event = threading.Event()
        threading.Thread(target=self._check_loop, name="feasibility-check", daemon=True).start()
        ranges = {  # the validator's ranges: a slider shows every valid value
            "stance_width_m": ctx.stance_width_range_m, "stance_splay_rad": (-MAX_SPLAY_RAD, MAX_SPLAY_RAD),
            "stance_x_bias_m": (-MAX_X_BIAS_M, MAX_X_BIAS_M),
            "liftoff_transition_s": (0.0, MAX_TRANSITION_S), "touchdown_transition_s": (0.0, MAX_TRANSITION_S),
            "pelvis_height_m": ctx.pelvis_height_range_m,
        }
        self.attributes: dict[str, viser.GuiSliderHandle] = {}
        a = self._sample().attributes
        for name in ATTRIBUTE_NAMES:
            lo, hi = ranges[name]
            self.attributes[name] = server.gui.add_slider(ATTRIBUTE_LABELS[name], min=lo, max=hi, step=0.005,
                                                          initial_value=min(max(getattr(a, name), lo), hi))
        self.copy_target = server.gui.add_dropdown("Copy sample to", options=SAMPLE_NAMES, initial_value="in_place")
        self.copy_button = server.gui.add_button("Copy", icon=viser.Icon.COPY)

        self.dropdown.on_update(lambda _: self.select(self.dropdown.value))
        self.timeline.on_update(lambda _: self._guard(self.set_events, tuple(self.timeline.value)))
        for name, slider in self.attributes.items():
            slider.on_update(functools.partial(self._on_attribute_slider, name))
        self.copy_button.on_click(lambda _: self._guard(self.copy_to, self.copy_target.value))
        session.subscribe(lambda style, reason: self.refresh())
        self.refresh()

    # ------------------------------------------------------------------ edits
    def _style(self) -> Style:
        style = self.session.style
        if style is None:
            raise ValueError("no style open")
        return style

    def _sample(self) -> GaitSample:
        return self._style().samples[self.sample_name]

    def _on_attribute_slider(self, name: str, _event: object) -> None:
        self._guard(self.set_attribute, name, self.attributes[name].value)

    def _guard(self, fn, *args) -> None:
        if self._syncing:
            return
        try:
            fn(*args)
        except Exception as exc:  # a panel bug must not break the session
            self.notify("error", f"{fn.__name__}: {exc}")
            self.refresh()

    def select(self, name: str) -> None:
        if name not in SAMPLE_NAMES:
            return
        self.sample_name = name
        self.refresh()
        self.on_sample(name)

    def set_events(self, events: tuple[float, ...]) -> bool:
        """New (t_LTD, t_RLO, t_RTD, T_S); refused if it breaks the cycle's constraints."""
        t_ltd, t_rlo, t_rtd, cycle = (float(e) for e in events)
        sample = self._sample()
        new = sample.with_intervals(Intervals(cycle, (0.0, t_ltd), (t_rlo, t_rtd)))
        result = self.session.apply(self._style().with_sample(self.sample_name, new),
                                    f"{self.sample_name} intervals")
        return self._result(result)

    def set_attribute(self, name: str, value: float) -> bool:
        sample = self._sample()
        new = replace(sample, attributes=replace(sample.attributes, **{name: float(value)}))
        result = self.session.apply(self._style().with_sample(self.sample_name, new), f"{self.sample_name} {name}")
        return self._result(result)

    def copy_to(self, target: str) -> bool:
        """Duplicate the current sample onto another one (its curves and intervals)."""
        if target == self.sample_name:
            return False
        result = self.session.apply(self._style().with_sample(target, self._sample()),
                                    f"copy {self.sample_name} → {target}")
        return self._result(result)

    def _result(self, result) -> bool:
        if not result.ok:
            self.message.content = f"⚠️ {result.message}"
            self.notify("warning", result.message)
            self.refresh()  # snap the controls back to the (still valid) style
        else:
            self.message.content = ""
        return result.ok

    # ------------------------------------------------------------------ view
    def refresh(self) -> None:
        if self.session.style is None:
            return
        self._syncing = True
        try:
            sample = self._sample()
            v = self.session.style.velocities.velocity_of(self.sample_name)
            self.velocity.content = f"velocity vx {v[0]:+.2f} m/s · vy {v[1]:+.2f} m/s · wz {v[2]:+.2f} rad/s"
            span = timeline_max_s(sample.intervals.cycle_s, self.session.ctx.max_cycle_s)
            if self.timeline.max < sample.intervals.cycle_s or self.sample_name != self._timeline_sample:
                # a new sample (or an undo past the end): rescale. Not while the animator drags a
                # handle: the slider must not change scale under the pointer.
                self.timeline.max = span
            self._timeline_sample = self.sample_name
            self.phase_bar.content = phase_bar_html(sample.intervals, float(self.timeline.max))
            events = tuple(round(e, 4) for e in sample.intervals.events_s)
            if tuple(self.timeline.value) != events:
                self.timeline.value = events  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
            for name, slider in self.attributes.items():
                value = min(max(getattr(sample.attributes, name), slider.min), slider.max)
                if abs(slider.value - value) > 1e-9:
                    slider.value = value  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
            if self.dropdown.value != self.sample_name:
                self.dropdown.value = self.sample_name  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
        finally:
            self._syncing = False
        self._request_check()

    # ------------------------------------------------------------------ feasibility
    def _request_check(self) -> None:
        wanted = (self.session.style, self.sample_name)
        if self._check_wanted is not None and wanted[0] is self._check_wanted[0] and wanted[1] == self._check_wanted[1]:
            return
        self._check_wanted = wanted
        self.feasibility.content = "<small>checking the sample…</small>"
        self._check_event.set()

    def _check_loop(self) -> None:
        from engine.gait.feasibility import check_style
        from engine.robot.model import load_robot

        while True:
            self._check_event.wait()
            self._check_event.clear()
            wanted = self._check_wanted
            if wanted is None or wanted[0] is None:
                continue
            style, name = wanted
            try:
                findings = check_style(load_robot(self.session.robot), style, samples=(name,))
            except Exception as exc:  # noqa: BLE001 - the check must never break the panel
                text = f"<small>feasibility check failed: {exc}</small>"
            else:
                text = feasibility_markdown(name, findings)
            if self._check_wanted is wanted:  # an edit since then: its own check follows
                self.feasibility.content = text


def feasibility_markdown(sample: str, findings: list, limit: int = 3) -> str:
    """The check's findings for one sample as the panel shows them."""
    if not findings:
        # (the check reads the reference: falls that begin in the closed loop only the rehearsal below can show)
        return (f"✓ **{sample}**: the reference check finds nothing in the way of walking it "
                "<small>(it reads the reference; the rehearsal below walks it in physics)</small>")
    lines = [f"⚠️ **{f.sample}**, around {f.phase_pct:.0f} % of the cycle: {f.message}" for f in findings[:limit]]
    more = len(findings) - limit
    if more > 0:
        lines.append(f"<small>… and {more} more</small>")
    return "\n\n".join(lines)
