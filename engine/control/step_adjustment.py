"""Step adjustment and time scaling from the divergent component of motion ξ = x + ẋ/ω: the feedback the
walking controller hands the planner each planner tick besides the gait feedback's.

Keeps the swing foot's target where the CoM can still be balanced over it (the CoP's reach on the landing
sole around ξ at touchdown, the legs' reach from the stance foot), takes ξ from the stance foot under a push
(whatever the plan says), and hurries the gait when ξ is thrown out past the stance foot's outer edge.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from engine.constants import GRAVITY_MPS2
from engine.control.gait_feedback import FeedbackOutput, GaitFeedbackGains
from engine.control.mpc import ComMpcSolution
from engine.control.walking_parameters import WalkingParameters
from engine.gait.planner import GaitPlanner
from engine.gait.style import SIDES
from engine.robot.model import RobotModel


class StepAdjustment:
    """The ξ-based step adjustment and hurry of one walking controller: the CoP's reach on the soles (m), the
    planner it reads (time to touchdown, nominal targets, latched feet, path yaw) and the time of the last push."""

    __slots__ = ("planner", "gains", "standing_com_z_m", "reach_back_m", "reach_forward_m", "half_sole_width_m",
                 "reach_side_m", "pushed_at_s", "xi_error_m")

    def __init__(self, robot: RobotModel, params: WalkingParameters, planner: GaitPlanner, gains: GaitFeedbackGains,
                 standing_com_z_m: float):
        self.planner = planner
        self.gains = gains
        self.standing_com_z_m = standing_com_z_m  # the LIP height before the first MPC tick
        # How far the CoP reaches from the sole centre toward the heel and the (ankle-held) toe,
        # less the share kept for the whole-body controller: the band a landing foot keeps around ξ.
        half = 0.5 * min(robot.config.soles[s].length_m for s in SIDES) - params.cop_margin_m
        self.reach_back_m = params.step_reach_share * half
        self.reach_forward_m = params.step_reach_share * max(half - planner.preview_toe_trim_m, 0.0)
        self.half_sole_width_m = 0.5 * min(robot.config.soles[s].width_m for s in SIDES)
        self.reach_side_m = params.step_reach_share * (
            self.half_sole_width_m - params.cop_margin_m - params.cop_lateral_extra_margin_m)
        self.pushed_at_s = -math.inf  # planner time the observer last saw a push
        self.xi_error_m = 0.0  # |measured ξ − the plan's ξ| at the last call (before the deadband)

    def reset(self) -> None:
        self.pushed_at_s = -math.inf  # planner time the observer last saw a push
        self.xi_error_m = 0.0

    def reachable_steps(self, fb: FeedbackOutput, params: WalkingParameters, plan: ComMpcSolution,
                        now: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray], com_z_m: float | None,
                        mpc_shift: np.ndarray, force_n: np.ndarray) -> FeedbackOutput:
        """Keep the swing foot's target where the CoM can still be balanced over it.

        With the divergent component of motion ξ = x + ẋ/ω that the CoM plan predicts at
        touchdown: along the walking direction, a foot landing ahead of ξ by more than the CoP
        reaches back (to the heel) stops the CoM and throws it back, one landing behind ξ by
        more than the CoP reaches forward (to the toe the ankles can hold) cannot stop it;
        sideways, a foot whose outer edge lies inside ξ cannot bring it back toward the other
        foot. The target is kept within those bounds; the difference joins the step adjustment.
        ``now``: the plan's CoM position and velocity at ``planner.t_s`` and the CoM state of this tick
        (position, velocity); ``com_z_m``: the LIP height (None before the first MPC tick: the standing CoM's);
        ``mpc_shift``: the MPC frame's shift −f/(m ω²) (m); ``force_n``: the observed horizontal push (N).
        """
        # On floats (x, y): the same IEEE operations as the 2-vector numpy expressions it replaced (a 2-vector dot
        # is x0·y0 + x1·y1, unfused); tests/control/test_stack_speed_references.py keeps that version.
        planner = self.planner
        ax, ay = fb.step_adjust_m.tolist()
        z = com_z_m if com_z_m is not None else self.standing_com_z_m
        omega = math.sqrt(GRAVITY_MPS2 / max(z, 0.2))
        c, s_ = math.cos(planner.path.yaw), math.sin(planner.path.yaw)  # forward (c, s_), left (−s_, c)
        # Where the robot is off the plan, its ξ runs away from the plan's as e^{ωt} under the
        # same CoP (the whole-body controller's corrections slow that: the growth is capped).
        pos_now, vel_now, com, com_vel = now
        (cx, cy), (vx, vy) = com.tolist(), com_vel.tolist()
        (px, py), (wx, wy) = pos_now.tolist(), vel_now.tolist()
        ex, ey = (cx + vx / omega) - (px + wx / omega), (cy + vy / omega) - (py + wy / omega)
        err = math.sqrt(ex * ex + ey * ey)  # ordinary tracking error is the MPC's to handle
        self.xi_error_m = err  # (balance recovery reads it: engine/control/recovery_blend.py)
        f = max(err - params.dcm_error_deadband_m, 0.0) / err if err > 0.0 else 0.0
        ex, ey = ex * f, ey * f
        pushed = _any2(force_n)
        if pushed:
            self.pushed_at_s = planner.t_s
        from_stance = (params.capture_from_stance_foot
                       and planner.t_s - self.pushed_at_s < params.stance_capture_after_push_s)
        shift_x, shift_y = mpc_shift.tolist()
        reach_bounded = from_stance
        for side in SIDES:
            t_td = planner.time_to_touchdown_s(side, fb.kappa)
            if t_td is None:
                continue
            nominal = planner.nominal_target(side)
            sign = 1.0 if side == "left" else -1.0
            if from_stance:  # pushed: where the stance foot says ξ goes, whatever the plan says
                dx, dy = self.xi_at_touchdown(side, com, com_vel, omega, t_td, mpc_shift).tolist()
            else:
                (px, py), (wx, wy), _ = plan.com_at_floats(planner.t_s + t_td)
                growth = min(math.exp(omega * t_td), params.dcm_error_growth_cap)
                dx = px + wx / omega + growth * ex - shift_x  # ξ against the real soles
                dy = py + wy / omega + growth * ey - shift_y
            rx, ry = (nominal.x + ax) - dx, (nominal.y + ay) - dy
            ahead = rx * c + ry * s_
            # Under a push the CoP must hold ξ against it for the whole step: land with ξ near
            # the sole's middle (margin both ways), not at the edge of the CoP's reach.
            share = params.pushed_reach_share if pushed else 1.0
            back, fwd = share * self.reach_back_m, share * self.reach_forward_m
            if ahead > back:
                k = ahead - back
                ax, ay = ax - k * c, ay - k * s_
            elif ahead < -fwd:
                k = -fwd - ahead
                ax, ay = ax + k * c, ay + k * s_
            outward = (rx * -s_ + ry * c) * sign  # foot beyond ξ, outward
            ox, oy = -s_ * sign, c * sign  # the outward direction (left, or −left)
            if outward < params.lateral_xi_inset_m:
                k = params.lateral_xi_inset_m - outward
                ax, ay = ax + k * ox, ay + k * oy
            elif outward > params.lateral_xi_max_out_m:  # ξ runs toward the other foot: land near it
                k = outward - params.lateral_xi_max_out_m
                ax, ay = ax - k * ox, ay - k * oy
            # Within the legs' reach of the stance foot: under a push, and (with a reach model) whenever the
            # adjustment outgrows max_step_adjust_m, i.e. the nominal foothold has run away from the robot.
            if from_stance or (params.capture_from_stance_foot
                               and math.sqrt(ax * ax + ay * ay) > params.max_step_adjust_m):
                reach_bounded = True
                stance = planner.latched["right" if side == "left" else "left"]
                rx, ry = (nominal.x - stance.x) + ax, (nominal.y - stance.y) + ay
                along, lateral = rx * c + ry * s_, rx * -s_ + ry * c
                along_c = min(max(along, -params.max_step_length_m), params.max_step_length_m)
                lateral_c = sign * min(sign * lateral, params.max_step_width_m)
                d_along, d_lateral = along_c - along, lateral_c - lateral
                ax, ay = ax + (d_along * c + d_lateral * -s_), ay + (d_along * s_ + d_lateral * c)
        norm = math.sqrt(ax * ax + ay * ay)
        if norm > params.max_step_adjust_m and not reach_bounded:  # within the legs' reach
            f = params.max_step_adjust_m / norm
            ax, ay = ax * f, ay * f
        old_x, old_y = fb.step_adjust_m.tolist()
        if ax == old_x and ay == old_y:  # np.array_equal of two (2,) arrays
            return fb
        # dataclasses.replace(fb, step_adjust_m=…) without its field introspection: FeedbackOutput's fields in order
        return FeedbackOutput(fb.velocity_adjust_mps, np.array([ax, ay]), fb.kappa, fb.epsilon_m, fb.epsilon_rate_mps,
                              fb.error_m)

    def xi_at_touchdown(self, swing_side: str, com: np.ndarray, com_vel: np.ndarray, omega: float,
                        t_td: float, mpc_shift: np.ndarray) -> np.ndarray:
        """The robot's ξ at the swing foot's touchdown, against the real soles: the measured ξ less
        the push's shift (a steady push f moves the LIP's equilibrium by f/(m ω²)) diverging for
        ``t_td`` from the CoP that best holds it on the stance foot (ξ clipped into the CoP's reach).
        Nothing of the MPC plan enters: a plan restarted from the robot's state cannot hide the error."""
        foot = self.planner.latched["right" if swing_side == "left" else "left"]
        chi = com + com_vel / omega - mpc_shift
        c, s_ = math.cos(foot.yaw), math.sin(foot.yaw)
        rel = chi - np.array([foot.x, foot.y])
        x = min(max(c * rel[0] + s_ * rel[1], -self.reach_back_m), self.reach_forward_m)
        y = min(max(-s_ * rel[0] + c * rel[1], -self.reach_side_m), self.reach_side_m)
        cop = np.array([foot.x + c * x - s_ * y, foot.y + s_ * x + c * y])
        return cop + (chi - cop) * math.exp(omega * t_td)

    def hurry_when_thrown_out(self, fb: FeedbackOutput, params: WalkingParameters, com: np.ndarray,
                              com_vel: np.ndarray, z: float, outer: str, single: bool, mpc_shift: np.ndarray,
                              force_n: np.ndarray) -> FeedbackOutput:
        """Time scaling at its upper bound while ξ is beyond the outer side of the foot that
        stands until the next lift-off (a sideways push toward it).

        ε < 0 slows the gait so a lagging CoM can reach the next foot; a CoM thrown out past the
        stance foot never gets there, no CoP can bring it back, and only that foot's own next step
        (after the other foot lands) catches it: the gait should hurry, not wait. The external
        push the observer sees moves the reachable CoP (the MPC's shift) and counts too.
        """
        if params.hurry_while_pushed and _any2(force_n):
            lo, hi = self.gains.kappa_single if single else self.gains.kappa_double
            return dataclasses.replace(fb, kappa=max(fb.kappa, hi))
        if not math.isfinite(params.lateral_capture_margin_m):
            return fb
        planner = self.planner
        omega = math.sqrt(GRAVITY_MPS2 / max(z, 0.2))
        (cx, cy), (vx, vy), (sx, sy) = com.tolist(), com_vel.tolist(), mpc_shift.tolist()
        xi_x, xi_y = cx + vx / omega - sx, cy + vy / omega - sy  # on floats: the former 2-vector expressions' numbers
        c, s_ = math.cos(planner.path.yaw), math.sin(planner.path.yaw)
        sign = 1.0 if outer == "left" else -1.0
        foot = planner.latched[outer]
        beyond = (xi_x - foot.x) * (-s_ * sign) + (xi_y - foot.y) * (c * sign) - self.half_sole_width_m
        if beyond <= params.lateral_capture_margin_m:
            return fb
        lo, hi = self.gains.kappa_single if single else self.gains.kappa_double
        return dataclasses.replace(fb, kappa=max(fb.kappa, hi))


def _any2(v: np.ndarray) -> bool:
    """``bool(v.any())`` of a 2-vector on floats (a NaN counts, as there), without the array method's Python layer."""
    x, y = v.tolist()
    return x != 0.0 or y != 0.0
