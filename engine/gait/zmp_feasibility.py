"""ZMP feasibility of the CoM MPC's plan under the style's pelvis height (issue 13: the check's CoP/ZMP part).

The CoM MPC (engine/control/mpc, the paper's Eq. 11) plans the horizontal CoM ``c`` on a linear inverted
pendulum of constant height ``z0`` and keeps its CoP ``p`` inside the support polygons, which the planner
shrinks by the controller's CoP margin. The whole-body controller then tracks the style's pelvis height
curve, which moves the CoM up and down. With the CoM at height ``z`` above the floor, accelerating
vertically by ``z̈``, the horizontal acceleration the plan asks for, ``c̈ = ω0² (c − p)`` with
``ω0² = g / z0``, needs the CoP (the ZMP of a point mass on a flat floor) at::

    p_req = c − z c̈ / (g + z̈)

Where ``p_req`` lies beyond the soles the robot cannot follow the plan (it tips about the sole's edge);
where ``g + z̈`` drops toward zero the feet unload. The limbs' angular momentum is left out (the MPC's
model leaves it out too).

:class:`PlanFollower` runs the MPC along an open-loop planner walk the way the controller does: a solve
every planner tick, from standing, each one continuing the last plan (the controller also pulls that
state toward the measured robot, which an open-loop walk does not have). :func:`cop_demands` then turns
the plans' CoM and CoP and the CoM height along the walk into ``p_req`` and its distance outside the
support.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import NDArray

from engine.constants import GRAVITY_MPS2
from engine.control.mpc import ComMpc, ComMpcSolution, SupportPhase
from engine.geometry.polygon import clip_into_polygon, outside_distance_m

FloatArray = NDArray[np.float64]

#: Below this share of gravity the vertical acceleration leaves the feet nearly unloaded.
MIN_LOAD_SHARE = 0.25
#: A plan whose CoM is farther than this from its CoP has left walking: followed open loop (no feedback,
#: no step adjustment, no pull toward a measured robot) the pendulum can fall behind the footholds for good
#: (README: on random styles it does, walkers included), and its CoP demand then says nothing about the style.
MAX_PLAN_OFFSET_M = 0.3


def required_cop(com_xy_m: FloatArray, plan_cop_xy_m: FloatArray, com_height_m: float, lip_height_m: float,
                 com_vertical_accel_mps2: float) -> FloatArray:
    """The CoP that gives the plan's horizontal CoM acceleration ``g/z0 (c − p)`` with the CoM at height
    ``com_height_m`` accelerating vertically by ``com_vertical_accel_mps2`` (flat floor, point mass)."""
    com = np.asarray(com_xy_m, dtype=float)
    accel = (GRAVITY_MPS2 / lip_height_m) * (com - np.asarray(plan_cop_xy_m, dtype=float))
    load = max(GRAVITY_MPS2 + com_vertical_accel_mps2, 1e-6)
    return com - (com_height_m / load) * accel


def support_at(supports: Sequence[SupportPhase], t_s: float) -> FloatArray:
    """The polygon of the support interval holding ``t_s`` (the last one past the preview's end)."""
    for sp in supports:
        if sp.t_start_s - 1e-9 <= t_s <= sp.t_end_s + 1e-9:
            return np.asarray(sp.polygon)
    return np.asarray(supports[-1].polygon)


@dataclass
class PlanFollower:
    """The CoM MPC solved every planner tick of an open-loop walk, each solve continuing the last plan."""

    preview_s: float

    def __post_init__(self) -> None:
        self.mpc = ComMpc(preview_s=self.preview_s)
        self.plan: ComMpcSolution | None = None

    def step(self, t_s: float, supports: Sequence[SupportPhase], lip_height_m: float,
             standing_com_xy_m: FloatArray) -> tuple[FloatArray, FloatArray, bool]:
        """Solve at ``t_s`` over ``supports`` with the pendulum at ``lip_height_m``; returns the plan's CoM and CoP
        at ``t_s`` and whether the QP solved (the first solve starts at rest at ``standing_com_xy_m``)."""
        first = np.asarray(supports[0].polygon)
        if self.plan is None:
            com0 = np.asarray(standing_com_xy_m, dtype=float)
            vel0 = np.zeros(2)
            cop0 = com0.copy()
        else:
            (cx, cy), (vx, vy), _ = self.plan.com_at_floats(t_s)
            com0, vel0 = np.array([cx, cy]), np.array([vx, vy])
            cop0 = np.array(self.plan.cop_at_floats(t_s))
        plan = self.mpc.solve(t_s, com0, vel0, clip_into_polygon(cop0, first), lip_height_m, supports)
        self.plan = plan
        (cx, cy), _, _ = plan.com_at_floats(t_s)
        return np.array([cx, cy]), np.array(plan.cop_at_floats(t_s)), bool(plan.ok)


@dataclass(frozen=True)
class CopDemand:
    """The CoP one instant of the plan needs (``required_cop``) and how far outside the soles it lies."""

    t_s: float
    required_cop_xy_m: FloatArray
    outside_m: float  # beyond the sole polygon (the MPC's support grown back by the CoP margin); ≤ 0 inside
    com_vertical_accel_mps2: float
    plan_offset_m: float = 0.0  # |CoM − CoP| of the plan

    @property
    def plan_diverged(self) -> bool:
        return self.plan_offset_m > MAX_PLAN_OFFSET_M

    @property
    def load_share(self) -> float:
        """The floor's vertical push as a share of the weight: (g + z̈) / g."""
        return (GRAVITY_MPS2 + self.com_vertical_accel_mps2) / GRAVITY_MPS2


def cop_demands(times_s: FloatArray, com_heights_m: FloatArray, com_xy_m: FloatArray, plan_cop_xy_m: FloatArray,
                supports: Sequence[FloatArray], lip_heights_m: FloatArray, margin_m: float) -> list[CopDemand]:
    """``p_req`` along a walk: per instant the plan's CoM and CoP, the CoM height (its vertical acceleration by
    finite differences over ``times_s``), the pendulum height the plan used and the MPC's support polygon, which lies
    ``margin_m`` inside the soles."""
    t = np.asarray(times_s, dtype=float)
    z = np.asarray(com_heights_m, dtype=float)
    if len(t) < 3:
        return []
    z_acc = np.gradient(np.gradient(z, t), t)
    out = []
    for i in range(len(t)):
        p_req = required_cop(com_xy_m[i], plan_cop_xy_m[i], float(z[i]), float(lip_heights_m[i]), float(z_acc[i]))
        offset = float(np.linalg.norm(np.asarray(com_xy_m[i]) - np.asarray(plan_cop_xy_m[i])))
        out.append(CopDemand(float(t[i]), p_req, outside_distance_m(p_req, supports[i]) - margin_m, float(z_acc[i]), offset))
    return out
