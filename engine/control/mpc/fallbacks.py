"""What the CoM MPC returns when the QP cannot give a plan: the previous plan if it still matches the state, the
CoP stepped through the support regions' centroids, or the CoP held; each finite by construction, with the
status and message saying which (:class:`~engine.control.mpc.types.ComMpcSolution`)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from engine.constants import GRAVITY_MPS2
from engine.control.mpc.kernels import plan_is_finite
from engine.control.mpc.lip import propagate_lip
from engine.control.mpc.problem import _Condensed
from engine.control.mpc.regions import _make_region, _Region
from engine.control.mpc.types import ComMpcSolution, SupportPhase
from engine.geometry.polygon import clip_convex_polygons, polygon_centroid

FloatArray = NDArray[np.float64]


def centroid_plan(
    t_now: float,
    com: FloatArray,
    vel: FloatArray,
    cop: FloatArray,
    height: float,
    state_ok: bool,
    supports: Sequence[SupportPhase],
    preview_s: float,
    min_interval_s: float,
) -> ComMpcSolution:
    """Safe plan: CoP waypoints at their regions' centroids (from the current CoP), CoM integrated exactly, over
    ``preview_s`` (intervals shorter than ``min_interval_s`` skipped)."""
    t_horizon = t_now + preview_s
    times = [t_now]
    regions: list[_Region] = []
    prev_end = t_now
    for s in supports:
        try:
            t1 = float(s.t_end_s)
        except (TypeError, ValueError, AttributeError):
            continue
        if not math.isfinite(t1) or t1 <= prev_end + min_interval_s:
            continue
        if prev_end >= t_horizon - min_interval_s:
            break
        end = min(t1, t_horizon)
        regions.append(_make_region(getattr(s, "polygon", None)))  # type: ignore[arg-type]
        times += [0.5 * (prev_end + end), end]
        prev_end = end
    if not state_ok:
        first_valid = next((r for r in regions if r.valid), None)
        if first_valid is not None:  # no usable state: start at rest over the support
            cop = first_valid.centroid.copy()
            com, vel = cop.copy(), np.zeros(2)
    if not regions:
        return hold_solution(t_now, com, vel, cop, height, preview_s)
    points = [cop]
    for k, region in enumerate(regions):
        mid = region.centroid if region.valid else points[-1]
        end_wp = mid
        nxt = regions[k + 1] if k + 1 < len(regions) else None
        if region.valid and nxt is not None and nxt.valid:
            inter = clip_convex_polygons(region.hull, nxt.hull)
            end_wp = polygon_centroid(inter) if len(inter) else mid
        points += [mid, end_wp]
    wps = np.array(points)
    t_arr = np.array(times)
    pos, vel_wp = propagate_lip(t_arr, wps - com, np.zeros(2), vel, math.sqrt(GRAVITY_MPS2 / height))
    return ComMpcSolution(t_arr, wps, pos + com, vel_wp, height, "", 0.0)


def pull_into_regions(wps: FloatArray, qp: _Condensed, centroids: FloatArray) -> FloatArray:
    """Move each waypoint (N, 2) along the segment to its centroid target until its rows hold."""
    rv = qp.row_var
    c = centroids[rv]
    num = np.maximum(qp.rhs - np.einsum("ij,ij->i", qp.normals, c), 0.0)
    den = np.einsum("ij,ij->i", qp.normals, wps[rv] - c)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(den > 0.0, num / den, np.inf)
    scale = np.ones(len(wps))
    np.minimum.at(scale, rv, ratio)
    scale = np.clip(scale, 0.0, 1.0)
    return centroids + scale[:, None] * (wps - centroids)


def plan_matches_state(plan: ComMpcSolution, t_now: float, com: FloatArray, vel: FloatArray, cop: FloatArray) -> bool:
    if not (plan.t_start_s <= t_now < plan.t_end_s):
        return False
    pos_p, vel_p, _ = plan.com_at(t_now)
    return bool(
        np.linalg.norm(pos_p - com) < 0.01
        and np.linalg.norm(vel_p - vel) < 0.05
        and np.linalg.norm(plan.cop_at(t_now) - cop) < 0.01
    )


def hold_solution(
    t_now: float, com: FloatArray, vel: FloatArray, cop: FloatArray, height: float, preview_s: float
) -> ComMpcSolution:
    times = np.array([t_now, t_now + preview_s])
    wps = np.vstack([cop, cop])
    pos, vel_wp = propagate_lip(times, wps - com, np.zeros(2), vel, math.sqrt(GRAVITY_MPS2 / height))
    if not (np.isfinite(pos).all() and np.isfinite(vel_wp).all()):
        pos, vel_wp = np.zeros((2, 2)), np.zeros((2, 2))
    return ComMpcSolution(times, wps, pos + com, vel_wp, height, "", 0.0)


def is_finite_plan(sol: ComMpcSolution) -> bool:
    """Whether all the plan's numbers are finite (compiled: :func:`engine.control.mpc.kernels.plan_is_finite`)."""
    c = np.ascontiguousarray
    return bool(plan_is_finite(c(sol.waypoint_times_s, np.float64), c(sol.waypoints_xy_m, np.float64),
                               c(sol.waypoint_com_xy_m, np.float64), c(sol.waypoint_com_vel_xy_mps, np.float64),
                               c(sol.qp_final_state, np.float64), float(sol.com_height_m)))


def replace_status(sol: ComMpcSolution, status: str, message: str, solve_time_s: float) -> ComMpcSolution:
    final_state = sol.qp_final_state
    if not np.isfinite(final_state).all():  # fallback plans: the propagated final state
        final_state = np.concatenate([sol.waypoint_com_xy_m[-1], sol.waypoint_com_vel_xy_mps[-1]])
    return dataclasses.replace(
        sol, status=status, message=message, solve_time_s=solve_time_s, qp_final_state=final_state
    )
