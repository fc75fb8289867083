"""The gait planner's tick as it was before issue 12's trim of its Python (branch plan11), kept as the reference the
current code is held to bit for bit (tests/gait/test_planner_step_reference.py, tools/planner_step_ab.py)."""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np

from engine.geometry import smoothstep
from engine.gait.blending import BlendedGait
from engine.gait.footsteps import Foothold
from engine.gait.planner import (
    _NO_ADJUST,
    _NO_FEEDBACK,
    _ONE_PIECE_TIMES,
    EDGE_SUPPORT_DEPTH_M,
    PATH_TABLE_STEP_S,
    PREVIEW_S,
    START_HOLD_S,
    STYLE_FADE_S,
    ContactPhase,
    GaitPlanner,
    GaitReference,
    PlannerFeedback,
    _remaining_ease_delay,
)
from engine.gait.planner_kernels import preview_intervals
from engine.gait.style import SIDES
from engine.gait.velocity_sampler import SAMPLE_NAMES, sample_weights


class PlannerBefore(GaitPlanner):
    """GaitPlanner with the methods plan11 rewrote (commit a15de57's, verbatim): the blend, the command's clamp, the
    step and the preview. The methods it left alone are inherited, and so are two whose change is a rename of the same
    number: ``evaluate`` (``ROLL_SMOOTHING ** 2`` hoisted into ``_ROLL_SMOOTHING_SQ``) and ``_build_path_table`` (a
    local alias of ``self.path``)."""

    def _blend(self) -> BlendedGait:
        weights = self.weights.tolist()
        members = [(w, self.banks.banks[n]) for w, n in zip(weights, SAMPLE_NAMES) if w > 1e-9]
        if self._fade_from is not None:
            f = smoothstep(self._fade_elapsed_s / STYLE_FADE_S)
            old = [(w * (1 - f), self._fade_from.banks[n]) for w, n in zip(weights, SAMPLE_NAMES) if w > 1e-9]
            members = [(w * f, b) for w, b in members] + old
        return self.banks.blend(members)

    def clamp_command(self, v: np.ndarray) -> np.ndarray:
        """The command limited to the style's sample velocities (``command_clamped`` tells)."""
        vel = self.style.velocities
        out, clamped = [], False
        for value, lim in zip((float(v[0]), float(v[1]), float(v[2])), (vel.x_max_mps, vel.y_max_mps, vel.yaw_max_radps)):
            if not math.isfinite(value):
                value, clamped = 0.0, True
            c = lim if value > lim else (-lim if value < -lim else value)
            clamped |= c != value
            out.append(c)
        self.command_clamped = clamped
        return np.array(out)

    def step(self, dt_s: float, command: np.ndarray, feedback: PlannerFeedback | None = None,
             with_preview: bool = True) -> GaitReference:
        """Advance by ``dt_s`` under ``command`` and the controller's ``feedback`` (time scaling κ,
        step adjustment, command preview) and return r(t)."""
        fb = feedback or _NO_FEEDBACK
        kappa, step_adjustment_xy = fb.time_scaling, fb.step_adjustment_xy_m
        self.command_goal, self.command_rate_limits = fb.command_goal, fb.command_rate_limits
        self.command = self.clamp_command(command)
        weights = sample_weights(self.command, self.style.velocities, self.style.blend_eta)
        fading = self._fade_from is not None
        if fading:
            self._fade_elapsed_s += dt_s
            if self._fade_elapsed_s >= STYLE_FADE_S:
                self._fade_from = None
        if fading or self._blend_stale or not bool((weights == self.weights).all()):  # np.array_equal of (9,) arrays
            self.weights = weights
            self.blend = self._blend()
            self._blend_stale = False
        blend = self.blend
        kappa = float(kappa) if math.isfinite(kappa) and kappa > 0 else 1.0

        # Exact phase clock: advance the gait time of the current blend by κ·dt, map back to φ.
        # At the start the clock holds in double support (the weight shift before the first step).
        phi_old = self.phi
        self.t_s += dt_s
        rate = kappa
        if self.hold_s > 0.0:  # the clock eases in from rest (C1 start)
            self.hold_s = max(self.hold_s - dt_s, 0.0)
            rate *= smoothstep(1.0 - self.hold_s / START_HOLD_S)
        if rate > 0.0:
            self.phi = max(blend.phase_of_time(blend.time_at(phi_old) + rate * dt_s), phi_old)
            self.path.advance(self.command, rate * dt_s)
        self._path_table = self._path_rows = None
        self._handle_events(phi_old, self.phi)
        adjust = _NO_ADJUST if step_adjustment_xy is None else np.asarray(step_adjustment_xy, dtype=float)
        for side in SIDES:
            if self.in_swing(side, self.phi):
                self._track_target(side, self._upcoming_foothold(side, adjust))
        ref = self.evaluate(self.phi)
        if with_preview:
            ref.preview = self.preview(kappa)
        return ref

    def preview(self, kappa: float = 1.0, horizon_s: float = PREVIEW_S) -> list[ContactPhase]:
        """Support intervals over the next ``horizon_s``: timings, footholds, polygons.

        From now over the contact events ahead: the feet stand where they stand (a swinging foot on its
        target), a foot that touches down later lands on its predicted foothold (the path at the middle of
        that contact ⊕ its stance offset, in the safe region of the other foot). One foot down: its sole,
        shortened at the toe by what the ankle cannot hold; both: the hull of both soles, the one of a foot
        rolling on its heel or toe (heel strike after its touchdown, toe-off before its liftoff) cut to that
        edge's strip. Compiled (:func:`engine.gait.planner_kernels.preview_intervals`)."""
        blend = self.blend
        phi = self.phi
        swinging = [self.in_swing(s, phi) for s in SIDES]
        start = [self.target[s] if swing else self.latched[s] for s, swing in zip(SIDES, swinging)]
        stances, touchdown_edges, liftoff_edges, events = self._blend_constants()
        if self.command_goal is None or self.command_rate_limits is None:  # the command holds: one piece
            path = self.path
            table = (_ONE_PIECE_TIMES, np.array([[float(path.x), float(path.y), float(path.yaw)]]),
                     np.asarray(self.command, dtype=float).reshape(1, 3))
        else:
            table = self._path_table_now()
        region = self.region
        if self._region_array is None or self._region_array[0] is not region:
            self._region_array = (region, np.array([region.side_m, region.front_m, region.cross_m, region.max_yaw_rad]))
        times, rows, holds, polygons = preview_intervals(
            float(phi), float(blend.time_at(phi)), float(kappa), _remaining_ease_delay(self.hold_s), float(horizon_s),
            events, np.array([[h.x, h.y, h.yaw] for h in start], dtype=float), np.array(swinging),
            self._edges_now(), np.array([self.landed[s] for s in SIDES]), touchdown_edges, liftoff_edges, stances,
            *table, PATH_TABLE_STEP_S, self._region_array[1],
            self.sole_length_m - 2.0 * self.preview_margin_m, self.sole_width_m - 2.0 * self.preview_margin_m,
            self.preview_toe_trim_m, EDGE_SUPPORT_DEPTH_M, 2.0)
        footholds = start + [Foothold(*row) for row in holds[2:].tolist()]
        polygons.flags.writeable = False  # the phases' polygons are views of it
        t_s = self.t_s
        phases = []
        for i, ((t0, t1), (left, right, i_left, i_right, m)) in enumerate(zip(times.tolist(), rows.tolist())):
            on = {"left": footholds[i_left], "right": footholds[i_right]} if left and right else (
                {"left": footholds[i_left]} if left else {"right": footholds[i_right]})
            phases.append(ContactPhase(t_s + t0, t_s + t1, on, polygons[i, :m]))
        return phases

def _assert_same(a: object, b: object, what: str) -> None:
    """The same type and bits (arrays: shape, dtype and bytes; dicts: keys in order, then each value; lists: each
    item; floats: their 8 bytes, so -0.0 is not 0.0; the rest, e.g. Footholds: ==)."""
    assert type(a) is type(b), (what, type(a), type(b))
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray)
        assert a.dtype == b.dtype and a.shape == b.shape, what
        assert a.tobytes() == b.tobytes(), what
    elif isinstance(a, (float, np.floating)):
        assert np.float64(a).tobytes() == np.float64(b).tobytes(), (what, a, b)  # type: ignore[arg-type]
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), what
        for key in a:
            _assert_same(a[key], b[key], f"{what}[{key}]")
    elif isinstance(a, (list, tuple)):
        assert isinstance(b, (list, tuple)) and len(a) == len(b), what
        for i, (x, y) in enumerate(zip(a, b)):
            _assert_same(x, y, f"{what}[{i}]")
    elif isinstance(a, ContactPhase):
        assert isinstance(b, ContactPhase)
        for f in fields(ContactPhase):
            _assert_same(getattr(a, f.name), getattr(b, f.name), f"{what}.{f.name}")
    else:
        assert a == b, (what, a, b)


def assert_same_reference(now: GaitReference, before: GaitReference, what: str) -> None:
    """Every field of two references (the preview's phases field by field) the same, bit for bit."""
    for f in fields(GaitReference):
        _assert_same(getattr(now, f.name), getattr(before, f.name), f"{what}: {f.name}")
