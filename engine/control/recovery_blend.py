"""Balance recovery by blending toward the robot's neutral gait (issue 13).

A style the animator authors is walked as authored while the robot is in balance. When the measured divergent
component of motion ξ = x + ẋ/ω runs off the MPC plan's (a push, a stumble, a style at the edge of what the
robot can hold), the planner blends the style's gait samples toward the same samples of the robot's neutral
style — the gait its controller is tuned on — in phase space, as it blends samples and edits: the reference
stays continuous. The style comes back once the error has stayed small for a while.

``RecoveryBlend.update`` maps the ξ error e to a target share ``clip((e − e₀) / (e₁ − e₀), 0, 1)`` of the
neutral gait. Where the robot enables it, the step adjustment's size maps the same way (``recovery_step_adjust_m``
→ ``recovery_full_step_adjust_m``) and the larger share wins. So does the measured CoM's distance outside the double
support the reference holds (``recovery_support_outside_m`` → ``recovery_full_support_outside_m``): a style that lands
a foot on its toe while the other rolls onto its toe gives the MPC only the two toe strips to put the CoP on, and a
body left behind them is pushed further back by a CoP ahead of it (engine/gait/support_edges.py); the ξ error stays
small until the robot is already falling backward. That distance counts once it has stayed beyond its start for
``recovery_support_outside_for_s`` without a break (a touchdown or a liftoff passes through a thin support for a few
hundredths of a second). The MPC re-plans from the measured state every tick, so
a robot that does not go where the gait steps (a strafe it cannot follow: the nominal footholds run away from it) can
keep ξ near its plan while the step adjustment moves every swing foot far from its nominal foothold. That size is
the controller's (engine/control/step_adjustment.py): measured from the nominal footholds of the gait being walked,
recovery blend included, and in double support the capture-point feedback alone — so as the share rises the
nominal footholds move toward neutral's and the signal shrinks; a style the robot cannot follow then comes back,
drifts off again and recovers again (episodes of a few seconds; ``studio bench styles`` measures the mean share).

A walk starts fully neutral where the robot sets ``recovery_start_neutral_s``: the share is 1 from ``reset`` and
the target must stay below it for that long plus ``recovery_hold_s`` before it decays, so the first steps from
standing are the neutral gait's and the style eases in over ``recovery_decay_s``.

The share follows a rising target at once (at most 1 per ``recovery_rise_s``), and a falling one only after the
target has stayed below the share for ``recovery_hold_s``, then at 1 per ``recovery_decay_s``. The share the planner
blends is quantised to ``recovery_share_step``: each new value re-blends the gait (a new
:class:`engine.gait.blending.BlendedGait`), so it changes at most a few times per step.
"""

from __future__ import annotations

import math

from engine.control.walking_parameters import WalkingParameters


class RecoveryBlend:
    """The neutral gait's share (0..1) in the planner's blend, from the ξ error against the plan (and the step
    adjustment's size, where enabled)."""

    def __init__(self, params: WalkingParameters):
        self.params = params
        self.enabled = (math.isfinite(params.recovery_xi_error_m) or math.isfinite(params.recovery_step_adjust_m)
                        or math.isfinite(params.recovery_support_outside_m))
        self.share = 0.0  # continuous
        self.blend_share = 0.0  # quantised: what the planner blends
        # The walk's start, not a recovery: from ``reset`` until the share first reaches 0, or until a signal (ξ, the
        # step adjustment, the body outside its support) asks for all of it (then it is a recovery). Recovery time and
        # share do not count it.
        self.starting = False
        self._calm_s = math.inf  # time since the target last reached the share
        self._outside_s = 0.0  # how long the CoM has stood beyond recovery_support_outside_m without a break
        self.time_in_recovery_s = 0.0
        self.share_time_s = 0.0  # ∫ blend_share dt (the walk's mean share = this ÷ its duration)

    def reset(self) -> None:
        """A new walk from standing: fully neutral for ``recovery_start_neutral_s`` (where set), else the style."""
        self.idle()
        self.time_in_recovery_s = self.share_time_s = 0.0
        start_s = self.params.recovery_start_neutral_s
        if self.enabled and start_s > 0.0:
            self.share = self.blend_share = 1.0
            self._calm_s = -start_s  # the hold counts from here: start_s + recovery_hold_s before the decay
            self.starting = True

    def idle(self) -> None:
        """No recovery blend this tick (the robot walks its neutral style itself): the share rests at 0."""
        self.share = self.blend_share = 0.0
        self._calm_s = math.inf
        self._outside_s = 0.0
        self.starting = False

    def target(self, xi_error_m: float, step_adjust_m: float = 0.0, support_outside_m: float = 0.0) -> float:
        """The neutral share the ξ error, the step adjustment's size and the CoM's distance outside the reference's
        double support ask for (the largest)."""
        p = self.params
        return max(_ramp(xi_error_m, p.recovery_xi_error_m, p.recovery_full_xi_error_m),
                   _ramp(step_adjust_m, p.recovery_step_adjust_m, p.recovery_full_step_adjust_m),
                   _ramp(support_outside_m, p.recovery_support_outside_m, p.recovery_full_support_outside_m))

    def update(self, xi_error_m: float, dt_s: float, step_adjust_m: float = 0.0, support_outside_m: float = 0.0) -> float:
        """Advance by ``dt_s`` with this tick's ξ error, step adjustment size and CoM distance outside the double
        support (m); returns the quantised share to blend."""
        if not self.enabled:
            return 0.0
        p = self.params
        outside = not support_outside_m <= p.recovery_support_outside_m  # (a NaN reading counts as outside)
        self._outside_s = self._outside_s + dt_s if outside else 0.0
        if self._outside_s < p.recovery_support_outside_for_s - 1e-9:
            support_outside_m = 0.0  # not for long enough yet
        target = self.target(xi_error_m, step_adjust_m, support_outside_m)
        if target >= self.share:
            self.starting = False  # the error asks for the whole share: a recovery from here
            self._calm_s = 0.0
            self.share = min(target, self.share + dt_s / max(p.recovery_rise_s, 1e-6))
        else:
            self._calm_s += dt_s
            if self._calm_s > p.recovery_hold_s:
                self.share = max(target, self.share - dt_s / max(p.recovery_decay_s, 1e-6))
        step = p.recovery_share_step
        self.blend_share = min(max(round(self.share / step) * step, 0.0), 1.0) if step > 0.0 else self.share
        if self.blend_share <= 0.0:
            self.starting = False
        elif not self.starting:
            self.time_in_recovery_s += dt_s
            self.share_time_s += self.blend_share * dt_s
        return self.blend_share


def _ramp(value_m: float, start_m: float, full_m: float) -> float:
    """0 below ``start_m``, 1 from ``full_m``, linear between; a signal that is off (``start_m`` inf) asks for 0, and a
    non-finite reading of one that is on for 1 (a broken estimate recovers rather than trusting the style)."""
    if not math.isfinite(start_m):
        return 0.0
    if not math.isfinite(value_m):
        return 1.0
    return min(max((value_m - start_m) / max(full_m - start_m, 1e-6), 0.0), 1.0)
