"""What a robot's legs can physically reach: the style validator's robot-level bounds (issue 13).

Two bounds, both computed from the robot model (joint limits and link geometry), never typed per robot:

* **Step reach.** In a double support both soles rest on their footholds — where the planner puts
  them: the path pose at the middle of each contact ⊕ the stance offset (Eq. 4, the same relation
  as :meth:`engine.gait.planner.GaitPlanner._upcoming_foothold`), so a sample's step is its velocity
  × the time between two contacts' middles. Each ankle is then within ``leg_length_m`` (its links'
  lengths summed, hip joint to ankle joint) of its hip, and the hips sit at the pelvis
  height the style asks (its ``pelvis_height_m`` plus the ``pelvis.z`` curve, the hips lowered by the
  ``pelvis.roll``/``pitch`` curves) and ``hip_separation_m`` apart. Two ankles farther apart than
  ``2 √(leg_length² − Δz²) + hip_separation`` cannot both be reached by any posture, whatever the
  pelvis's horizontal place and yaw; a heel or toe pitch at the contact switch moves the ankle by at
  most ``pitch × pivot_radius_m`` and widens the bound by that. The bound is taken at the best instant
  of each double support (the lowest hips), so it only rejects what no leg posture reaches.
* **Swing roll.** A swing foot's roll beyond what its ankle roll joint turns: the foot's place is
  planned (nominal path plus the x/y offsets), so the hip cannot tilt the leg sideways for it
  (``studio bench styles`` random-0-36 on G1: a roll curve of −0.286 rad against the ankle's ±0.262
  held the reference's own IK at the limit, and the robot fell).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from engine.constants import FOOT_FRAMES
from engine.gait.footsteps import Foothold, SafeRegion, foothold_from_path, project_to_safe_region, stance_offset_xy_yaw
from engine.gait.path_frame import predict_xy_yaw

if TYPE_CHECKING:
    from engine.robot.model import RobotModel

DS_TIMES = 9  # instants per double support at which the hips' height is evaluated


@dataclass(frozen=True)
class LegReach:
    """The legs' geometry that bounds a step (metres, from the robot model)."""

    leg_length_m: float  # the leg's links summed, hip joint to ankle joint: no posture reaches farther
    hip_offset_m: tuple[float, float, float]  # the left hip joint in the pelvis frame (the right one mirrored)
    hip_separation_m: float  # between the two hip joints
    ankle_height_m: float  # the ankle joint above the floor, sole flat
    ankle_to_sole_m: tuple[float, float]  # the sole centre from the ankle joint, in the foot's frame (x, y)
    pivot_radius_m: float  # farthest sole corner from the ankle joint
    sole_length_m: float
    sole_width_m: float
    ankle_roll_range_rad: float  # |roll| both ankle roll joints reach

    @classmethod
    def for_robot(cls, robot: "RobotModel") -> "LegReach":
        import pinocchio as pin

        model = robot.pin_model
        data = model.createData()
        q0 = robot.q_standing.copy()
        pin.framesForwardKinematics(model, data, q0)
        root = data.oMi[1]
        sole = robot.config.soles["left"]
        fid = model.getFrameId(FOOT_FRAMES[0])
        ankle = model.frames[fid].parentJoint
        chain = [j for j in model.supports[ankle] if j > 1]
        hip = chain[0]
        hip_in_root = root.actInv(data.oMi[hip].translation)
        right_hip = [j for j in model.supports[model.frames[model.getFrameId(FOOT_FRAMES[1])].parentJoint] if j > 1][0]
        hip_sep = float(np.linalg.norm(data.oMi[hip].translation - data.oMi[right_hip].translation))
        foot = data.oMf[fid]
        ankle_in_foot = foot.actInv(data.oMi[ankle].translation)
        hl, hw = 0.5 * sole.length_m, 0.5 * sole.width_m
        corners = np.array([[sx * hl, sy * hw, 0.0] for sx in (-1, 1) for sy in (-1, 1)])
        pivot = float(np.max(np.linalg.norm(corners - ankle_in_foot, axis=1)))

        roll = math.inf  # (the soles flat at standing: their long axis is the ankle roll joint's)
        for side_frame in FOOT_FRAMES:
            f = model.getFrameId(side_frame)
            axis_x = data.oMf[f].rotation[:, 0]
            for j in [j for j in model.supports[model.frames[f].parentJoint] if j > 1]:
                axis = _joint_axis(model, data, j)
                if abs(float(axis @ axis_x)) > 0.95:  # turns the foot about its long axis: its ankle roll
                    jq = model.joints[j].idx_q
                    roll = min(roll, abs(float(model.lowerPositionLimit[jq])), abs(float(model.upperPositionLimit[jq])))
        # The sum of the leg's link lengths, joint to joint: each link's length is fixed, so no posture within
        # any joint limits puts the ankle farther from the hip (TALOS's straight leg is it; G1's hip offsets kink its
        # straight leg to 0.639 m of 0.698 m summed).
        pin.forwardKinematics(model, data, pin.neutral(model))
        points = [data.oMi[j].translation for j in chain]
        length = float(sum(np.linalg.norm(b - a) for a, b in zip(points[:-1], points[1:])))

        return cls(leg_length_m=float(length), hip_offset_m=(float(hip_in_root[0]), float(hip_in_root[1]), float(hip_in_root[2])),
                   hip_separation_m=hip_sep, ankle_height_m=float(ankle_in_foot[2]),
                   ankle_to_sole_m=(float(-ankle_in_foot[0]), float(-ankle_in_foot[1])), pivot_radius_m=pivot,
                   sole_length_m=float(sole.length_m), sole_width_m=float(sole.width_m),
                   ankle_roll_range_rad=float(roll) if math.isfinite(roll) else math.inf)

    # ------------------------------------------------------------------ the step bound
    def hip_height_m(self, pelvis_z_m: float, roll_rad: float, pitch_rad: float) -> float:
        """The lower hip joint's height for a pelvis at ``pelvis_z_m`` rolled and pitched (ZYX)."""
        ox, oy, oz = self.hip_offset_m
        sr, cr, sp, cp = math.sin(roll_rad), math.cos(roll_rad), math.sin(pitch_rad), math.cos(pitch_rad)
        return pelvis_z_m + min(-sp * ox + cp * sr * s * oy + cp * cr * oz for s in (1.0, -1.0))

    def ankle_distance_limit_m(self, hip_z_m: float, pitch_allowance_rad: float) -> float:
        """Farthest apart two ankles on the floor can be with both hips at ``hip_z_m`` or higher."""
        dz = max(hip_z_m - self.ankle_height_m, 0.0)
        horizontal = math.sqrt(max(self.leg_length_m ** 2 - dz ** 2, 0.0))
        return 2.0 * horizontal + self.hip_separation_m + pitch_allowance_rad * self.pivot_radius_m

    def ankle_xy(self, foothold: Foothold) -> np.ndarray:
        c, s = math.cos(foothold.yaw), math.sin(foothold.yaw)
        ax, ay = self.ankle_to_sole_m
        return np.array([foothold.x - (c * ax - s * ay), foothold.y - (s * ax + c * ay)])


@dataclass(frozen=True)
class StepReach:
    """The longest of a sample's two steps against what the legs reach there (metres)."""

    ankle_distance_m: float
    limit_m: float
    double_support: str  # "after left touchdown" / "after right touchdown"

    @property
    def excess_m(self) -> float:
        return self.ankle_distance_m - self.limit_m


def step_reach(reach: LegReach, sample, velocity: Sequence[float],
               pelvis_curve: Callable[[str, float], float]) -> StepReach:
    """The worse double support of ``sample`` (a :class:`engine.gait.style.GaitSample`) walked at
    ``velocity`` (vx, vy, wz): its ankles' distance and the limit at that double support's best
    instant. ``pelvis_curve(channel, t_s)`` gives the value of a ``pelvis.*`` curve (0 without one)."""
    iv, a = sample.intervals, sample.attributes
    cycle = iv.cycle_s
    t_ltd, t_rlo, t_rtd, _ = iv.events_s
    mid = {"left": 0.5 * (t_ltd + cycle), "right": 0.5 * (t_rtd + cycle + t_rlo)}
    region = SafeRegion.for_sole(reach.sole_length_m, reach.sole_width_m)

    def foothold(side: str, t_s: float) -> Foothold:
        pose = predict_xy_yaw(0.0, 0.0, 0.0, velocity, t_s)
        return foothold_from_path(pose, stance_offset_xy_yaw(side, a.stance_width_m, a.stance_splay_rad, a.stance_x_bias_m))

    def boundary_pitch(side: str, at_touchdown: bool) -> float:
        out = 0.0
        for tail in ("heel_pitch", "toe_pitch"):
            curve = sample.curves.get(f"{side}_foot.{tail}")
            if curve is not None:
                out = max(out, abs(float(curve.evaluate(curve.duration_s if at_touchdown else 0.0))))
        return out

    worst: StepReach | None = None
    for lead, trail, t0, t1, trail_t, where in (
            ("left", "right", t_ltd, t_rlo, mid["right"] - cycle, "after left touchdown"),
            ("right", "left", t_rtd, cycle, mid["left"], "after right touchdown")):
        trail_fh = foothold(trail, trail_t)
        lead_fh = project_to_safe_region(trail_fh, foothold(lead, mid[lead]), lead, region)
        distance = float(np.linalg.norm(reach.ankle_xy(lead_fh) - reach.ankle_xy(trail_fh)))
        allowance = boundary_pitch(lead, True) + boundary_pitch(trail, False)
        limit = max(reach.ankle_distance_limit_m(
            reach.hip_height_m(a.pelvis_height_m + pelvis_curve("pelvis.z", t), pelvis_curve("pelvis.roll", t),
                               pelvis_curve("pelvis.pitch", t)), allowance)
            for t in np.linspace(t0, t1, DS_TIMES).tolist())
        found = StepReach(distance, limit, where)
        if worst is None or found.excess_m > worst.excess_m:
            worst = found
    assert worst is not None
    return worst


def _joint_axis(model, data, j: int) -> np.ndarray:
    """A revolute joint's axis in the world (zeros for other joints)."""
    s = model.joints[j].shortname()
    if not s.startswith("JointModelR"):
        return np.zeros(3)
    if s.endswith("X"):
        local = np.array([1.0, 0.0, 0.0])
    elif s.endswith("Y"):
        local = np.array([0.0, 1.0, 0.0])
    elif s.endswith("Z"):
        local = np.array([0.0, 0.0, 1.0])
    else:  # JointModelRevoluteUnaligned
        local = np.asarray(model.joints[j].extract().axis, dtype=float)
    return data.oMi[j].rotation @ local


def sample_step_reach(reach: LegReach, sample, velocity: Sequence[float]) -> StepReach:
    """:func:`step_reach` with the sample's own ``pelvis.*`` curves."""
    def pelvis_curve(channel: str, t_s: float) -> float:
        curve = sample.curves.get(channel)
        return 0.0 if curve is None else float(curve.evaluate(t_s % curve.duration_s))

    return step_reach(reach, sample, velocity, pelvis_curve)


def max_reachable_speed(reach: LegReach, sample, unit_velocity: Sequence[float], hi: float = 10.0) -> float:
    """The largest ``s`` ≤ ``hi`` with ``s × unit_velocity`` within reach for ``sample`` (bisection, to 0.1 %)."""
    def ok(s: float) -> bool:
        return sample_step_reach(reach, sample, tuple(s * u for u in unit_velocity)).excess_m <= 0.0

    if ok(hi):
        return hi
    lo = 0.0
    if not ok(lo):
        return 0.0
    while hi - lo > 1e-3 * hi:
        m = 0.5 * (lo + hi)
        lo, hi = (m, hi) if ok(m) else (lo, m)
    return lo
