"""Touchdown of the swing feet as the walking controller sees it: the sole corners of a landing foot already on the
ground before its planned touchdown (handed to the whole-body QP as contacts), the flag of a foot the last whole-body
tick stood on while the plan has it in swing (the push observer holds), and the re-latching of a landed foot's
foothold where the foot really is, a few planner ticks after its touchdown."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from engine.control.controller import RobotState
from engine.control.walking_parameters import WalkingParameters
from engine.control.wbc import WbcReference
from engine.control.wbc.reference import N_CORNERS
from engine.gait.footsteps import Foothold
from engine.gait.planner import GaitPlanner, GaitReference
from engine.gait.style import SIDES
from engine.robot.model import RobotModel


class TouchdownTracker:
    """The touchdown state of one walking controller: its pinocchio model and data (shared with the controller: the
    forward kinematics of a landing check writes the controller's data, as before), the feet's frames and sole corners
    (m, from the sole centre), the per-reference contact tables and the planner ticks since each foot's touchdown."""

    __slots__ = ("model", "data", "foot_frames", "corner_offsets_m", "contact_ref", "ref_contact",
                 "landing_candidates", "early_key", "since_touchdown")

    def __init__(self, robot: RobotModel, model: pin.Model, data: pin.Data):
        self.model = model
        self.data = data
        self.foot_frames = [model.getFrameId(f"{side}_foot") for side in SIDES]
        self.corner_offsets_m = np.array([[np.subtract(c, robot.config.soles[side].center)
                                           for c in robot.config.soles[side].corners()] for side in SIDES])
        self.reset()

    def reset(self) -> None:
        self.contact_ref: GaitReference | None = None
        self.ref_contact = np.ones((2, N_CORNERS), dtype=bool)
        # Of the planner's reference (kept until its next tick, see reference_tables): the feet with no corner in
        # contact whose planned vertical velocity is not upward (the only ones with_early_touchdown looks at).
        self.landing_candidates: list[int] = []
        self.early_key: tuple[np.ndarray | None, np.ndarray | None, bool] = (None, None, False)
        self.since_touchdown = [-1, -1]

    def reference_tables(self, ref: GaitReference) -> None:
        """What the ticks until the planner's next one read of its reference ``ref``: the corners in contact and the
        feet that may be landing early (no corner in contact, not moving up)."""
        # ref.corner_contact & ref.contact[:, None] and ref.foot_lin_vel[:, 2] on Python bools and floats (the same
        # flags: a corner is in contact while its foot is; the feet's vertical velocities)
        corners, feet = ref.corner_contact.tolist(), ref.contact.tolist()
        flags = [[bool(c) and bool(down) for c in row] for row, down in zip(corners, feet)]
        up = [vel[2] for vel in ref.foot_lin_vel.tolist()]
        contact = np.array(flags, dtype=bool)
        self.contact_ref, self.ref_contact = ref, contact
        self.landing_candidates = [i for i in range(2) if not any(flags[i]) and up[i] <= 0.0]

    def early_now(self, wbc_contact: np.ndarray, contact: np.ndarray) -> bool:
        """:func:`early_touchdown`, kept while both arrays are the same objects (between planner ticks the whole-body
        contact is the reference's, which is not written in place)."""
        key = self.early_key
        if key[0] is wbc_contact and key[1] is contact:
            return key[2]
        early = early_touchdown(wbc_contact, contact)
        self.early_key = (wbc_contact, contact, early)
        return early

    def with_early_touchdown(self, est: RobotState, reference: WbcReference, ref: GaitReference | None,
                             params: WalkingParameters) -> np.ndarray:
        """Sole corners the whole-body QP may push on: the plan's, plus the corners of a landing
        foot that are already on the ground (a swing foot reaches the floor a few ms before its
        planned touchdown; pretending it is still in the air makes the QP fight the floor). ``ref``: the planner's
        reference ``reference`` was interpolated from (None before the first planner tick)."""
        contact = reference.contact
        height = params.landing_height_m
        if ref is not None and contact is self.ref_contact and self.contact_ref is ref \
                and reference.foot_lin_vel_mps is ref.foot_lin_vel:  # the controller's _wbc_reference: the per-reference tables
            landing = [i for i in self.landing_candidates if self.planned_low(reference, i, height, params)]
        else:
            flags = contact.tolist()
            landing = [i for i in range(2) if not any(flags[i])
                       and self.planned_low(reference, i, height, params) and reference.foot_lin_vel_mps[i, 2] <= 0.0]
        if not landing:
            return contact
        pin.framesForwardKinematics(self.model, self.data, est.q)
        contact = contact.copy()
        for i in landing:
            m = self.data.oMf[self.foot_frames[i]]
            heights = m.translation[2] + (m.rotation @ self.corner_offsets_m[i].T)[2]
            contact[i] = heights < params.touchdown_height_m
        return contact

    def on_rolled_edges(self, est: RobotState, contact: np.ndarray, lift_m: float) -> np.ndarray:
        """``contact`` (2, 4) with each foot rolled about its long axis by more than ``lift_m`` (one side's corners
        that much higher than the other's, on the mean, measured) standing on its lower side's corners only.
        Corners front-left, front-right, back-right, back-left: the left side 0 and 3, the right side 1 and 2."""
        flags = contact.tolist()
        feet = [i for i in range(2) if any(flags[i])]
        if not feet:
            return contact
        pin.framesForwardKinematics(self.model, self.data, est.q)
        out = contact
        for i in feet:
            m = self.data.oMf[self.foot_frames[i]]
            z = (m.rotation @ self.corner_offsets_m[i].T)[2].tolist()
            lift = 0.5 * (z[0] + z[3]) - 0.5 * (z[1] + z[2])  # left side above the right
            if abs(lift) <= lift_m:
                continue
            keep = [False, True, True, False] if lift > 0.0 else [True, False, False, True]
            edge = [f and k for f, k in zip(flags[i], keep)]
            if any(edge):
                if out is contact:
                    out = contact.copy()
                out[i] = edge
        return out

    def planned_low(self, reference: WbcReference, i: int, height: float, params: WalkingParameters) -> bool:
        """Foot ``i``'s planned sole centre below ``height``, or its lowest planned corner below ``landing_corner_height_m``."""
        z = float(reference.foot_pos_m[i, 2])
        if z < height:
            return True
        corner = params.landing_corner_height_m
        return corner > 0.0 and z + float((reference.foot_rotation[i][2] @ self.corner_offsets_m[i].T).min()) < corner

    def relatch_landed_feet(self, est: RobotState, ref: GaitReference, contact_before: np.ndarray,
                            params: WalkingParameters, planner: GaitPlanner) -> list[int]:
        """A few ticks after touchdown, latch the foothold where the foot really is. ``ref``: the planner's reference
        of this tick (after its step), ``contact_before``: the feet in contact before it. Returns the planner ticks
        since each foot's touchdown (−1: in swing)."""
        for i, side in enumerate(SIDES):
            if not ref.contact[i]:
                self.since_touchdown[i] = -1
                continue
            if not contact_before[i]:
                self.since_touchdown[i] = 0
            elif self.since_touchdown[i] >= 0:
                self.since_touchdown[i] += 1
            if self.since_touchdown[i] == params.relatch_after_plan_ticks:
                pin.framesForwardKinematics(self.model, self.data, est.q)
                m = self.data.oMf[self.model.getFrameId(f"{side}_foot")]
                measured = Foothold(float(m.translation[0]), float(m.translation[1]),
                                    float(math.atan2(m.rotation[1, 0], m.rotation[0, 0])))
                if abs(m.translation[2]) < 0.01:  # really down
                    planner.relatch(side, measured)
        return self.since_touchdown


def early_touchdown(wbc_contact: np.ndarray, contact: np.ndarray) -> bool:
    """A foot the last whole-body tick stood on (any corner) that the plan has in swing."""
    corners, planned = wbc_contact.tolist(), contact.tolist()
    return any(any(c) and not p for c, p in zip(corners, planned))
