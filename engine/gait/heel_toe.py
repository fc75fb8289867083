"""Heel/toe "reverse foot lock" (paper Fig. 5) and the support-phase heel/toe transitions.

The stylized foot rotation is four angles (θ, ψ_heel, ψ_toe, γ) applied in that order: yaw θ
about the sole centre, pitch ψ_heel about the heel (toes rise for ψ_heel < 0), pitch ψ_toe
about the resulting toe (heel rises for ψ_toe > 0), then roll γ. With
−π/2 ≤ ψ_heel ≤ 0 ≤ ψ_toe ≤ π/2 the rig keeps the heel and toe at or above the ground; a
smooth vertical offset (W/2)·|sin γ| keeps a rolled sole edge up too (the translation
offset x_heel-toe of §4.3).
"""

from __future__ import annotations

import math

import numpy as np

from engine.geometry import rot_zyx, smoothstep


ROLL_SMOOTHING = 0.003  # δ of the smooth |sin γ|: under-lifts a rolled sole edge by at most δ·W/2


def foot_rig(length_m: float, yaw: float, heel_pitch: float, toe_pitch: float, roll: float,
             width_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t of the rigged foot in the nominal (flat) foot frame.

    Points of the foot map as p ↦ R p + t; the frame sits at the sole centre, x forward.
    R = Rz(θ) Ry(ψ_heel + ψ_toe) Rx(γ); t keeps the heel fixed through the heel pitch and
    the (moved) toe fixed through the toe pitch, and lifts the foot by (W/2)·|sin γ| (smoothed
    so the reference stays C1) so a rolled sole edge stays at or above the ground.
    """
    if yaw == 0.0 and heel_pitch == 0.0 and toe_pitch == 0.0 and roll == 0.0:
        return np.eye(3), np.zeros(3)
    half = 0.5 * length_m
    # In the yawed foot frame: heel h = (−L/2, 0, 0); toe after the heel pitch:
    ch, sh = math.cos(heel_pitch), math.sin(heel_pitch)
    toe_x, toe_z = -half + length_m * ch, -length_m * sh
    # Second pitch about the moved toe: t = toe1 + Ry(ψt)(h − Ry(ψh) h − toe1)
    hx = -half - (-half * ch) - toe_x
    hz = 0.0 - (half * sh) - toe_z
    ct, st = math.cos(toe_pitch), math.sin(toe_pitch)
    tx = toe_x + ct * hx + st * hz
    tz = toe_z - st * hx + ct * hz
    if roll != 0.0 and width_m > 0.0:
        sr = math.sin(roll)
        tz += 0.5 * width_m * (math.sqrt(sr * sr + ROLL_SMOOTHING ** 2) - ROLL_SMOOTHING)
    cz, sz = math.cos(yaw), math.sin(yaw)
    rot = rot_zyx(yaw, heel_pitch + toe_pitch, roll)
    return rot, np.array([cz * tx, sz * tx, tz])


def lift_to_ground(rot: np.ndarray, trans: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Translation raised so no sole corner (rows of ``corners``, foot frame) is below z = 0.

    Only C0 (a max over corners): the planner's rig keeps soles above ground smoothly; this is
    the exact check used where smoothness does not matter (editing previews, tests)."""
    z = corners @ rot[2] + trans[2]
    low = float(z.min())
    if low < 0.0:
        trans = trans.copy()
        trans[2] -= low
    return trans


def stance_pitch(t_since_touchdown_s: float, t_until_liftoff_s: float, touchdown_pitch: tuple[float, float],
                 liftoff_pitch: tuple[float, float], touchdown_transition_s: float,
                 liftoff_transition_s: float) -> tuple[float, float]:
    """(ψ_heel, ψ_toe) during support: from the touchdown angles to flat, and from flat to the liftoff angles.

    Each transition eases (smoothstep, so the foot's rate is continuous with the swing's flat
    boundary tangents) over its duration; the caller caps durations to the foothold.
    """
    heel, toe = 0.0, 0.0
    if touchdown_transition_s > 0 and t_since_touchdown_s < touchdown_transition_s:
        w = 1.0 - smoothstep(t_since_touchdown_s / touchdown_transition_s)
        heel += w * touchdown_pitch[0]
        toe += w * touchdown_pitch[1]
    if liftoff_transition_s > 0 and t_until_liftoff_s < liftoff_transition_s:
        w = 1.0 - smoothstep(t_until_liftoff_s / liftoff_transition_s)
        heel += w * liftoff_pitch[0]
        toe += w * liftoff_pitch[1]
    return heel, toe
