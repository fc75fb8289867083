"""Warm starts of the CoM MPC's active set: the previous solutions' active rows, matched to this call's rows by
waypoint time and kind and by edge normal (shifted timings and moved footholds keep the warm start)."""

from __future__ import annotations

from engine.control.mpc.active_set import _NO_KEYS, _NO_NORMALS

#: Warm start: a previous active row matches a row of a waypoint of the same kind
#: (midpoint / end) within this time [s] and with an edge normal this parallel.
WARM_TIME_TOL_S = 0.03
WARM_KIND_OFFSET_S = 1e3  # separates midpoints from end points in the matching key
#: Number of previous solutions whose active rows are tried as warm starts.
WARM_HISTORY = 2
WARM_NORMAL_COS = 0.999


def two_newest(history: list) -> list:
    """The warm-start history's two newest entries, padded with empty ones (what the compiled solves take)."""
    return (list(history) + [(_NO_KEYS, _NO_NORMALS)] * 2)[:2]
