"""The gait planner's tick as it was before issue 12's trim of its Python (branch plan11), kept as the reference the
current code is held to bit for bit (tests/gait/test_planner_step_reference.py, tools/planner_step_ab.py)."""

from __future__ import annotations

import math
from dataclasses import fields

import numpy as np

from engine.geometry import smooth_max, smooth_min, smoothstep
from engine.gait.blending import HEEL, SWING_PHASES, TOE, BlendedGait
from engine.gait.footsteps import Foothold, foothold_from_path, project_to_safe_region, stance_offset_xy_yaw
from engine.gait.heel_toe import ROLL_SMOOTHING, stance_pitch
from engine.gait.path_frame import predict_xy_yaw
from engine.gait.planner import (
    _LEFT_LIFTOFF,
    _LEFT_TOUCHDOWN,
    _NO_ADJUST,
    _NO_FEEDBACK,
    _NO_POS,
    _NO_ROTS,
    _ONE_PIECE_TIMES,
    _PATH_TABLE_SIZE,
    _PATH_TABLE_TIMES,
    _PATH_TABLE_TIMES_LIST,
    _RIGHT_LIFTOFF,
    _RIGHT_TOUCHDOWN,
    CONTACT_TOL_M,
    EDGE_SUPPORT_DEPTH_M,
    MIN_HEEL_TOE_TRANSITION_S,
    PATH_TABLE_STEP_S,
    PREVIEW_S,
    START_HOLD_S,
    STYLE_FADE_S,
    TARGET_SETTLE_FRACTION,
    TRANSITION_SMOOTHING_S,
    ContactPhase,
    GaitPlanner,
    GaitReference,
    PlannerFeedback,
    _pitched_edge,
    _remaining_ease_delay,
)
from engine.gait.planner_kernels import (
    EDGE_CODES,
    FOOT_FLAT,
    FOOT_ROLLED,
    FOOT_SWING,
    path_table,
    preview_intervals,
    reference_frames,
)
from engine.gait.style import SIDES
from engine.gait.swing import nominal_swing
from engine.gait.velocity_sampler import SAMPLE_NAMES, sample_weights


class PlannerBefore(GaitPlanner):
    """GaitPlanner with the replaced methods (commit a15de57's, verbatim)."""

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

    def _stance_xy_yaw(self, side: str) -> tuple[float, float, float]:
        """:meth:`stance` of the current blend as floats, kept while the blend is."""
        cached = self._stances
        if cached is None or cached[0] is not self.blend:
            b = self.blend
            width, splay, x_bias = (b.attribute("stance_width_m"), b.attribute("stance_splay_rad"),
                                    b.attribute("stance_x_bias_m"))
            cached = self._stances = (b, {s: stance_offset_xy_yaw(s, width, splay, x_bias) for s in SIDES})
        return cached[1][side]

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

    def _path_pose_ahead(self, dt_s: float) -> tuple[float, float, float]:
        """:meth:`path_ahead` on floats (x, y, yaw)."""
        if self.command_goal is None or self.command_rate_limits is None:
            path = self.path
            return predict_xy_yaw(float(path.x), float(path.y), float(path.yaw), self.command, dt_s)
        if self._path_rows is None:
            self._path_table_now()
            assert self._path_rows is not None
        poses, vels = self._path_rows
        k = min(int(dt_s / PATH_TABLE_STEP_S), len(_PATH_TABLE_TIMES_LIST) - 1)
        x, y, yaw = poses[k].tolist()  # the row as floats (a tick reads two or three of the 61)
        return predict_xy_yaw(x, y, yaw, vels[k].tolist(), dt_s - _PATH_TABLE_TIMES_LIST[k])

    def _path_table_now(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """This tick's path table (times, poses, velocities), built on its first use."""
        if self._path_table is None or self._path_rows is None:
            self._path_table = self._build_path_table()
            self._path_rows = self._path_table[1:]
        return self._path_table

    def _build_path_table(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Path poses and mean piece velocities every PATH_TABLE_STEP_S of the ramp toward the goal.

        The rate-limited velocity ramp is a short float loop; the arcs of all pieces are then chained
        (:func:`engine.gait.planner_kernels.path_table`, one compiled call): rebuilt every planner tick, as the
        path and the command (with the controller's velocity adjustment) move every tick."""
        command_goal, command_rate_limits = self.command_goal, self.command_rate_limits
        assert command_goal is not None and command_rate_limits is not None, "path_ahead builds it with a goal only"
        clamped = self.command_clamped  # clamping the goal must not change what the command reports
        goal = self.clamp_command(command_goal)
        self.command_clamped = clamped
        poses, vels = path_table(float(self.path.x), float(self.path.y), float(self.path.yaw),
                                 np.asarray(self.command, dtype=float), goal,
                                 np.asarray(command_rate_limits, dtype=float), PATH_TABLE_STEP_S, _PATH_TABLE_SIZE)
        return _PATH_TABLE_TIMES, poses, vels

    def _track_target(self, side: str, raw: Foothold) -> None:
        """Follow the re-evaluated foothold's increments, easing them out before touchdown.

        The paper re-evaluates the upcoming foothold every tick and latches it at touchdown;
        a target still moving at touchdown would land the foot with that velocity (a kink).
        Following increments with gain 1 − w(s), w easing 0 → 1 over the last
        TARGET_SETTLE_FRACTION of the swing, keeps r(t) C1 and lands exactly on the target.
        """
        prev = self._raw_target.get(side)
        self._raw_target[side] = raw
        if prev is None:
            self.target[side] = raw
            return
        lo, td = SWING_PHASES[side]
        k = math.floor(self.phi - lo)
        blend = self.blend
        t_lo, t_td = blend.event_time(k + lo), blend.event_time(k + td)
        s = (blend.time_at(self.phi) - t_lo) / (t_td - t_lo)
        gain = 1.0 - smoothstep((s - (1.0 - TARGET_SETTLE_FRACTION)) / TARGET_SETTLE_FRACTION)
        cur = self.target[side]
        d_yaw = math.remainder(raw.yaw - prev.yaw, 2 * math.pi)
        self.target[side] = Foothold(cur.x + gain * (raw.x - prev.x), cur.y + gain * (raw.y - prev.y),
                                     cur.yaw + gain * d_yaw)

    def _handle_events(self, phi_old: float, phi_new: float) -> None:
        """Liftoff: remember where the foot leaves from. Touchdown: latch the target."""
        events = []
        for side in SIDES:
            lo, td = SWING_PHASES[side]
            for base in (math.floor(phi_old), math.floor(phi_old) + 1):
                for phase, kind in ((base + lo, "liftoff"), (base + td, "touchdown")):
                    if phi_old < phase <= phi_new:
                        events.append((phase, side, kind))
        for _, side, kind in sorted(events):
            if kind == "liftoff":
                self.swing_start[side] = self.latched[side]
                self.target[side] = self._upcoming_foothold(side, _NO_ADJUST)
                self._raw_target[side] = self.target[side]
            else:
                if self.path_follows_feet > 0.0:
                    nominal = self._upcoming_foothold(side, _NO_ADJUST)
                    self._shift_path(self.target[side].x - nominal.x, self.target[side].y - nominal.y)
                self.latched[side] = self.target[side]
                self.landed[side] = True

    def _upcoming_foothold(self, side: str, adjust_xy: np.ndarray) -> Foothold:
        blend = self.blend
        phi_td, phi_lo = self._contact_midpoint_phase(side, self.phi)
        t_now = blend.time_at(self.phi)
        t_mid = 0.5 * (blend.event_time(phi_td) + blend.event_time(phi_lo))
        pose = self._path_pose_ahead(max(t_mid - t_now, 0.0))
        target = foothold_from_path(pose, self._stance_xy_yaw(side))
        adjust_x, adjust_y = adjust_xy.tolist()
        if adjust_x != 0.0 or adjust_y != 0.0:  # adjust_xy.any()
            target = Foothold(target.x + adjust_x, target.y + adjust_y, target.yaw)
        other = "right" if side == "left" else "left"
        return project_to_safe_region(self.latched[other], target, side, self.region)

    def evaluate(self, phi: float) -> GaitReference:
        """r at phase φ for the current state. Rates are backward differences over the last tick
        (the controller interpolates between ticks with them). The frames (pelvis and sole rotations, sole
        positions and corners, their rates) are one compiled call
        (:func:`engine.gait.planner_kernels.reference_frames`)."""
        blend = self.blend
        cycle_vals, left_vals, right_vals = blend.channel_values(phi)  # (the rates are backward differences here)
        t = blend.time_at(phi)
        f = phi - math.floor(phi)  # in_swing of both feet
        swinging = (_LEFT_LIFTOFF <= f < _LEFT_TOUCHDOWN, _RIGHT_LIFTOFF <= f < _RIGHT_TOUCHDOWN)
        left, left_progress = self._foot_params("left", phi, t, blend, left_vals, swinging[0])
        right, right_progress = self._foot_params("right", phi, t, blend, right_vals, swinging[1])
        pelvis_yaw, pelvis_pitch, pelvis_roll = cycle_vals[1:4].tolist()
        params = np.array([float(self.path.yaw), pelvis_yaw, pelvis_pitch, pelvis_roll, self.sole_length_m,
                           self.sole_width_m, ROLL_SMOOTHING, ROLL_SMOOTHING ** 2, *left, *right])
        prev = self._last_pose
        dt = self.t_s - prev["t"] if prev is not None else 0.0
        rots, foot_pos, corners, ang, lin = reference_frames(
            params, self.sole_corners_local, prev["rots"] if prev is not None else _NO_ROTS,
            prev["foot_pos"] if prev is not None else _NO_POS, dt if prev is not None and dt > 0 else 0.0)
        pelvis_rot, foot_rot = rots[0], rots[1:]
        pelvis_z = blend.attribute("pelvis_height_m") + cycle_vals[0]
        upper = cycle_vals[4:].copy()
        # (the soles' rotations are rots[1:], their positions foot_pos: rows left, right)
        self._last_pose = {"t": self.t_s, "pelvis_z": pelvis_z, "rots": rots, "foot_pos": foot_pos, "upper": upper}
        if prev is None or dt <= 0:
            z_rate = 0.0
            upper_qd = np.zeros(upper.shape)  # np.zeros_like(upper) (float64 zeros) without its Python wrapper
        else:
            z_rate = (pelvis_z - prev["pelvis_z"]) / dt
            upper_qd = (upper - prev["upper"]) / dt
        return GaitReference(
            t_s=self.t_s, phase=phi, command=self.command.copy(),
            sample_weights=self.weights.copy(), path_pose=self.path.pose(),
            pelvis_z=pelvis_z, pelvis_z_rate=z_rate, pelvis_rot=pelvis_rot, pelvis_ang_vel=ang[0],
            foot_pos=foot_pos.copy(), foot_rot=foot_rot, foot_lin_vel=lin, foot_ang_vel=ang[1:],
            contact=np.array([not swinging[0], not swinging[1]]),
            corner_contact=corners[:, :, 2] < CONTACT_TOL_M, sole_corners=corners,
            upper_q=upper, upper_qd=upper_qd,
            footholds={"left": self.target["left"] if swinging[0] else self.latched["left"],  # (SIDES' order)
                       "right": self.target["right"] if swinging[1] else self.latched["right"]},
            cycle_s=blend.events_s[3],
            swing_progress=np.array([left_progress, right_progress]),
        )

    def _foot_params(self, side: str, phi: float, t: float, blend: BlendedGait, vals: np.ndarray,
                     swinging: bool) -> tuple[tuple[float, ...], float]:
        """The sole's part of :func:`engine.gait.planner_kernels.reference_frames`' parameters (FOOT_PARAMS: mode,
        x, y, yaw, rig yaw, heel and toe pitch, roll, offset) and its swing progress.

        Swinging: the nominal swing (Eqs. 5–6) at its progress ⊕ the style's rig and offset. Standing: the
        latched foothold with the heel/toe transitions after touchdown / before liftoff."""
        lo, td = SWING_PHASES[side]
        k = math.floor(phi - lo)
        if swinging:
            t_lo, t_td = blend.event_time(k + lo), blend.event_time(k + td)
            s = min(max((t - t_lo) / (t_td - t_lo), 0.0), 1.0)
            x, y, yaw, _ = nominal_swing(self.swing_start[side], self.target[side], s)
            v = vals.tolist()  # the rig's angles as floats (the same numbers, without numpy scalars)
            return (FOOT_SWING, x, y, yaw, v[3], v[HEEL], v[TOE], v[6], v[0], v[1], v[2]), s
        hold = self.latched[side]
        t_td = blend.event_time(k + td)  # last touchdown (k indexes the swing that ended)
        t_next_lo = blend.event_time(k + 1 + lo)
        foothold_s = t_next_lo - t_td
        t_ltd, t_rlo, t_rtd, cycle = blend.events_s
        ds = (t_rlo - t_ltd, cycle - t_rtd)
        ds_after_td, ds_before_lo = ds if side == "left" else ds[::-1]
        # A pitched foot at liftoff/touchdown needs time to roll from/to flat: never less than
        # MIN_HEEL_TOE_TRANSITION_S (else the foot would snap), never more than the double support.
        # Smooth min/max: durations vary with the blend weights, and a hard switch of the
        # binding limit would put a kink in the foot's pitch.
        eps = TRANSITION_SMOOTHING_S
        d_td = smooth_min(smooth_min(smooth_max(blend.attribute("touchdown_transition_s"), MIN_HEEL_TOE_TRANSITION_S, eps),
                                     0.5 * foothold_s, eps), ds_after_td, eps)
        d_lo = smooth_min(smooth_min(smooth_max(blend.attribute("liftoff_transition_s"), MIN_HEEL_TOE_TRANSITION_S, eps),
                                     0.5 * foothold_s, eps), ds_before_lo, eps)
        liftoff_pitch, touchdown_pitch = blend.boundary_pitch[side]
        if not self.landed[side]:
            d_td = 0.0
        heel, toe = stance_pitch(t - t_td, t_next_lo - t, touchdown_pitch, liftoff_pitch, d_td, d_lo)
        mode = FOOT_FLAT if heel == 0.0 and toe == 0.0 else FOOT_ROLLED
        return (mode, hold.x, hold.y, hold.yaw, 0.0, heel, toe, 0.0, 0.0, 0.0, 0.0), 1.0

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

    def _edges_now(self) -> np.ndarray:
        """Edge codes (EDGE_CODES) of the sole edge each foot stands on at the last evaluated pose (from its pitch:
        −asin of (Rz(yaw)ᵀ R)[2, 0], which is R[2, 0]); −1 for both before the first pose."""
        if self._last_pose is None:
            return np.array([-1, -1])
        codes = []
        for r20 in self._last_pose["rots"][1:, 2, 0].tolist():  # the soles' R[2, 0]
            pitch = -math.asin(max(-1.0, min(1.0, r20)))
            codes.append(EDGE_CODES[_pitched_edge(min(pitch, 0.0), max(pitch, 0.0))])
        return np.array(codes)

    def _blend_constants(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The current blend's stance offsets (2, 3), the edge codes of its touchdown and liftoff pitches
        (2,) per foot and its event times (4,), kept while the blend is."""
        cached = self._preview_constants
        if cached is None or cached[0] is not self.blend:
            pitch = self.blend.boundary_pitch
            cached = self._preview_constants = (
                self.blend, np.array([self._stance_xy_yaw(s) for s in SIDES]),
                np.array([EDGE_CODES[_pitched_edge(*pitch[s][1])] for s in SIDES]),
                np.array([EDGE_CODES[_pitched_edge(*pitch[s][0])] for s in SIDES]), np.array(self.blend.events_s))
        return cached[1], cached[2], cached[3], cached[4]


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
