"""How often the studio streams what the engine publishes, so that the simulation keeps the sim clock.

The engine publishes 60 frames and 20 telemetry packets per second of wall time and steps the simulation in
real time when it gets the CPU (≈ 0.7 of a core for G1 walking, `studio bench soak`'s ``[soak cpu]``). Every
frame the studio streams costs it CPU per connected browser (pose messages, viser's per-client windows); on a
machine where the CPU is short (a browser rendering beside the studio), that CPU is taken from the engine,
which then lets simulated time fall behind (the frame's ``real_time_factor`` drops below 1).

:class:`StreamRate` lowers the rate while the engine falls behind — by a factor each second the engine reports
a real-time factor under :data:`BEHIND_RTF`, never below its floor (24 frames/s for the robot: above the
20 frames/s a browser needs to look smooth) — and raises it back while the engine keeps real time. A frame
that changes what the user must see at once (a mode, an edit's revision, paused or fallen) always goes out.
The studio computes nothing here: it only decides which of the engine's frames to draw.
"""

from __future__ import annotations

BEHIND_RTF = 0.97  # the engine reports less than this: it is short of CPU, stream less
CAUGHT_UP_RTF = 0.99  # at least this: stream more again
STEP = 0.75  # the rate changes by this factor once per adaptation period
ADAPT_PERIOD_S = 1.0  # the engine updates its real-time factor once a second
FRAME_HZ = (24.0, 60.0)  # robot frames: floor, full (the engine's publish rate)
TELEMETRY_HZ = (10.0, 20.0)  # overlays, ghost and joint-limit tints: floor, full
MAX_CREDIT = 2.0  # after a gap, at most one item beyond the rate goes out at once


class StreamRate:
    """Admits at most ``rate_hz`` items per second of wall time; the rate follows the engine's real-time factor
    between ``floor_hz`` and ``full_hz``."""

    def __init__(self, floor_hz: float, full_hz: float):
        if not 0.0 < floor_hz <= full_hz:
            raise ValueError(f"expected 0 < floor_hz <= full_hz, got {floor_hz}, {full_hz}")
        self.floor_hz, self.full_hz = floor_hz, full_hz
        self.rate_hz = full_hz
        self.admitted = 0
        self.skipped = 0
        self._last_item_s: float | None = None
        self._credit = 0.0
        self._last_adapt_s: float | None = None

    @property
    def full(self) -> bool:
        return self.rate_hz >= self.full_hz

    def adapt(self, now_s: float, real_time_factor: float) -> None:
        """Follow the engine's real-time factor (at most once per :data:`ADAPT_PERIOD_S`; 0 or less: unknown)."""
        if self._last_adapt_s is None:
            self._last_adapt_s = now_s
            return
        if now_s - self._last_adapt_s < ADAPT_PERIOD_S or real_time_factor <= 0.0:
            return
        self._last_adapt_s = now_s
        if real_time_factor < BEHIND_RTF:
            self.rate_hz = max(self.floor_hz, self.rate_hz * STEP)
        elif real_time_factor >= CAUGHT_UP_RTF:
            self.rate_hz = min(self.full_hz, self.rate_hz / STEP)

    def admit(self, now_s: float, urgent: bool = False) -> bool:
        """True: stream this item now. Credit accrues at ``rate_hz`` per second of wall time and an item spends
        one (so 60 Hz input at 24 Hz admits 2 of every 5, not every third); at the full rate, or when
        ``urgent``, the item goes out regardless."""
        dt = 1.0 / self.rate_hz if self._last_item_s is None else max(now_s - self._last_item_s, 0.0)
        self._last_item_s = now_s
        self._credit = min(self._credit + dt * self.rate_hz, MAX_CREDIT)
        if self.full or urgent or self._credit >= 1.0 - 1e-9:
            self._credit = max(self._credit - 1.0, 0.0)
            self.admitted += 1
            return True
        self.skipped += 1
        return False
