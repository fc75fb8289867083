"""Speed-ups of the gait planner compute the same numbers as the code they replaced (kept here)."""

from __future__ import annotations

import numpy as np

from engine.gait.footsteps import stance_offset, stance_offset_xy_yaw
from engine.gait.phase_map import PHASE_WAYPOINTS, PhaseMap, _pchip_slope


def phase_map_tables_reference(ev: tuple[float, float, float, float]) -> tuple[list, list]:
    """PhaseMap.__init__'s slopes and segments before the speed-up (weights computed per call)."""
    phi = list(PHASE_WAYPOINTS)
    times = [0.0, ev[0], ev[1], ev[2], ev[3]]
    hs = [phi[i + 1] - phi[i] for i in range(4)]
    ds = [(times[i + 1] - times[i]) / hs[i] for i in range(4)]
    slopes = [0.0] * 5
    for i in range(1, 4):
        slopes[i] = _pchip_slope(ds[i - 1], ds[i], hs[i - 1], hs[i])
    slopes[0] = slopes[4] = _pchip_slope(ds[3], ds[0], hs[3], hs[0])
    seg = []
    for i in range(4):
        h, d, m0, m1 = hs[i], ds[i], slopes[i], slopes[i + 1]
        c2 = (3.0 * d - 2.0 * m0 - m1) / h
        c3 = (m0 + m1 - 2.0 * d) / (h * h)
        seg.append((phi[i], times[i], m0, c2, c3, h, times[i + 1]))
    return slopes, seg


def test_phase_map_tables_match_the_reference() -> None:
    rng = np.random.default_rng(3)
    for _ in range(2000):
        ev = tuple(np.cumsum(rng.uniform(0.01, 0.6, 4)).tolist())
        slopes, seg = phase_map_tables_reference(ev)
        pm = PhaseMap(*ev)
        assert pm._slopes == slopes  # exact float equality, element by element
        assert pm._seg == seg


def test_stance_offset_floats_match_the_array() -> None:
    rng = np.random.default_rng(4)
    for _ in range(500):
        width, splay, bias = rng.normal(0.0, 0.3, 3).tolist()
        for side in ("left", "right"):
            assert stance_offset_xy_yaw(side, width, splay, bias) == tuple(stance_offset(side, width, splay, bias).tolist())
