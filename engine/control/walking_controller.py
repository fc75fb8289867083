"""The walking controller: the paper's control stack in the simulation's controller slot.

Per 500 Hz tick: estimator → (every 4th tick, 125 Hz: gait feedback → sampler/planner →
CoM MPC) → task-space inverse dynamics → joint servo set-points. Between planner ticks the
reference is extrapolated with its rates and the CoM follows the MPC's exact trajectory.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from engine.constants import GRAVITY_MPS2
from engine.control.mpc import ComMpc, ComMpcSolution, SupportInterval, SupportPhase
from engine.control.controller import JointCommand, RobotState
from engine.control.reference_kernels import interpolate_reference, interpolate_references
from engine.control.disturbance_observer import ExternalForceObserver
from engine.control.estimation import StateEstimator
from engine.control.estimation.quaternion import wxyz_from_xyzw
from engine.control.gait_feedback import FeedbackOutput, GaitFeedback, GaitFeedbackGains
from engine.control.wbc import TaskSpaceInverseDynamics, WbcReference, WholeBodyController
from engine.control.wbc.reference import N_BASIS, N_CORNERS
from engine.control.foot_geometry import toe_trim_m
from engine.control.recovery_blend import RecoveryBlend
from engine.control.step_adjustment import StepAdjustment
from engine.control.walking_parameters import WalkingParameters
from engine.control.touchdown import TouchdownTracker
from engine.control.walking_telemetry import WalkingTelemetry, update_telemetry
from engine.gait.footsteps import Foothold
from engine.gait.start_settle import StartPose, StartSettle
from engine.gait.support_edges import outside_support_m
from engine.geometry.polygon import clip_into_polygon, halfplanes_cached
from engine.geometry.rotation import matrix_from_quat
from engine.geometry.vector import vector_norm
from engine.gait.offline_plan import planner_for
from engine.gait.planner import PLANNER_RATE_HZ, GaitReference, PlannerFeedback
from engine.gait.style import SIDES, Style, StyleContext
from engine.robot.model import RobotModel
from engine.sim import CONTROL_PERIOD_S

TICKS_PER_PLAN = int(round(1.0 / (PLANNER_RATE_HZ * CONTROL_PERIOD_S)))  # 4
PLAN_DT_S = TICKS_PER_PLAN * CONTROL_PERIOD_S
# The time since the planner's tick of each control tick until its next (compute's dt_since) → the tick's index k
_TICK_OF_DT = {k * CONTROL_PERIOD_S: k for k in range(TICKS_PER_PLAN)}
_ZEROS3 = (0.0, 0.0, 0.0)  # a foot in contact's feed-forward row


@dataclass(slots=True)
class StepTimings:
    """Wall-clock cost of each stage (s) in the last tick; None when the stage did not run."""

    planner: float | None = None
    mpc: float | None = None
    wbc: float | None = None
    estimator: float | None = None


class WalkingController:
    """Walks a biped in a style, steered by a velocity command."""

    name = "walking"

    def __init__(self, robot: RobotModel, style: Style, wbc: str = "paper", state_source: str = "truth",
                 feedback: bool = True, ctx: StyleContext | None = None, params: WalkingParameters | None = None):
        if robot.kind != "biped":
            raise ValueError(f"{robot.name} is a {robot.kind}: the walking controller needs a biped")
        self.robot = robot
        self.params = params or WalkingParameters.for_robot(robot.name)
        self._command_accel_limits = np.array(self.params.command_accel_limits, dtype=float)
        self.ctx = ctx or StyleContext.for_robot(robot.name)
        self.style = style
        self.planner = planner_for(robot, style, self.ctx)
        self.planner.preview_margin_m = self.params.cop_margin_m
        self.planner.preview_lateral_extra_m = self.params.cop_lateral_extra_margin_m
        self.planner.preview_toe_trim_m = toe_trim_m(robot, self.params.cop_margin_m, self.params.ankle_load_factor)
        self.planner.path_follows_feet = self.params.path_follows_feet
        self.mpc = ComMpc(preview_s=self.params.mpc_preview_s)
        self.feedback = GaitFeedback(GaitFeedbackGains.for_robot(robot.name), enabled=feedback)
        self.wbc: WholeBodyController
        if wbc == "paper":
            self.wbc = TaskSpaceInverseDynamics(robot, upper_body_joints=self.ctx.upper_joints)
        elif wbc == "placo":
            from engine.control.wbc.placo_peer import PlacoWbc

            self.wbc = PlacoWbc(robot, upper_body_joints=self.ctx.upper_joints)
        else:
            raise ValueError(f"wbc: expected 'paper' or 'placo', got {wbc!r}")
        self.wbc_name = wbc
        self.estimator = StateEstimator(robot, mode="estimated" if state_source == "estimated" else "truth")
        self.observer = ExternalForceObserver(robot.mass_kg, time_constant_s=self.params.observer_time_constant_s,
                                              deadband_n_per_kg=self.params.observer_deadband_n_per_kg)
        self._mpc_shift = np.zeros(2)  # the MPC plans in a frame shifted by −f_ext/(m ω²)
        self._landing = False  # a foot is landing: the observer holds
        self.state_source = state_source
        self.model = robot.pin_model
        self.data = self.model.createData()
        self._vcom_view = self.data.vcom[0]  # (3,) a view of data's memory, updated in place by centerOfMass
        # the whole-body controller's dynamics pass, shared with this tick's CoM (TaskSpaceInverseDynamics.snapshot)
        self._wbc_snapshot = getattr(self.wbc, "snapshot", None)
        data = self.model.createData()
        self.com_offset_m = float(pin.centerOfMass(self.model, data, robot.q_standing)[2] - robot.q_standing[2])
        self.command = np.zeros(3)
        self.command_filtered = np.zeros(3)
        self.tick = 0
        self._plan_ticks = 0
        self.replans = 0
        self.ref: GaitReference | None = None
        self.plan: ComMpcSolution | None = None
        self._plan_t0 = 0.0
        self.estimate: RobotState | None = None
        self.timings = StepTimings()
        self._telemetry = WalkingTelemetry()
        self._telemetry_stale = False
        self._last_com = np.zeros(2)
        self._last_fb: FeedbackOutput | None = None
        self._pending_style: Style | None = None
        self.touchdown = TouchdownTracker(robot, self.model, self.data)
        self.wbc_contact = np.ones((2, 4), dtype=bool)
        self.step_adjustment = StepAdjustment(robot, self.params, self.planner, self.feedback.gains,
                                              robot.q_standing[2] + self.com_offset_m)
        self.start_settle = StartSettle(self.params.start_settle_s)
        self._upper_q_index = np.array([7 + robot.joint_names.index(j) for j in self.ctx.upper_joints], dtype=np.intp)
        self.recovery = RecoveryBlend(self.params)
        if self.recovery.enabled:  # (without a neutral style that loads, the planner never recovers toward one)
            self.planner.set_recovery_style(self._neutral_style())

    def _neutral_style(self) -> Style | None:
        """The robot's neutral style (robots/<name>.toml ``default_style``), the gait balance recovery blends
        toward; None when the robot has none that loads (then there is no recovery blend)."""
        from engine.gait.style import StyleError, load_style, styles_dir

        name = self.robot.config.default_style
        if not name:
            return None
        try:
            return load_style(styles_dir(self.robot.name) / f"{name}.json", self.ctx, expected_robot=self.robot.name)
        except (OSError, StyleError, ValueError):
            return None

    # ------------------------------------------------------------------ inputs
    def set_command(self, v: np.ndarray) -> None:
        self.command = np.asarray(v, dtype=float).copy()

    def set_style(self, style: Style) -> None:
        """Live edit: the planner cross-fades to the new style."""
        self.style = style
        self.planner.set_style(style)

    # ------------------------------------------------------------------ lifecycle
    def reset(self, state: RobotState) -> None:
        q = state.q
        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, q)
        feet = []
        for side in SIDES:
            m = data.oMf[self.model.getFrameId(f"{side}_foot")]
            feet.append(Foothold(float(m.translation[0]), float(m.translation[1]),
                                 float(math.atan2(m.rotation[1, 0], m.rotation[0, 0]))))
        base_yaw = math.atan2(2 * (q[6] * q[5] + q[3] * q[4]), 1 - 2 * (q[4] ** 2 + q[5] ** 2))
        mid = 0.5 * (np.array([feet[0].x, feet[0].y]) + np.array([feet[1].x, feet[1].y]))
        self.planner.reset(np.array([mid[0], mid[1], base_yaw]), feet[0], feet[1])
        self.estimator.reset(state)
        self.wbc.reset(state)
        self.feedback.reset()
        self.recovery.reset()
        pelvis_rot = matrix_from_quat(np.array(wxyz_from_xyzw(q[3:7])))  # (pinocchio's q: x, y, z, w)
        self.start_settle.reset(StartPose.from_state(float(q[2]), pelvis_rot, q[self._upper_q_index]))
        self.mpc.reset()
        self.command_filtered = np.zeros(3)
        self.tick = 0
        self._plan_ticks = 0
        self.ref = None
        self.plan = None
        self.touchdown.reset()
        # The references of the control ticks until the planner's next one (_interpolate_ticks), per (ref, plan)
        self._reference_batch: tuple = (None, None)
        self._foot_acc = np.zeros((2, 3))
        self._foot_ang_acc = np.zeros((2, 3))
        self._landing = False
        self._com_z: float | None = None  # the LIP height, low-passed (set on the first MPC tick)
        com = pin.centerOfMass(self.model, data, q, state.v)
        self._init_com = (com[:2].copy(), np.zeros(2), mid.copy())
        self.observer.reset(data.vcom[0][:2].copy())
        self._mpc_shift = np.zeros(2)
        self.step_adjustment.reset()
        self._ground_force: np.ndarray | None = None  # horizontal ground force of the last WBC tick

    # ------------------------------------------------------------------ one tick
    def compute(self, state: RobotState) -> JointCommand:
        t_start = time.perf_counter()
        if self.state_source == "estimated":
            contact = self.ref.contact if self.ref is not None else np.ones(2, dtype=bool)
            est = self.estimator.update(state.t_s, getattr(state, "imu", None), state.q[7:], state.v[6:], contact, truth=state)
        else:
            est = state
        self.estimate = est
        # The CoM and its velocity of this state: from the whole-body controller's dynamics pass of this tick when it
        # has one (CCRBA's CoM and momentum; its compute() below reuses the pass), else pinocchio's centerOfMass
        # (a copy of data.com[0]; data.vcom[0] read through a view of data's memory taken once). The pass's time
        # counts in timings.estimator, and the whole-body controller's pinocchio_s reads ≈ 0 when it is reused.
        snapshot = self._wbc_snapshot(est.q, est.v) if self._wbc_snapshot is not None else None
        if snapshot is not None:
            self._com_now = (snapshot.com_m.copy(), snapshot.momentum[:3] / snapshot.mass_kg)
        else:
            self._com_now = (pin.centerOfMass(self.model, self.data, est.q, est.v), self._vcom_view.copy())
        # Around a landing the ground force is an impact the QP did not plan: the observer holds
        # (planned landings, and a swing foot already on the ground early).
        early = self.ref is not None and self.touchdown.early_now(self.wbc_contact, self.ref.contact)
        self.observer.update(CONTROL_PERIOD_S, self._com_now[1][:2],
                             None if (self._landing or early) else self._ground_force)
        t_est = time.perf_counter()
        self.timings = StepTimings(None, None, None, t_est - t_start)  # (positional: planner, mpc, wbc, estimator)
        if self.tick % TICKS_PER_PLAN == 0:
            self._plan_tick(est)
        dt_since = (self.tick % TICKS_PER_PLAN) * CONTROL_PERIOD_S
        t_wbc = time.perf_counter()
        reference = self._wbc_reference(dt_since)
        reference.contact = self.touchdown.with_early_touchdown(est, reference, self.ref, self.params)
        if self.params.rolled_foot_edge_lift_m > 0.0:
            reference.contact = self.touchdown.on_rolled_edges(est, reference.contact, self.params.rolled_foot_edge_lift_m)
        self.wbc_contact = reference.contact
        reference.external_wrench = self._external_wrench(est)
        cmd = self.wbc.compute(est, reference)
        self._ground_force = _horizontal_ground_force(self.wbc.diagnostics)
        self.timings.wbc = time.perf_counter() - t_wbc
        self.tick += 1
        return cmd

    def _outside_support_m(self, com_xy: np.ndarray) -> float:
        """How far the measured CoM stands outside the double support the reference holds (m; 0 inside, in single
        support, or where the robot does not count it: ``recovery_support_outside_m`` inf)."""
        ref = self.ref
        if not math.isfinite(self.params.recovery_support_outside_m) or ref is None or not bool(ref.contact.all()):
            return 0.0
        distance_m = outside_support_m(com_xy, ref.contact, ref.corner_contact, ref.sole_corners)
        return max(distance_m, 0.0) if math.isfinite(distance_m) else 0.0

    def _com_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Horizontal CoM position and velocity of this tick's state (computed once in compute())."""
        return self._com_now[0][:2].copy(), self._com_now[1][:2].copy()

    def _external_wrench(self, est: RobotState) -> np.ndarray | None:
        """The observed push as a wrench about the CoM (applied at the pelvis)."""
        fx, fy = self.observer.force_n.tolist()
        if fx == 0.0 and fy == 0.0:  # not force_n.any() (a NaN counts as a force, as there), on floats
            return None
        qx, qy, qz = est.q[:3].tolist()
        cx, cy, cz = self._com_now[0].tolist()
        ax, ay, az = qx - cx, qy - cy, qz - cz
        # [f, arm × f] with f = (fx, fy, 0): np.cross's products and differences, term by term
        return np.array([fx, fy, 0.0, ay * 0.0 - az * fy, az * fx - ax * 0.0, ax * fy - ay * fx])

    def _plan_tick(self, est: RobotState) -> None:
        t0 = time.perf_counter()
        com, com_vel = self._com_state()
        planner = self.planner
        if self.plan is not None:
            t_now = planner.t_s
            ref_pos, ref_vel, _ = self.plan.com_at(t_now)
        else:
            ref_pos, ref_vel = self._init_com[0], self._init_com[1]
        fb = self._feedback(com, com_vel, ref_pos, ref_vel)
        # The command rate-limited toward its (finite) target, on floats (x, y, yaw): the same operations
        # as on the 3-vectors (np.clip(d, −l, l) is min(max(d, −l), l)).
        target = [c if math.isfinite(c) else 0.0 for c in self.command.tolist()]
        limits = [a * PLAN_DT_S for a in self._command_accel_limits.tolist()]
        filtered = [f + min(max(t - f, -lim), lim)
                    for t, f, lim in zip(target, self.command_filtered.tolist(), limits)]
        self.command_filtered = np.array(filtered)
        adjust_x, adjust_y = fb.velocity_adjust_mps.tolist()
        command = np.array([filtered[0] + adjust_x, filtered[1] + adjust_y, filtered[2]])
        goal = np.array([target[0] + adjust_x, target[1] + adjust_y, target[2]])
        contact_before = self.ref.contact.copy() if self.ref is not None else np.ones(2, dtype=bool)
        # The plan's CoM now and the CoM state just read serve reachable_steps too (nothing moved them since).
        if self.plan is not None:
            fb = self.step_adjustment.reachable_steps(fb, self.params, self.plan, (ref_pos, ref_vel, com, com_vel),
                                                      self._com_z, self._mpc_shift, self.observer.force_n)
        # (Before the first plan: the share reset left, so a walk that starts neutral plans neutral from its first tick.)
        recovery_share = self.recovery.blend_share if self.recovery.enabled and planner.recovers_toward_other_gait else 0.0
        if self.recovery.enabled and self.plan is not None:
            if planner.recovers_toward_other_gait:
                ax, ay = fb.step_adjust_m.tolist()  # how far the swing feet land from the style's footholds
                recovery_share = self.recovery.update(self.step_adjustment.xi_error_m, PLAN_DT_S,
                                                      math.sqrt(ax * ax + ay * ay), self._outside_support_m(com))
            else:  # walking the neutral style itself: nothing to blend toward, nothing to report
                self.recovery.idle()
        ref = planner.step(PLAN_DT_S, command, PlannerFeedback(
            time_scaling=fb.kappa, step_adjustment_xy_m=fb.step_adjust_m, command_goal=goal,
            command_rate_limits=self._command_accel_limits, recovery_share=recovery_share))
        if self.start_settle.active(planner.t_s):  # from a reset: the posture eases into the style's
            (ref.pelvis_z, ref.pelvis_z_rate, ref.pelvis_rot, ref.pelvis_ang_vel, ref.upper_q,
             ref.upper_qd) = self.start_settle.apply(planner.t_s, float(planner.path.yaw), ref.pelvis_z,
                                                     ref.pelvis_z_rate, ref.pelvis_rot, ref.pelvis_ang_vel,
                                                     ref.upper_q, ref.upper_qd)
        self._feet_feedforward(ref)
        self.ref = ref
        since_touchdown = self.touchdown.relatch_landed_feet(est, ref, contact_before, self.params, planner)
        in_contact, progress = ref.contact.tolist(), ref.swing_progress.tolist()
        self._landing = any(
            (not in_contact[i] and progress[i] > 1.0 - self.params.observer_hold_swing_share)
            or 0 <= since_touchdown[i] < self.params.observer_hold_after_touchdown_plan_ticks for i in range(2))
        t1 = time.perf_counter()
        self.timings.planner = t1 - t0
        every = max(self.params.mpc_every_plan_ticks, 1)
        self._plan_ticks += 1
        if self.plan is not None and (self._plan_ticks - 1) % every != 0:
            self._last_com, self._last_fb = com, fb
            self._telemetry_stale = True
            return
        # CoM MPC over the planner's contact preview; initial conditions continue the last plan.
        # The planner's contact phases are the MPC's supports as they are (read only, no copy per tick).
        supports: Sequence[SupportPhase] = ref.preview
        # LIP height: the measured CoM height, low-passed (the walking posture differs from standing).
        com_z = float(self._com_now[0][2])  # data.com[0] of this tick (nothing since moved it)
        self._com_z = com_z if self._com_z is None else self._com_z + self.params.com_z_filter * (com_z - self._com_z)
        z_com = self._com_z
        # A steady push f shifts the LIP's equilibrium by f/(m ω²): plan in a frame whose supports
        # are shifted by −f/(m ω²) (the CoP the plan returns is then the robot's minus that shift).
        # The 2-vector arithmetic below on floats (x, y): the same operations as the array expressions.
        omega2 = GRAVITY_MPS2 / max(z_com, 0.2)
        stiffness = self.robot.mass_kg * omega2
        fx, fy = self.observer.force_n.tolist()
        sx, sy = -fx / stiffness, -fy / stiffness  # −f / (m ω²)
        shift = np.array([sx, sy])
        if sx != 0.0 or sy != 0.0:  # shift.any()
            supports = [SupportInterval(sp.t_start_s, sp.t_end_s, sp.polygon + shift) for sp in supports]
        old_x, old_y = self._mpc_shift.tolist()
        self._mpc_shift = shift
        if self.plan is None:
            com0, vel0, cop0 = self._init_com
        else:
            # Continue the last plan (continuity of the reference), pulled a little toward the
            # estimate so the plan never drifts away from the robot.
            pull = self.params.mpc_state_pull
            (px, py), (wx, wy), _ = self.plan.com_at_floats(ref.t_s)
            (cx, cy), (vx, vy) = com.tolist(), com_vel.tolist()
            com0 = np.array([px + pull * (cx - px), py + pull * (cy - py)])
            vel0 = np.array([wx + pull * (vx - wx), wy + pull * (vy - wy)])
            qx, qy = self.plan.cop_at_floats(ref.t_s)
            cop0 = np.array([qx + (sx - old_x), qy + (sy - old_y)])
        # The only infeasible part of the QP is an initial CoP outside today's support (time
        # scaling and touchdowns move contact switches relative to the last plan): clip it in.
        first = supports[0].polygon
        cop0 = _clip_to_polygon(cop0, first)
        # (the preview's phases as the MPC reads them, packed by the planner; None for the shifted copies)
        packed = planner.packed_supports(supports) if supports is ref.preview else None
        plan = self.mpc.solve(ref.t_s, com0, vel0, cop0, z_com, supports, packed)
        # The last support's vertex mean and the plan's final capture point's distance to it, on floats (x, y): the
        # numbers of polygon.mean(axis=0) (numpy's row-by-row sum along axis 0, then ÷ the count) and of
        # np.linalg.norm(final_capture_point_xy_m − goal) (the 2-vector's dot through numpy: its rounding)
        goal_x, goal_y = _vertex_mean(supports[-1].polygon)
        miss = _distance(plan.final_capture_point_floats(), goal_x, goal_y) if plan.ok else math.inf
        lost = plan.ok and miss > self.params.capture_tolerance_m
        # In double support the robot's ξ belongs between its feet: beyond them (a push), a plan
        # continued with the CoP ramping off the trailing foot throws it further (ξ = com + com_vel / ω: computed
        # when read, the same array).
        omega = math.sqrt(omega2)
        thrown = (self.params.restart_when_thrown and all(ref.contact.tolist())  # bool(contact.all()), on a list
                  and not _inside_polygon(com + com_vel / omega, first))
        if not plan.ok or lost or thrown:
            # The plan cannot be continued (a push, a sudden change) or no longer captures the CoM
            # on its footholds: restart it from the robot's state and keep the more capturable one.
            # The restart's CoP starts where it best holds the robot's ξ (a CoP can move at once;
            # one left on the trailing foot while ξ runs past the new one throws the robot on).
            xi_robot = com + com_vel / omega
            retry = self.mpc.solve(ref.t_s, com, com_vel, _clip_to_polygon(xi_robot, first), z_com, supports, packed)
            if retry.ok and (not plan.ok or thrown
                             or _distance(retry.final_capture_point_floats(), goal_x, goal_y) < miss):
                plan = retry
                self.replans += 1
        if plan.ok or self.plan is None:
            self.plan = plan
        self.timings.mpc = time.perf_counter() - t1
        self._last_com, self._last_fb = com, fb
        self._telemetry_stale = True

    def _feet_feedforward(self, ref: GaitReference) -> None:
        """Swing-foot acceleration feed-forward from consecutive reference rates, limited per axis to
        ``swing_feedforward_limit_mps2`` (a moved swing target must not become an acceleration spike)."""
        prev = self.ref
        if prev is None:
            self._foot_acc = np.zeros((2, 3))
            self._foot_ang_acc = np.zeros((2, 3))
            return
        limit = self.params.swing_feedforward_limit_mps2
        # On floats, per foot: the same IEEE operations as the (2, 3) array expressions, np.minimum(np.maximum(
        # (v − v_prev) / dt, −l), l) (Python's max/min keep a NaN first argument as the ufuncs do) and the rows of the
        # feet in contact set to 0 (tests/control/test_stack_speed_references.py keeps the array version)
        lin, lin_prev = ref.foot_lin_vel.tolist(), prev.foot_lin_vel.tolist()
        ang, ang_prev = ref.foot_ang_vel.tolist(), prev.foot_ang_vel.tolist()
        acc: list[Sequence[float]] = []
        ang_acc: list[Sequence[float]] = []
        for in_contact, v, v_prev, w, w_prev in zip(ref.contact.tolist(), lin, lin_prev, ang, ang_prev):
            if in_contact:
                acc.append(_ZEROS3)
                ang_acc.append(_ZEROS3)
            else:
                acc.append([min(max((a - b) / PLAN_DT_S, -limit), limit) for a, b in zip(v, v_prev)])
                ang_acc.append([(a - b) / PLAN_DT_S for a, b in zip(w, w_prev)])
        self._foot_acc = np.array(acc)
        self._foot_ang_acc = np.array(ang_acc)

    def _feedback(self, com: np.ndarray, com_vel: np.ndarray, ref_pos: np.ndarray, ref_vel: np.ndarray) -> FeedbackOutput:
        planner = self.planner
        swinging = [s for s in SIDES if planner.in_swing(s, planner.phi)]
        if swinging:
            side = swinging[0]
            stance = "right" if side == "left" else "left"
            stance_xy = np.array([planner.latched[stance].x, planner.latched[stance].y])
            next_xy = np.array([planner.target[side].x, planner.target[side].y])
        else:
            # Double support: weight moves from the foot about to lift to the one just landed.
            f = planner.phi - math.floor(planner.phi)
            leaving = "left" if f >= 0.6 or f < 0.0 else "right"
            landed = "right" if leaving == "left" else "left"
            stance_xy = np.array([planner.latched[leaving].x, planner.latched[leaving].y])
            next_xy = np.array([planner.latched[landed].x, planner.latched[landed].y])
        z = (self.ref.pelvis_z if self.ref is not None else self.robot.q_standing[2]) + self.com_offset_m
        fb = self.feedback.update(PLAN_DT_S, com, com_vel, ref_pos, ref_vel, z, planner.path.yaw,
                                  stance_xy, next_xy, single_support=bool(swinging))
        outer = stance if swinging else leaving
        return self.step_adjustment.hurry_when_thrown_out(fb, self.params, com, com_vel, z, outer, bool(swinging),
                                                          self._mpc_shift, self.observer.force_n)

    def _wbc_reference(self, dt_since: float) -> WbcReference:
        ref = self.ref
        assert ref is not None and self.plan is not None
        touchdown = self.touchdown
        if touchdown.contact_ref is not ref:  # the planner's corners in contact: the same until its next tick
            touchdown.reference_tables(ref)
        plan = self.plan
        batch = self._reference_batch
        if batch[0] is not ref or batch[1] is not plan:  # the references of the ticks until the planner's next
            batch = self._reference_batch = self._interpolate_ticks(ref, plan)
        k = _TICK_OF_DT.get(dt_since)
        if k is not None:  # dt_since = k · CONTROL_PERIOD_S, k < TICKS_PER_PLAN: the batch's k-th row
            _, _, coms, feet_pos, feet_rot, pelvis_rots, turned, uppers = batch
            com = coms[k]
            pelvis_rot = pelvis_rots[k] if turned[k] else ref.pelvis_rot
            foot_pos, foot_rot, upper_q = feet_pos[k], feet_rot[k], uppers[k]
        else:  # another time (not a control tick's; compute() never asks one): one compiled call
            # The plan's CoM at t (com_at), the feet along their velocities, the turning feet and the pelvis along
            # their angular velocities (Rodrigues), the upper body along its rates: the same numbers as the batch.
            com, foot_pos, foot_rot, pelvis_rot, upper_q = interpolate_reference(
                dt_since, ref.t_s + dt_since, plan.waypoint_times_s, plan.waypoints_xy_m, plan.waypoint_com_xy_m,
                plan.waypoint_com_vel_xy_mps, float(plan.omega_rps), ref.foot_pos, ref.foot_lin_vel, ref.foot_rot,
                ref.foot_ang_vel, ref.pelvis_rot, ref.pelvis_ang_vel, ref.upper_q, ref.upper_qd)
        # (positional: WbcReference's field order, com_xy_m … foot_ang_acc_radps2, external_wrench None as by default)
        return WbcReference(
            com[0], com[1], com[2], ref.pelvis_z + ref.pelvis_z_rate * dt_since, ref.pelvis_z_rate, pelvis_rot,
            ref.pelvis_ang_vel, foot_pos, foot_rot, ref.foot_lin_vel, ref.foot_ang_vel, touchdown.ref_contact, upper_q,
            ref.upper_qd, None, self._foot_acc, self._foot_ang_acc,
        )

    def _interpolate_ticks(self, ref: GaitReference, plan: ComMpcSolution) -> tuple:
        """(ref, plan, then :func:`interpolate_references`' arrays: CoM, feet, feet's rotations, pelvis, whether it
        turned, upper body) for the ticks ``k · CONTROL_PERIOD_S`` after the planner's, k < TICKS_PER_PLAN: one
        compiled call per planner tick instead of one per control tick (the same operations per tick as
        :func:`interpolate_reference`, so the same numbers). The arrays are new per planner tick (a reference handed
        out earlier keeps its own)."""
        n = TICKS_PER_PLAN
        batch = (ref, plan, np.empty((n, 3, 2)), np.empty((n, 2, 3)), np.empty((n, 2, 3, 3)), np.empty((n, 3, 3)),
                 np.empty(n, dtype=np.bool_), np.empty((n, ref.upper_q.shape[0])))
        interpolate_references(CONTROL_PERIOD_S, ref.t_s, plan.waypoint_times_s, plan.waypoints_xy_m,
                               plan.waypoint_com_xy_m, plan.waypoint_com_vel_xy_mps, float(plan.omega_rps),
                               ref.foot_pos, ref.foot_lin_vel, ref.foot_rot, ref.foot_ang_vel, ref.pelvis_rot,
                               ref.pelvis_ang_vel, ref.upper_q, ref.upper_qd, *batch[2:])
        return batch

    @property
    def telemetry(self) -> WalkingTelemetry:
        """Overlay/plot signals, assembled on demand (the studio reads them at 20 Hz)."""
        if self._telemetry_stale and self.ref is not None and self._last_fb is not None:
            update_telemetry(self._telemetry, self.ref, self.plan, self._last_com, self._last_fb, self._mpc_shift,
                             self.planner.command_clamped, self.wbc.diagnostics, self.observer.force_n)
            self._telemetry.recovery_share = self.planner.recovery_share
            self._telemetry.recovery_starting = self.recovery.starting
            self._telemetry_stale = False
        return self._telemetry


_clip_to_polygon = clip_into_polygon  # the initial-CoP clip (engine.geometry.polygon)


def _horizontal_ground_force(diag) -> np.ndarray | None:  # noqa: ANN001
    """Σ of the horizontal contact forces of a solved tick (None otherwise): Σ_c B_c ρ_c summed over
    corners first (the friction basis is per foot), without building every corner's force."""
    if not diag.ok:
        return None
    if diag.basis is None or diag.rho is None:  # a peer without the paper's basis (placo)
        forces = diag.contact_forces_n
        return None if forces is None else forces[..., :2].sum(axis=(0, 1))
    if diag.horizontal_force_n is not None:  # the compiled whole-body tick's (kernels.horizontal_force)
        return diag.horizontal_force_n
    basis, rho = diag.basis, diag.rho
    if N_BASIS != 4 or N_CORNERS != 4 or basis.shape != (len(SIDES), 3, N_BASIS) or rho.shape != (len(SIDES) * N_CORNERS * N_BASIS,):
        per_foot = rho.reshape(len(SIDES), -1, basis.shape[-1]).sum(axis=1)  # (2, 4): Σ over corners
        return np.einsum("fkb,fb->k", basis[:, :2, :], per_foot)
    # The same sums on floats (a fraction of the numpy calls' cost) in numpy's order: corner after
    # corner, each foot's four edges as einsum adds them ((e0 + e2) + (e1 + e3)), then foot + foot.
    r, b = rho.tolist(), basis.tolist()
    n = N_CORNERS * N_BASIS
    terms = [[0.0, 0.0] for _ in SIDES]
    for f in range(len(SIDES)):
        w = [((r[f * n + j] + r[f * n + 4 + j]) + r[f * n + 8 + j]) + r[f * n + 12 + j] for j in range(4)]
        for k in range(2):
            e = b[f][k]
            terms[f][k] = (e[0] * w[0] + e[2] * w[2]) + (e[1] * w[1] + e[3] * w[3])
    return np.array([terms[0][0] + terms[1][0], terms[0][1] + terms[1][1]])


def _vertex_mean(polygon: np.ndarray) -> tuple[float, float]:
    """``polygon.mean(axis=0)`` of an (M, 2) float array as floats (x, y): numpy's sum along axis 0 adds the rows in
    order from the first, then divides by M (the same numbers, without the two array operations)."""
    rows = polygon.tolist()
    if not rows:  # (an empty polygon's mean: NaN)
        return math.nan, math.nan
    x, y = rows[0]
    for rx, ry in rows[1:]:
        x += rx
        y += ry
    return x / len(rows), y / len(rows)


def _distance(point: tuple[float, float], x: float, y: float) -> float:
    """``np.linalg.norm(np.array(point) − (x, y))``: the differences on floats, the norm by :func:`vector_norm`
    (numpy's dot of the 2-vector, whose rounding a float expression need not repeat)."""
    return vector_norm(np.array([point[0] - x, point[1] - y]))


def _inside_polygon(p: np.ndarray, polygon: np.ndarray) -> bool:
    normals, offsets, bound = halfplanes_cached(polygon)
    # bool((normals @ p <= bound).all()) on the list of flags (without ndarray.all's Python layer; NaN compares False)
    return len(offsets) == 0 or all((normals @ p <= bound).tolist())
