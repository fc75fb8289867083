"""The Style tab's *Speeds*: how fast the style walks at its key velocities (the four fields of the style's
``velocities``: paper §6.1's sample velocities).

Each sample walks at one of them (forward_fast and reverse_fast at the fast speed, forward_slow and reverse_slow at
the slow one, the strafes sideways, the turns turning); the joystick's full deflection is the fast speed. An edit
goes through the style session like any other (validated: slow below fast, and each sample's step — its velocity ×
its timings — within the legs' reach; undoable; autosaved). A refused value snaps back and the message says why.
The panel computes nothing.
"""

from __future__ import annotations

import functools
from dataclasses import replace
from typing import TYPE_CHECKING, Callable

import viser

from studio.panels.typing_pause import after_typing_pause
from studio.style_session import EditResult

if TYPE_CHECKING:
    from studio.style_session import StyleSession

SPEED_DECIMALS = 3  # the fields show (and step by) a thousandth: a style's 0.279 m/s is not shown as 0.28
#: (field of SampleVelocities, label, the samples walking at it)
SPEED_FIELDS = (
    ("x_max_mps", "Fast (m/s)", "forward_fast and reverse_fast, and the joystick's full forward"),
    ("x_slow_mps", "Slow (m/s)", "forward_slow and reverse_slow"),
    ("y_max_mps", "Sideways (m/s)", "left_strafe and right_strafe"),
    ("yaw_max_radps", "Turning (rad/s)", "left_turn and right_turn"),
)


class StyleSpeeds:
    def __init__(self, server: viser.ViserServer, session: "StyleSession", notify: Callable[[str, str], None]):
        self.session = session
        self.notify = notify
        self._syncing = False
        self.inputs: dict[str, viser.GuiNumberHandle] = {}
        style = session.style
        for field, label, samples in SPEED_FIELDS:
            value = float(getattr(style.velocities, field)) if style is not None else 0.0
            handle = server.gui.add_number(label, initial_value=round(value, SPEED_DECIMALS), min=0.0,
                                           step=10.0 ** -SPEED_DECIMALS, hint=f"the speed of {samples}")
            handle.on_update(after_typing_pause(functools.partial(self._on_typed, field),
                                                ignore=lambda: self._syncing))
            self.inputs[field] = handle
        self.message = server.gui.add_markdown("")
        session.subscribe(lambda style, reason: self.refresh())

    def _on_typed(self, field: str, _event: object) -> None:
        self.set_speed(field, float(self.inputs[field].value))

    def set_speed(self, field: str, value: float) -> bool:
        """Set one of the style's speeds (an edit of the session: validated, undoable)."""
        style = self.session.style
        if style is None:
            return False
        if abs(float(getattr(style.velocities, field)) - value) < 1e-9:
            return True
        try:
            velocities = replace(style.velocities, **{field: value})
        except ValueError as exc:  # (the velocities' own invariants: positive, finite, slow below fast)
            result = EditResult(False, f"velocities.{field}: {exc}")
        else:
            result = self.session.apply(replace(style, velocities=velocities), f"speed {field}")
        if result.ok:
            self.message.content = ""
        else:
            self.message.content = f"⚠️ {result.message}"
            self.notify("warning", result.message)
            self.refresh()  # the refused value snaps back
        return result.ok

    def refresh(self) -> None:
        style = self.session.style
        if style is None:
            return
        self._syncing = True
        try:
            for field, handle in self.inputs.items():
                value = round(float(getattr(style.velocities, field)), SPEED_DECIMALS)
                if abs(float(handle.value) - value) > 1e-9:
                    handle.value = value  # type: ignore[misc]  # viser 1.1.1's stub types .value read-only
        finally:
            self._syncing = False
