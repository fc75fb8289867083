"""The procedural gait planner (paper §4.2, Eqs. 1–6): r(t) = g(v, s, Π, t).

Each 125 Hz tick it
1. blends the style's samples for the command velocity (sampler §5.3 + phase-space blending),
2. advances a *phase clock* φ at dφ/dt = κ / Ω'(φ) — contact events sit at fixed phases
   (LLO 0, LTD 0.1, RLO 0.5, RTD 0.6), so blends, live edits and time scaling never
   reorder or skip them,
3. integrates the path frame, re-evaluates the swing foot's upcoming foothold (Eq. 4, with
   the safe-region projection) and latches it at touchdown,
4. composes nominal and stylized motion (Eq. 3): feet = nominal swing (Eqs. 5–6) ⊕ swing
   curves with the heel/toe rig; pelvis height and rotation; upper-body joints,
5. previews the contact sequence over 2 s (footholds, timings, support polygons) for the MPC.

Discrete changes (a new style while editing) cross-fade over ``STYLE_FADE_S`` as a
phase-space blend of the old and new samples, so the reference stays continuous.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from engine.geometry import quat_from_matrix, smoothstep
from engine.gait.blending import (
    HEEL, MIN_MEMBER_WEIGHT, SWING_PHASES, TOE, WAYPOINT_PHASES, BlendedGait, ChannelLayout, StyleBanks,
)
from engine.gait.footsteps import (
    Foothold,
    SafeRegion,
    foothold_from_path,
    stance_offset,
    stance_offset_xy_yaw,
)
from engine.gait.heel_toe import ROLL_SMOOTHING
from engine.gait.path_frame import PathFrame, predict_xy_yaw
from engine.gait.phase_map import PHI_LTD, PHI_RLO, PHI_RTD
from engine.gait.style import SIDES, Style, StyleContext
from engine.gait.planner_kernels import (
    EDGE_CODES,
    PREVIEW_EVENT_PHASES,
    SWING_HEEL,
    SWING_TOE,
    evaluate_reference_into,
    pack_supports,
    path_table,
    preview_intervals,
    upcoming_foothold,
)
from engine.gait.velocity_sampler import SAMPLE_NAMES, sample_weight_list

PLANNER_RATE_HZ = 125.0
PREVIEW_S = 2.0
STYLE_FADE_S = 0.3
START_PHASE = PHI_RTD  # start in double support, right foot just down: the left lifts first
START_HOLD_S = 0.6  # the clock eases in over this time: a longer first double support to shift the weight
CONTACT_TOL_M = 1e-3
#: A stance foot pitched beyond this at a touchdown/liftoff transition rolls on its heel or toe edge [rad].
EDGE_CONTACT_PITCH_RAD = 0.02
#: Depth of the strip along a rolling sole edge that the MPC may plan the CoP on [m].
EDGE_SUPPORT_DEPTH_M = 0.02
TARGET_SETTLE_FRACTION = 0.4


@dataclass(slots=True)
class ContactPhase:
    """A support interval of the preview: which feet are down where, and the support polygon."""

    t_start_s: float
    t_end_s: float
    footholds: dict[str, Foothold]
    polygon: np.ndarray  # (M, 2) counter-clockwise


@dataclass(frozen=True)
class PlannerFeedback:
    """The controller's input to the planner each tick (paper §7.1, Gait Feedback), passed to
    :meth:`GaitPlanner.step` rather than written into planner fields.

    ``time_scaling`` is κ (> 1 speeds the gait up); ``step_adjustment_xy_m`` moves the upcoming
    foothold (world x, y); ``command_goal`` and ``command_rate_limits`` are the command preview:
    where the joystick is heading and how fast the command may change (m/s², m/s², rad/s²), so
    footholds ahead are planned along that ramp (None: today's command holds for the preview).
    ``recovery_share`` (0..1) is the robot's neutral gait's share in the blend while the controller recovers
    balance (engine/control/recovery_blend.py; 0: the style as authored).
    """

    time_scaling: float = 1.0
    step_adjustment_xy_m: np.ndarray | None = None
    command_goal: np.ndarray | None = None
    command_rate_limits: np.ndarray | None = None
    recovery_share: float = 0.0


@dataclass
class GaitReference:
    """The planner output r(t) of Eq. 2 with everything the controller and the studio need."""

    t_s: float
    phase: float  # cycles since start (integer part) + gait phase φ
    command: np.ndarray  # (3,) command after clamping [vx, vy, wz]
    sample_weights: np.ndarray  # (9,)
    path_pose: np.ndarray  # (3,) x, y, yaw
    pelvis_z: float
    pelvis_z_rate: float
    pelvis_rot: np.ndarray  # (3, 3)
    pelvis_ang_vel: np.ndarray  # (3,) world
    foot_pos: np.ndarray  # (2, 3) sole centres [left, right]
    foot_rot: np.ndarray  # (2, 3, 3)
    foot_lin_vel: np.ndarray  # (2, 3)
    foot_ang_vel: np.ndarray  # (2, 3)
    contact: np.ndarray  # (2,) bool: foot in its support phase
    corner_contact: np.ndarray  # (2, 4) bool: sole corner on the ground
    sole_corners: np.ndarray  # (2, 4, 3) world
    upper_q: np.ndarray  # (K,)
    upper_qd: np.ndarray  # (K,)
    footholds: dict[str, Foothold]  # current latched (stance) or target (swing) foothold per side
    preview: list[ContactPhase] = field(default_factory=list)
    cycle_s: float = 0.0
    swing_progress: np.ndarray = field(default_factory=lambda: np.zeros(2))

    @property
    def pelvis_quat(self) -> np.ndarray:
        return quat_from_matrix(self.pelvis_rot)

    def foot_quat(self, i: int) -> np.ndarray:
        return quat_from_matrix(self.foot_rot[i])


def _remaining_ease_delay(hold_s: float) -> float:
    """Extra time the slow start adds before future events: ∫ (1 − smoothstep) over the rest of the ease-in."""
    if hold_s <= 0.0:
        return 0.0
    u0 = 1.0 - hold_s / START_HOLD_S

    def antiderivative(u: float) -> float:  # ∫ (1 − 3u² + 2u³) du
        return u - u ** 3 + 0.5 * u ** 4

    return START_HOLD_S * (antiderivative(1.0) - antiderivative(u0))


_NO_FEEDBACK = PlannerFeedback()
_ROLL_SMOOTHING_SQ = ROLL_SMOOTHING ** 2  # (evaluate_reference_into's frame: Python's ** 2, once)
(_LEFT_LIFTOFF, _LEFT_TOUCHDOWN), (_RIGHT_LIFTOFF, _RIGHT_TOUCHDOWN) = SWING_PHASES["left"], SWING_PHASES["right"]
_NO_ROTS = np.zeros((3, 3, 3))  # evaluate's previous frames before the first tick (no rates)
_NO_POS = np.zeros((2, 3))
_NO_ADJUST = np.zeros(2)  # no step adjustment (x, y): _upcoming_foothold reads it, never writes it
_NO_ADJUST.flags.writeable = False
PATH_TABLE_STEP_S = 0.05
PATH_TABLE_HORIZON_S = 3.0


class GaitPlanner:
    """Stateful planner: ``reset`` once, then ``step`` at 125 Hz with the velocity command."""

    def __init__(self, style: Style, ctx: StyleContext, sole_length_m: float, sole_width_m: float):
        self.ctx = ctx
        self.sole_length_m = sole_length_m
        self.sole_width_m = sole_width_m
        hl, hw = 0.5 * sole_length_m, 0.5 * sole_width_m
        self.sole_corners_local = np.array([[hl, hw, 0.0], [hl, -hw, 0.0], [-hl, -hw, 0.0], [-hl, hw, 0.0]])
        self.region = SafeRegion.for_sole(sole_length_m, sole_width_m)
        self.preview_margin_m = 0.0  # shrink the preview's soles: the MPC plans the CoP this far inside
        self.preview_lateral_extra_m = 0.0  # ... and this much further inside the soles' sides
        self.preview_toe_trim_m = 0.0  # and this much shorter at the toe (what the ankles cannot hold)
        # Share (0..1) of a landed foot's deviation from its nominal foothold (step adjustment,
        # re-latching to where it really landed) that moves the path frame with it, so later
        # footholds are planned from the feet the robot stands on rather than a dead-reckoned path.
        self.path_follows_feet = 0.0
        # Command preview of the last step's PlannerFeedback: where the joystick is heading and how
        # fast the command may change. Footholds ahead are then planned along the ramp the command
        # will follow, not as if today's command held for the whole preview (None: it holds).
        self.command_goal: np.ndarray | None = None
        self.command_rate_limits: np.ndarray | None = None
        self._path_table: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._path_rows: tuple[np.ndarray, np.ndarray] | None = None  # (poses, vels) of the table: rows read one by one
        self._stances: tuple[BlendedGait, dict[str, tuple[float, float, float]]] | None = None
        self._preview_constants: tuple[BlendedGait, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._region_array: tuple[SafeRegion, np.ndarray] | None = None  # the preview's (side, front, cross, max yaw)
        # evaluate_reference_into's ``frame``: the sole's length and width, ROLL_SMOOTHING, its square (Python's
        # ** 2) and CONTACT_TOL_M (the sole's size is fixed for the planner's life, like sole_corners_local)
        self._frame = np.array([sole_length_m, sole_width_m, ROLL_SMOOTHING, _ROLL_SMOOTHING_SQ, CONTACT_TOL_M])
        self._attribute_row: tuple[BlendedGait, np.ndarray] | None = None  # evaluate's blend attributes
        # the last preview's phases and their packing for the CoM MPC (packed_supports)
        self._packed_preview: tuple[list[ContactPhase], np.ndarray, np.ndarray] | None = None
        self.layout = ChannelLayout(ctx.upper_joints, np.array([ctx.standing_angles[j] for j in ctx.upper_joints]))
        self.banks = StyleBanks(style, self.layout)
        self._fade_from: StyleBanks | None = None
        self._fade_elapsed_s = 0.0
        # The gait balance recovery blends toward (set_recovery_style) and its share in the blend.
        self.recovery_banks: StyleBanks | None = None
        self._recovery_style: Style | None = None
        self._recovery_is_style = False
        self.recovery_share = 0.0
        self.t_s = 0.0
        self.phi = START_PHASE
        self.path = PathFrame()
        self.command = np.zeros(3)
        self.command_clamped = False
        self.weights = np.zeros(len(SAMPLE_NAMES))
        self._weight_list: list[float] = self.weights.tolist()  # self.weights as floats (compared each tick)
        self.latched: dict[str, Foothold] = {}
        self.swing_start: dict[str, Foothold] = {}
        self.target: dict[str, Foothold] = {}
        self.blend: BlendedGait  # set by reset()
        self._blend_stale = True
        self.reset()

    @property
    def style(self) -> Style:
        return self.banks.style

    # ------------------------------------------------------------------ setup
    def reset(self, path_pose: np.ndarray | None = None, left: Foothold | None = None,
              right: Foothold | None = None) -> None:
        """Start standing in double support (right foot just touched down)."""
        pose = np.zeros(3) if path_pose is None else np.asarray(path_pose, dtype=float)
        self.path = PathFrame(*pose)
        self.t_s = 0.0
        self.phi = START_PHASE
        self.command = np.zeros(3)
        self._weight_list = sample_weight_list((0.0, 0.0, 0.0), self.style.velocities, self.style.blend_eta)
        self.weights = np.array(self._weight_list)
        self.recovery_share = 0.0
        self.blend = self._blend()
        self._blend_stale = True
        a = self.blend.attributes
        for side, given in (("left", left), ("right", right)):
            stance = stance_offset(side, a.stance_width_m, a.stance_splay_rad, a.stance_x_bias_m)
            self.latched[side] = given if given is not None else foothold_from_path(pose, stance)
        self.swing_start = dict(self.latched)
        self.target = dict(self.latched)
        self.landed = {side: False for side in SIDES}  # no touchdown transition before the first step
        self.hold_s = START_HOLD_S
        self._raw_target: dict[str, Foothold] = {}
        self._last_pose: dict | None = None  # the frames of the last evaluate() (backward-difference rates)

    def set_style(self, style: Style) -> None:
        """Switch to an edited style; the reference cross-fades to it over STYLE_FADE_S."""
        if style is self.style:
            return
        self._fade_from = self.banks
        self._fade_elapsed_s = 0.0
        self._blend_stale = True
        self.banks = StyleBanks(style, self.layout, previous=self.banks)
        self._recovery_is_style = self._same_gait(style, self._recovery_style)

    def set_recovery_style(self, style: Style | None) -> None:
        """The gait balance recovery blends toward (the robot's neutral style; None: no recovery blend).
        Its samples must carry the style's sample names (every valid style does)."""
        self._recovery_style = style
        self.recovery_banks = None if style is None else StyleBanks(style, self.layout)
        self._recovery_is_style = self._same_gait(self.style, style)
        self._blend_stale = True

    @property
    def recovers_toward_other_gait(self) -> bool:
        """Whether a recovery share changes the gait: a recovery style is set and the style walked is not it."""
        return self.recovery_banks is not None and not self._recovery_is_style

    @staticmethod
    def _same_gait(a: Style, b: Style | None) -> bool:
        """Whether walking ``a`` toward ``b`` changes nothing (the neutral style walked as itself: its blend stays
        bit for bit the style's, rather than equal to rounding)."""
        if b is None:
            return False
        from engine.gait.style import style_to_json_dict

        gait = ("velocities", "blend_eta", "samples")  # (not its name or description)
        da, db = style_to_json_dict(a), style_to_json_dict(b)
        return all(da.get(k) == db.get(k) for k in gait)

    # ------------------------------------------------------------------ helpers
    def _blend(self) -> BlendedGait:
        weights = self._weight_list
        members = [(w, self.banks.banks[n]) for w, n in zip(weights, SAMPLE_NAMES) if w > MIN_MEMBER_WEIGHT]
        if self._fade_from is not None:
            f = smoothstep(self._fade_elapsed_s / STYLE_FADE_S)
            old = [(w * (1 - f), self._fade_from.banks[n]) for w, n in zip(weights, SAMPLE_NAMES) if w > MIN_MEMBER_WEIGHT]
            members = [(w * f, b) for w, b in members] + old
        share = self.recovery_share
        if share > 0.0 and self.recovers_toward_other_gait:  # balance recovery: toward the neutral gait
            assert self.recovery_banks is not None  # (recovers_toward_other_gait says so)
            neutral = [(w * share, self.recovery_banks.banks[n]) for w, n in zip(weights, SAMPLE_NAMES) if w > MIN_MEMBER_WEIGHT]
            members = [(w * (1.0 - share), b) for w, b in members] + neutral
        return self.banks.blend(members)

    def clamp_command(self, v: np.ndarray) -> np.ndarray:
        """The command limited to the style's sample velocities (``command_clamped`` tells)."""
        out, self.command_clamped = self._clamped(v)
        return np.array(out)

    def _clamped(self, v: np.ndarray) -> tuple[list[float], bool]:
        """:meth:`clamp_command`'s floats (x, y, yaw) and whether any was clamped, per axis unrolled."""
        vel = self.style.velocities
        clamped = False
        value, lim = float(v[0]), vel.x_max_mps
        if not math.isfinite(value):
            value, clamped = 0.0, True
        x = lim if value > lim else (-lim if value < -lim else value)
        clamped |= x != value
        value, lim = float(v[1]), vel.y_max_mps
        if not math.isfinite(value):
            value, clamped = 0.0, True
        y = lim if value > lim else (-lim if value < -lim else value)
        clamped |= y != value
        value, lim = float(v[2]), vel.yaw_max_radps
        if not math.isfinite(value):
            value, clamped = 0.0, True
        yaw = lim if value > lim else (-lim if value < -lim else value)
        clamped |= yaw != value
        return [x, y, yaw], clamped

    def stance(self, side: str, blend: BlendedGait | None = None) -> np.ndarray:
        b = blend or self.blend
        return stance_offset(side, b.attribute("stance_width_m"), b.attribute("stance_splay_rad"),
                             b.attribute("stance_x_bias_m"))

    def _stance_xy_yaw(self, side: str) -> tuple[float, float, float]:
        """:meth:`stance` of the current blend as floats, kept while the blend is."""
        cached = self._stances
        if cached is None or cached[0] is not self.blend:
            b = self.blend
            width, splay, x_bias = (b.attribute("stance_width_m"), b.attribute("stance_splay_rad"),
                                    b.attribute("stance_x_bias_m"))
            cached = self._stances = (b, {s: stance_offset_xy_yaw(s, width, splay, x_bias) for s in SIDES})
        return cached[1][side]

    @staticmethod
    def in_swing(side: str, phi: float) -> bool:
        lo, hi = SWING_PHASES[side]
        f = phi - math.floor(phi)
        return lo <= f < hi

    # ------------------------------------------------------------------ stepping
    def step(self, dt_s: float, command: np.ndarray, feedback: PlannerFeedback | None = None,
             with_preview: bool = True) -> GaitReference:
        """Advance by ``dt_s`` under ``command`` and the controller's ``feedback`` (time scaling κ,
        step adjustment, command preview) and return r(t)."""
        fb = feedback or _NO_FEEDBACK
        kappa, step_adjustment_xy = fb.time_scaling, fb.step_adjustment_xy_m
        self.command_goal, self.command_rate_limits = fb.command_goal, fb.command_rate_limits
        clamped, self.command_clamped = self._clamped(command)
        self.command = np.array(clamped)
        share = fb.recovery_share
        if share != self.recovery_share:
            self.recovery_share = float(min(max(share, 0.0), 1.0)) if math.isfinite(share) else 1.0
            self._blend_stale = True
        style = self.style
        weights = sample_weight_list(clamped, style.velocities, style.blend_eta)  # (the command's floats)
        fading = self._fade_from is not None
        if fading:
            self._fade_elapsed_s += dt_s
            if self._fade_elapsed_s >= STYLE_FADE_S:
                self._fade_from = None
        if fading or self._blend_stale or weights != self._weight_list:  # (9 floats: np.array_equal's test)
            self._weight_list = weights
            self.weights = np.array(weights)
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
        f = self.phi - math.floor(self.phi)  # in_swing of both feet
        if _LEFT_LIFTOFF <= f < _LEFT_TOUCHDOWN:
            self._track_target("left", self._upcoming_foothold("left", adjust))
        if _RIGHT_LIFTOFF <= f < _RIGHT_TOUCHDOWN:
            self._track_target("right", self._upcoming_foothold("right", adjust))
        ref = self.evaluate(self.phi)
        if with_preview:
            ref.preview = self.preview(kappa)
        return ref

    def time_to_touchdown_s(self, side: str, kappa: float = 1.0) -> float | None:
        """Seconds until a swinging foot's touchdown at time-scaling κ (None when not swinging)."""
        if not self.in_swing(side, self.phi):
            return None
        lo, td = SWING_PHASES[side]
        k = math.floor(self.phi - lo)
        blend = self.blend
        return max(blend.event_time(k + td) - blend.time_at(self.phi), 0.0) / max(kappa, 1e-3)

    def nominal_target(self, side: str) -> Foothold:
        """The upcoming foothold of ``side`` without step adjustment."""
        return self._upcoming_foothold(side, _NO_ADJUST)

    def relatch(self, side: str, measured: Foothold, max_shift_m: float = 0.05) -> bool:
        """Move a support foot's latched foothold to where the foot actually landed.

        The contact preview (and so the CoM MPC) then plans on the real support; the
        reference of a foot flat on the ground is held by damping only, so nothing jumps.
        Refused (False) for swinging feet or implausible shifts.
        """
        if self.in_swing(side, self.phi):
            return False
        old = self.latched[side]
        if math.hypot(measured.x - old.x, measured.y - old.y) > max_shift_m:
            return False
        self.latched[side] = measured
        self._shift_path(measured.x - old.x, measured.y - old.y)
        if self._last_pose is not None:
            self._last_pose = None  # no spurious rates from the shift
        return True

    def path_ahead(self, dt_s: float) -> np.ndarray:
        """The path pose ``dt_s`` of gait time ahead, the command ramping toward ``command_goal``
        within ``command_rate_limits`` (exact arcs per piece of a 50 ms table)."""
        return np.array(self._path_pose_ahead(dt_s))

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
        path = self.path
        poses, vels = path_table(float(path.x), float(path.y), float(path.yaw),
                                 np.asarray(self.command, dtype=float), goal,
                                 np.asarray(command_rate_limits, dtype=float), PATH_TABLE_STEP_S, _PATH_TABLE_SIZE)
        return _PATH_TABLE_TIMES, poses, vels

    def _shift_path(self, dx_m: float, dy_m: float) -> None:
        """Move the path frame by ``path_follows_feet`` × (dx, dy)."""
        gain = self.path_follows_feet
        if gain > 0.0 and math.isfinite(dx_m) and math.isfinite(dy_m):
            self.path.x += gain * dx_m
            self.path.y += gain * dy_m

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

    def _contact_midpoint_phase(self, side: str, phi: float) -> tuple[float, float]:
        """(touchdown φ, next liftoff φ) of the contact that follows the current/next swing."""
        lo, td = SWING_PHASES[side]
        k = math.floor(phi - lo)
        return k + td, k + 1 + lo

    def _upcoming_foothold(self, side: str, adjust_xy: np.ndarray) -> Foothold:
        """The foothold of the contact after ``side``'s current or next swing: the path pose at that contact's
        middle (along the command ramp's path table) ⊕ the stance offset, moved by ``adjust_xy`` (world x, y),
        projected to the safe region beside the other foot. One compiled call
        (:func:`engine.gait.planner_kernels.upcoming_foothold`, the preview's predicted footholds with the step
        adjustment: the same numbers as the Python it replaced, kept in tests/gait/test_planner_speed_references.py)."""
        stances, _, _, events = self._blend_constants()
        left = side == "left"
        support = self.latched["right" if left else "left"]
        adjust_x, adjust_y = adjust_xy.tolist()
        x, y, yaw = upcoming_foothold(0 if left else 1, float(self.phi), float(self.blend.time_at(self.phi)), events,
                                      float(support.x), float(support.y), float(support.yaw), stances,
                                      *self._path_table_args(), PATH_TABLE_STEP_S, self._region_values(), 2.0,
                                      adjust_x, adjust_y)
        return Foothold(x, y, yaw)

    def _path_table_args(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The compiled kernels' path table (times, poses, velocities): this tick's table along the command ramp, or
        one piece at the path pose with the command while the command holds (no goal)."""
        if self.command_goal is None or self.command_rate_limits is None:  # the command holds: one piece
            path = self.path
            return (_ONE_PIECE_TIMES, np.array([[float(path.x), float(path.y), float(path.yaw)]]),
                    np.asarray(self.command, dtype=float).reshape(1, 3))
        return self._path_table_now()

    def _region_values(self) -> np.ndarray:
        """The safe region as the kernels read it (side, front, cross, max yaw), kept while the region is."""
        region = self.region
        if self._region_array is None or self._region_array[0] is not region:
            self._region_array = (region, np.array([region.side_m, region.front_m, region.cross_m, region.max_yaw_rad]))
        return self._region_array[1]

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, phi: float) -> GaitReference:
        """r at phase φ for the current state. Rates are backward differences over the last tick
        (the controller interpolates between ticks with them). The blended channels, the soles' swing or stance
        parameters and the frames (pelvis and sole rotations, sole positions and corners, their rates) are one
        compiled call (:func:`engine.gait.planner_kernels.evaluate_reference_into`) writing into new arrays."""
        blend = self.blend
        merged = blend.merged
        t = blend.time_at(phi)
        f = phi - math.floor(phi)  # in_swing of both feet
        swing_left, swing_right = _LEFT_LIFTOFF <= f < _LEFT_TOUCHDOWN, _RIGHT_LIFTOFF <= f < _RIGHT_TOUCHDOWN
        # per side (swing start, target) while swinging, else (latched, latched): (2, 2, 3) float64, one array call
        la, lb = (self.swing_start["left"], self.target["left"]) if swing_left else (self.latched["left"],) * 2
        ra, rb = (self.swing_start["right"], self.target["right"]) if swing_right else (self.latched["right"],) * 2
        feet = np.array([[[la.x, la.y, la.yaw], [lb.x, lb.y, lb.yaw]], [[ra.x, ra.y, ra.yaw], [rb.x, rb.y, rb.yaw]]],
                        dtype=float)
        prev = self._last_pose
        if prev is not None:
            dt = self.t_s - prev["t"]
            prev_rots, prev_foot_pos, prev_pelvis_z, prev_upper = (prev["rots"], prev["foot_pos"], prev["pelvis_z"],
                                                                   prev["upper"])
        else:
            dt, prev_rots, prev_foot_pos, prev_pelvis_z, prev_upper = 0.0, _NO_ROTS, _NO_POS, 0.0, None
        n_upper = merged.n_cycle - 4
        if prev_upper is None:
            prev_upper = np.zeros(n_upper)
        assert prev_upper.shape[0] == n_upper, "the upper-body channels are fixed per planner (its StyleContext)"
        rots, foot_pos, corners = np.empty((3, 3, 3)), np.empty((2, 3)), np.empty((2, 4, 3))
        corner_contact, ang, lin = np.empty((2, 4), dtype=np.bool_), np.empty((3, 3)), np.empty((2, 3))
        upper, upper_qd, progress, scalars = np.empty(n_upper), np.empty(n_upper), np.empty(2), np.empty(2)
        evaluate_reference_into(
            float(phi), t, blend.events_array, blend.weights, WAYPOINT_PHASES, merged.phase_segments, merged.cycles,
            merged.member_of_row, merged.offset, merged.periodic, merged.period, merged.hi, merged.search, merged.t0,
            merged.coef, merged.n_cycle, float(self.path.yaw), self._frame, feet,
            np.array([swing_left, swing_right]), np.array([self.landed["left"], self.landed["right"]]),
            blend.boundary_pitch_array, self._blend_attributes(), self.sole_corners_local, prev is not None, dt,
            prev_rots, prev_foot_pos, prev_pelvis_z, prev_upper, 2.0, rots, foot_pos, corners, corner_contact, ang,
            lin, upper, upper_qd, progress, scalars)
        pelvis_z = scalars[0]
        # (the soles' rotations are rots[1:], their positions foot_pos: rows left, right)
        self._last_pose = {"t": self.t_s, "pelvis_z": pelvis_z, "rots": rots, "foot_pos": foot_pos, "upper": upper}
        return GaitReference(  # (positional: the field order, t_s … swing_progress; keywords cost more per tick)
            self.t_s, phi, self.command.copy(), self.weights.copy(), self.path.pose(), pelvis_z,
            0.0 if prev is None or dt <= 0 else scalars[1], rots[0], ang[0], foot_pos.copy(), rots[1:], lin, ang[1:],
            np.array([not swing_left, not swing_right]), corner_contact, corners, upper, upper_qd,
            {"left": self.target["left"] if swing_left else self.latched["left"],  # (SIDES' order)
             "right": self.target["right"] if swing_right else self.latched["right"]},
            [], blend.events_s[3], progress,
        )

    def _blend_attributes(self) -> np.ndarray:
        """:func:`evaluate_reference_into`'s ``attributes`` of the current blend (pelvis height, touchdown and
        liftoff transitions [s]), kept while the blend is."""
        cached = self._attribute_row
        if cached is None or cached[0] is not self.blend:
            b = self.blend
            cached = self._attribute_row = (b, np.array([b.attribute("pelvis_height_m"),
                                                         b.attribute("touchdown_transition_s"),
                                                         b.attribute("liftoff_transition_s")]))
        return cached[1]

    # ------------------------------------------------------------------ preview for the MPC
    def preview(self, kappa: float = 1.0, horizon_s: float = PREVIEW_S) -> list[ContactPhase]:
        """Support intervals over the next ``horizon_s``: timings, footholds, polygons.

        From now over the contact events ahead: the feet stand where they stand (a swinging foot on its
        target), a foot that touches down later lands on its predicted foothold (the path at the middle of
        that contact ⊕ its stance offset, in the safe region of the other foot). One foot down: its sole,
        shortened at the toe by what the ankle cannot hold; both: the hull of both soles, the one of a foot
        rolling on its heel or toe (heel strike after its touchdown, toe-off before its liftoff) cut to that
        edge's strip. Compiled (:func:`engine.gait.planner_kernels.preview_intervals`; the same supports packed for the
        CoM MPC by :func:`~engine.gait.planner_kernels.pack_supports`, read through :meth:`packed_supports`)."""
        blend = self.blend
        phi = self.phi
        f = phi - math.floor(phi)  # in_swing of both feet
        swing_left, swing_right = _LEFT_LIFTOFF <= f < _LEFT_TOUCHDOWN, _RIGHT_LIFTOFF <= f < _RIGHT_TOUCHDOWN
        left = self.target["left"] if swing_left else self.latched["left"]
        right = self.target["right"] if swing_right else self.latched["right"]
        landed = self.landed
        stances, touchdown_edges, liftoff_edges, events = self._blend_constants()
        times, rows, holds, polygons = preview_intervals(
            float(phi), float(blend.time_at(phi)), float(kappa), _remaining_ease_delay(self.hold_s), float(horizon_s),
            events, np.array([[left.x, left.y, left.yaw], [right.x, right.y, right.yaw]], dtype=float),
            np.array([swing_left, swing_right]), self._edges_now(), np.array([landed["left"], landed["right"]]),
            touchdown_edges, liftoff_edges, stances,
            *self._path_table_args(), PATH_TABLE_STEP_S, self._region_values(),
            self.sole_length_m - 2.0 * self.preview_margin_m,
            self.sole_width_m - 2.0 * (self.preview_margin_m + self.preview_lateral_extra_m),
            self.preview_toe_trim_m, EDGE_SUPPORT_DEPTH_M, 2.0)
        footholds = [left, right] + [Foothold(x, y, yaw) for x, y, yaw in holds[2:].tolist()]
        polygons.flags.writeable = False  # the phases' polygons are views of it
        t_s = self.t_s
        phases: list[ContactPhase] = []
        append = phases.append
        for i, ((t0, t1), (down_left, down_right, i_left, i_right, m)) in enumerate(zip(times.tolist(),
                                                                                       rows.tolist())):
            on = {"left": footholds[i_left], "right": footholds[i_right]} if down_left and down_right else (
                {"left": footholds[i_left]} if down_left else {"right": footholds[i_right]})
            append(ContactPhase(t_s + t0, t_s + t1, on, polygons[i, :m]))  # (one view per phase)
        self._packed_preview = (phases, *pack_supports(t_s, times, rows, polygons))
        return phases

    def packed_supports(self, phases: object) -> tuple[np.ndarray, np.ndarray] | None:
        """The CoM MPC's packed supports (``ComMpc.solve``'s ``packed``: per phase its start, end [s] and vertex count
        (n, 3), the polygons' vertices one after the other) of ``phases`` when they are this planner's last preview
        (the same object: :func:`engine.gait.planner_kernels.pack_supports` packed them with it), else None."""
        packed = self._packed_preview
        if packed is None or packed[0] is not phases:
            return None
        return packed[1], packed[2]

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


_PATH_TABLE_TIMES = np.arange(int(math.ceil(PATH_TABLE_HORIZON_S / PATH_TABLE_STEP_S)) + 1) * PATH_TABLE_STEP_S
_PATH_TABLE_TIMES.flags.writeable = False
_PATH_TABLE_TIMES_LIST = _PATH_TABLE_TIMES.tolist()
_PATH_TABLE_SIZE = len(_PATH_TABLE_TIMES_LIST)
_ONE_PIECE_TIMES = np.zeros(1)  # the preview's path table while the command holds
assert tuple(PREVIEW_EVENT_PHASES) == (0.0, PHI_LTD, PHI_RLO, PHI_RTD)
assert (SWING_HEEL, SWING_TOE) == (HEEL, TOE)


def _pitched_edge(heel_pitch: float, toe_pitch: float) -> str | None:
    """The sole edge a foot at (ψ_heel, ψ_toe) stands on: the heel when the toe is up (ψ_heel < 0),
    the toe when the heel is up (ψ_toe > 0), None when it is (nearly) flat."""
    if heel_pitch < -EDGE_CONTACT_PITCH_RAD:
        return "heel"
    if toe_pitch > EDGE_CONTACT_PITCH_RAD:
        return "toe"
    return None
