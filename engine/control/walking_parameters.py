"""The walking controller's tuning: one typed parameter set per robot (as placo's HumanoidParameters).

Defaults are G1's; ``robots/<name>.toml`` overrides fields in ``[control.walking]`` (names are
checked: an unknown one is a config error naming the file and field).
"""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass

from engine.robot.config import RobotConfig, RobotConfigError, load_robot_config


@dataclass(frozen=True)
class WalkingParameters:
    """Every number of :class:`engine.control.walking_controller.WalkingController` that is tuned."""

    # Joystick rate limits (m/s², m/s², rad/s²): G1 cannot accelerate its gait faster.
    command_accel_limits: tuple[float, float, float] = (0.25, 0.3, 1.5)
    # Re-latch a landed foot this many planner ticks (16 ms) after touchdown.
    relatch_after_plan_ticks: int = 2
    # The MPC plans the CoP this far inside the soles (headroom for the whole-body QP).
    cop_margin_m: float = 0.01
    # ... and this much further inside the soles' sides (0: the same margin all round). A robot whose ankle roll
    # range is small (G1 ±0.26 rad) cannot hold a CoP near the sole's side edge once the leg tilts: the plan keeps
    # the lateral CoP nearer the sole's middle and leaves the rest to the whole-body controller.
    cop_lateral_extra_margin_m: float = 0.0
    # LIP height: low-pass of the measured CoM height per planner tick (≈ 0.16 s time constant).
    com_z_filter: float = 0.05
    # A plan whose final capture point misses the last support by more is re-anchored.
    capture_tolerance_m: float = 0.1
    # The path frame moves with step adjustments and re-latched footholds (share 0..1).
    path_follows_feet: float = 1.0
    # A step moves at most this far from its nominal foothold.
    max_step_adjust_m: float = 0.35
    # ... sideways at most this far outward of ξ (with ξ running toward the stance foot, land near it)
    lateral_xi_max_out_m: float = 0.15
    # ... and at least this far outward of ξ at touchdown (it must move ξ back in).
    lateral_xi_inset_m: float = 0.03
    # ξ this far beyond the stance foot's outer edge hurries the gait (inf: never).
    lateral_capture_margin_m: float = 0.0
    # While the push observer sees a push, single and double supports run at the time scaling's upper
    # bound (the steps that catch a pushed ξ land sooner; the ξ error the κ law reads is small after a plan restart).
    hurry_while_pushed: bool = False
    # Push observer: response time and the force per kg below which model errors hide pushes.
    observer_time_constant_s: float = 0.08
    observer_deadband_n_per_kg: float = 0.25
    # The observer holds over this last share of a swing and this many planner ticks after touchdown.
    observer_hold_swing_share: float = 0.15
    observer_hold_after_touchdown_plan_ticks: int = 5
    # At most this growth of the measured ξ error is expected by touchdown; errors below the
    # deadband are left to the MPC (a push is larger).
    dcm_error_growth_cap: float = 2.5
    dcm_error_deadband_m: float = 0.04
    # Where a swing foot's ξ at touchdown comes from: the MPC plan's ξ plus the grown error against
    # the plan (False, and always when undisturbed; a plan restart hides the error), or, under a push,
    # the robot's measured ξ (less the push's shift) diverging from the best CoP on the stance foot for
    # the time left (True: the standard DCM step adjustment, from the foot the robot stands on) ...
    capture_from_stance_foot: bool = False
    # ... while the observer sees a push and this long after (undisturbed, the plan's ξ, whose CoP rolls
    # heel to toe, places the steps: the stance-foot prediction holds the CoP still and differs a little).
    stance_capture_after_push_s: float = 3.0
    # With it, a step lands at most this far sideways outward / fore-aft from the stance foot (in the
    # path frame; the legs' reach) instead of max_step_adjust_m from the nominal foothold.
    max_step_width_m: float = 0.45
    max_step_length_m: float = 0.45
    # Share of the CoP's reach a step may rely on (rest: margin for tracking), and while pushed.
    step_reach_share: float = 0.8
    pushed_reach_share: float = 0.25
    # Restart the MPC when ξ leaves the double support polygon (off: a 50 N side push while
    # walking at 0.15 m/s fell with it, recorded).
    restart_when_thrown: bool = False
    # Per axis, the swing feet's feed-forward acceleration (the difference of consecutive reference rates)
    # is limited to this. A step adjustment moves a swing target mid-swing, and the twice-differenced jump
    # (a few mm over 8 ms planner ticks) gave accelerations of 100+ m/s² whose reaction moved the CoM velocity,
    # hence the next adjustment: G1 casual stopping in the sweep ran into a period-2 limit cycle, ±230 N
    # sideways at the stance foot, 2.17 mm stance slip. The nominal swings' own accelerations (≤ 35 m/s²
    # on G1) stay below it, and so do a capture step's after a push (40 made a 1.5 N/kg push from the left
    # on standing G1 carry it 0.74 m instead of 0.25 m). README "Swing feed-forward limit".
    swing_feedforward_limit_mps2: float = 80.0
    # A descending swing foot this low may touch down early, and its corners this close to the floor carry load.
    landing_height_m: float = 0.01
    touchdown_height_m: float = 0.001
    # ... and so may one whose planned sole's lowest corner is below this (0: off): a foot planned heel- or toe-down
    # reaches the floor with its centre still 10-20 mm up (issue 13, README "Why the swing foot meets the floor early").
    landing_corner_height_m: float = 0.0
    # A foot on the ground whose sole is rolled about its long axis so that one side's corners stand this much
    # higher than the other side's (measured, forward kinematics each tick) stands on its lower edge only: the QP
    # may push on those corners alone (0: off, the plan's corners). G1's ankle roll reaches ±0.26 rad; when the
    # leg tilts further the foot rolls onto its edge and the QP, still counting on the whole sole, plans a CoP it
    # cannot get (issue 13, the sideways falls of random styles).
    rolled_foot_edge_lift_m: float = 0.0
    # Vertical load (× m g) a single-support ankle must hold the CoP under (the MPC's toe trim).
    ankle_load_factor: float = 1.15
    # Per planner tick, how far the MPC's initial CoM state moves toward the estimate (paper: 0).
    mpc_state_pull: float = 0.0
    # The CoM MPC's preview (paper: 2 s).
    mpc_preview_s: float = 2.0
    # The CoM MPC is solved every this many planner ticks (paper: 1, at the planner's 125 Hz);
    # between solves the whole-body controller follows the last plan, a function of time.
    mpc_every_plan_ticks: int = 1
    # Balance recovery (engine/control/recovery_blend.py, issue 13): while the measured ξ is this far off the
    # MPC plan's, the planner blends the style toward the robot's neutral style (robots/<name>.toml
    # ``default_style``), fully neutral at ``recovery_full_xi_error_m``; the style's share comes back once the
    # error has stayed below for ``recovery_hold_s``, over ``recovery_decay_s``. The share rises 0 → 1 in
    # ``recovery_rise_s`` and moves in steps of ``recovery_share_step`` (each step re-blends the gait). inf: off.
    recovery_xi_error_m: float = float("inf")
    recovery_full_xi_error_m: float = 0.10
    # ... and while the step adjustment is this large (m; from the nominal footholds of the gait being walked: the
    # robot does not go where the gait steps, and the MPC, re-planning from the robot each tick, keeps ξ near its
    # plan), fully neutral at ``recovery_full_step_adjust_m``. inf: the step adjustment does not count.
    recovery_step_adjust_m: float = float("inf")
    recovery_full_step_adjust_m: float = 0.3
    # ... and while the measured CoM stands this far outside the double support the reference holds (the convex hull
    # of both feet's grounded sole corners; a style that lands a foot on its toe with the body behind it), fully
    # neutral at ``recovery_full_support_outside_m``. Counted only while the reference holds both feet on the ground
    # (in single support the CoM is outside the foot by design). inf: it does not count.
    # It counts once the CoM has stood beyond ``recovery_support_outside_m`` for ``recovery_support_outside_for_s``
    # without a break: touchdowns and liftoffs pass through thin supports for a few hundredths of a second.
    recovery_support_outside_m: float = float("inf")
    recovery_full_support_outside_m: float = 0.06
    recovery_support_outside_for_s: float = 0.1
    recovery_rise_s: float = 0.1
    recovery_hold_s: float = 0.5
    recovery_decay_s: float = 1.5
    recovery_share_step: float = 0.05
    # Walking starts in the neutral gait (share 1 from reset), held this long before the ordinary hold and decay
    # hand over to the style (0: the style from the first step). The robot finds its feet in the gait its
    # controller is tuned on, then eases into the style: the first forward steps of a style whose posture is far
    # from standing (the robot's standing pose) otherwise lag the CoM plan and walk backward (issue 13, stop 36).
    recovery_start_neutral_s: float = 0.0
    # From a reset the reference's posture (pelvis height, roll and pitch, upper-body joints) eases from the pose the
    # robot stands in into the style's over this time (engine/gait/start_settle.py; 0: the style's posture from the
    # first tick, which the whole-body controller meets in one jump).
    start_settle_s: float = 0.0

    @classmethod
    def for_robot(cls, name: str) -> WalkingParameters:
        """The defaults with robot ``name``'s ``[control.walking]`` table applied."""
        return cls.from_config(load_robot_config(name))

    @classmethod
    def from_config(cls, cfg: RobotConfig) -> WalkingParameters:
        """The defaults with ``cfg.walking`` (the ``[control.walking]`` table) applied."""
        overrides = dict(cfg.walking)
        known = {f.name: f for f in dataclasses.fields(cls)}
        values: dict[str, object] = {}
        for key, value in overrides.items():
            if key not in known:
                close = difflib.get_close_matches(key, sorted(known), n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise RobotConfigError(f"{cfg.path.name}: control.walking.{key}: unknown WalkingParameters field{hint}")
            default = getattr(cls, key)
            if isinstance(default, tuple):
                if not isinstance(value, (list, tuple)) or len(value) != len(default):
                    raise RobotConfigError(f"{cfg.path.name}: control.walking.{key}: expected a list of "
                                           f"{len(default)} numbers, got {value!r}")
                values[key] = tuple(float(v) for v in value)
            elif isinstance(default, bool):
                if not isinstance(value, bool):
                    raise RobotConfigError(f"{cfg.path.name}: control.walking.{key}: expected true or false, got {value!r}")
                values[key] = value
            elif isinstance(default, int):
                if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                    raise RobotConfigError(f"{cfg.path.name}: control.walking.{key}: expected a non-negative integer, "
                                           f"got {value!r}")
                values[key] = value
            else:
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise RobotConfigError(f"{cfg.path.name}: control.walking.{key}: expected a number, got {value!r}")
                values[key] = float(value)
        return cls(**values)  # type: ignore[arg-type]
