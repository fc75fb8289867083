"""Stance slip: how far a sole that is really in stance drifts on the ground.

A foot is in stance when the plan holds it flat on the ground *and* MuJoCo's floor contacts push
on it with more than ``STANCE_LOAD_FRACTION`` of the body weight. Its drift is measured from where
its sole centre was after ``SLIP_SETTLE_S`` of stance (the landing itself settles first); the
anchor is dropped as soon as either condition ends. So a foot still in the air after a late
touchdown (a stumble) does not count its air travel as slip, while a loaded sole that slides does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SLIP_SETTLE_S = 0.02  # ignore the first moments of a contact (the landing itself)
STANCE_LOAD_FRACTION = 0.1  # of the body weight: below it a foot touches but does not stand


@dataclass
class StanceSlipMeter:
    """Largest sole drift in stance over a walk, fed once per simulation tick."""

    dt_s: float
    body_weight_n: float
    load_fraction: float = STANCE_LOAD_FRACTION
    settle_s: float = SLIP_SETTLE_S
    max_slip_m: float = 0.0
    _since_s: np.ndarray = field(default_factory=lambda: np.zeros(2))
    _anchor_xy_m: list[np.ndarray | None] = field(default_factory=lambda: [None, None])

    def update(self, planned_flat: np.ndarray, sole_xy_m: np.ndarray, load_n: np.ndarray) -> np.ndarray:
        """One tick: ``planned_flat[i]`` the plan holds foot i flat on the ground, ``sole_xy_m[i]``
        its sole centre, ``load_n[i]`` the floor's normal force on it. Returns this tick's drift of
        each anchored foot (0 where none), in metres."""
        drift = np.zeros(2)
        threshold_n = self.load_fraction * self.body_weight_n
        for i in range(2):
            if planned_flat[i] and load_n[i] > threshold_n:
                self._since_s[i] += self.dt_s
                if self._since_s[i] >= self.settle_s:
                    anchor = self._anchor_xy_m[i]
                    if anchor is None:
                        anchor = self._anchor_xy_m[i] = np.array(sole_xy_m[i], dtype=float)
                    drift[i] = float(np.linalg.norm(np.asarray(sole_xy_m[i]) - anchor))
            else:
                self._since_s[i] = 0.0
                self._anchor_xy_m[i] = None
        self.max_slip_m = max(self.max_slip_m, float(drift.max()))
        return drift
