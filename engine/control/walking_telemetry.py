"""The walking controller's telemetry: the signals the studio's overlays and plots read (CoM and CoP,
their plans, the support polygons, the footholds, the feedback, the solvers' status, the observed push),
assembled on demand from the controller's last planner tick (the studio reads them at 20 Hz)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from engine.control.gait_feedback import FeedbackOutput
from engine.control.mpc import ComMpcSolution
from engine.gait.planner import GaitReference


@dataclass
class WalkingTelemetry:
    """What the studio's overlays and plots need, refreshed every planner tick."""

    t_s: float = 0.0
    com_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    com_ref_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    cop_ref_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    com_path_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    cop_path_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    support_polygon: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    preview_polygons: list[np.ndarray] = field(default_factory=list)
    footholds: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # planned (x, y, yaw)
    sample_weights: np.ndarray = field(default_factory=lambda: np.zeros(9))
    feedback: FeedbackOutput | None = None
    command: np.ndarray = field(default_factory=lambda: np.zeros(3))
    command_clamped: bool = False
    mpc_status: str = ""
    wbc_status: str = ""
    external_force_n: np.ndarray = field(default_factory=lambda: np.zeros(2))  # observed horizontal push
    recovery_share: float = 0.0  # the neutral gait's share in the blend while balance recovers (0: the style)
    recovery_starting: bool = False  # that share is the walk's start from neutral, not a recovery


def update_telemetry(tel: WalkingTelemetry, ref: GaitReference, plan: ComMpcSolution | None, com: np.ndarray,
                     fb: FeedbackOutput, mpc_shift: np.ndarray, command_clamped: bool, wbc_diagnostics: object,
                     external_force_n: np.ndarray) -> None:
    """Refresh ``tel`` in place from the planner's reference ``ref``, the CoM plan ``plan`` (planned in a frame
    shifted by ``mpc_shift``, m), the CoM ``com`` and feedback ``fb`` of that planner tick, the planner's
    command clamp, the whole-body controller's diagnostics and the observer's push (N)."""
    tel.t_s = ref.t_s
    tel.com_xy = com
    if plan is not None:
        tel.com_ref_xy = plan.com_at(ref.t_s)[0]
        tel.cop_ref_xy = plan.cop_at(ref.t_s) - mpc_shift
        _, tel.com_path_xy = plan.com_path(0.04)
        tel.cop_path_xy = plan.waypoints_xy_m - mpc_shift
        tel.mpc_status = plan.status
    tel.support_polygon = ref.preview[0].polygon if ref.preview else np.zeros((0, 2))
    tel.preview_polygons = [p.polygon for p in ref.preview]
    holds: list[np.ndarray] = []
    for p in ref.preview:
        for hold in p.footholds.values():
            row = hold.as_array()
            if not holds or np.abs(np.asarray(holds[-1]) - row).max() > 1e-9:
                holds.append(row)
    tel.footholds = np.unique(np.round(np.array(holds), 6), axis=0) if holds else np.zeros((0, 3))
    tel.sample_weights = ref.sample_weights
    tel.feedback = fb
    tel.command = ref.command
    tel.command_clamped = command_clamped
    tel.wbc_status = getattr(wbc_diagnostics, "status", "")
    tel.external_force_n = external_force_n.copy()
