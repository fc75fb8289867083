"""Where the gait reference stands: the sole edge each grounded foot rolls on, and how far a point (the measured
CoM) lies outside the support that the reference's grounded sole corners span (issue 13).

A style may land a foot on its toe (a toe pitch at touchdown, eased flat over its touchdown transition) while the
other foot rolls onto its toe to lift off. In that double support the planner gives the CoM MPC only the two toe
strips to put the CoP on (:meth:`engine.gait.planner.GaitPlanner.preview`); with the body behind them, the CoP ahead
of the CoM pushes it further back. The rehearsal names such an onset (engine/gait/rehearsal.py, kind "edges").
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from engine.geometry.polygon import convex_hull_2d, outside_distance_m

FloatArray = NDArray[np.float64]

#: The planner's edge codes (engine.gait.planner_kernels.EDGE_CODES; tests/gait/test_support_edges.py keeps them equal)
EDGE_FLAT, EDGE_HEEL, EDGE_TOE = 0, 1, 2
EDGE_WORDS = {EDGE_HEEL: "heel", EDGE_TOE: "toe"}


def support_edges(contact: NDArray[np.bool_], corner_contact: NDArray[np.bool_], sole_corners: FloatArray,
                  foot_pos: FloatArray, foot_rot: FloatArray) -> NDArray[np.int64]:
    """(2,) per foot: :data:`EDGE_TOE` where the reference holds it on the ground on its front corners only (the heel
    up), :data:`EDGE_HEEL` on its back corners only, :data:`EDGE_FLAT` otherwise (flat, or in the air).
    Arguments: a :class:`engine.gait.planner.GaitReference`'s ``contact`` (2,), ``corner_contact`` (2, 4),
    ``sole_corners`` (2, 4, 3), ``foot_pos`` (2, 3) and ``foot_rot`` (2, 3, 3)."""
    out = np.zeros(2, dtype=np.int64)
    for i in range(2):
        down = corner_contact[i]
        if not contact[i] or down.all() or not down.any():
            continue
        forward = foot_rot[i][:2, 0]
        along = (sole_corners[i, :, :2] - foot_pos[i, :2]) @ forward
        front_down = bool(np.all(along[down] > 0.0))
        back_down = bool(np.all(along[down] < 0.0))
        out[i] = EDGE_TOE if front_down else (EDGE_HEEL if back_down else EDGE_FLAT)
    return out


def outside_support_m(point_xy: FloatArray, contact: NDArray[np.bool_], corner_contact: NDArray[np.bool_],
                      sole_corners: FloatArray) -> float:
    """How far ``point_xy`` lies outside the convex hull of the grounded corners of the feet the reference holds on
    the ground (≤ 0 inside; NaN with no corner down)."""
    mask = corner_contact & contact[:, None]
    points = sole_corners[:, :, :2][mask]
    if len(points) == 0:
        return math.nan
    point = np.asarray(point_xy, dtype=float)
    hull = convex_hull_2d(points)
    if len(hull) < 3:  # one corner, or corners on one line (both toe edges side by side): the distance to it
        a, b = hull[0], hull[-1]
        ab = b - a
        u = min(max(float((point - a) @ ab) / max(float(ab @ ab), 1e-18), 0.0), 1.0)
        return float(np.linalg.norm(point - (a + u * ab)))
    return outside_distance_m(point, hull)


__all__ = ["support_edges", "outside_support_m", "EDGE_FLAT", "EDGE_HEEL", "EDGE_TOE", "EDGE_WORDS"]
