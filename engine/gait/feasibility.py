"""Edit-time feasibility check: will the robot be able to walk this sample? (issue 13)

For a gait sample, the planner walks the sample's own velocity open loop (kinematic, no
physics): from standing the command ramps up at the controller's joystick rate limits, two
cycles settle, and over the next cycle, ``TICKS_PER_CYCLE`` times:

* reach — least-squares IK of both soles, pelvis height and rotation (the pelvis free to move
  horizontally, pulled gently toward the support-centre CoM plan of the kinematic preview):
  a foot on the ground more than ``REACH_TOLERANCE_M`` from its plan (a swing foot more than
  ``SWING_REACH_TOLERANCE_M``) means no leg posture reaches it; the leg joints then at a
  limit name the reason ("right knee straight: lower the pelvis or shorten the stride",
  "left knee fully bent: raise the pelvis height");
* joint speed — finite differences of that IK against the model's velocity limits (severity
  "rating": the simulation models no velocity limit and walks such styles; a real motor may not
  keep up);
* torque — in single support, the links' gravity plus the robot's weight carried by the stance
  sole along the CoM's vertical (clamped to the sole less the CoP margin: a static equilibrium),
  against the torque limit the controller uses (90 % of the effort);
* swing clearance — a swing foot's sole corners below the floor, or an apex below
  ``MIN_CLEARANCE_M``;
* balance — the CoM MPC (the controller's, solved every tick along the same open-loop walk from
  standing, each solve continuing the last plan) plans the CoM on a pendulum of constant height; the
  pelvis height curve moves the CoM up and down, and the CoP that the plan's horizontal acceleration
  then needs (engine/gait/zmp_feasibility.py: ``p = c − z c̈ / (g + z̈)``) is flagged beyond the soles
  (``BALANCE_TOLERANCE_M``) or where the feet carry less than ``MIN_LOAD_SHARE`` of the weight;
* curve rates — each curve of the sample against the rate and acceleration its channel can
  follow (engine/gait/curve_rates.py: a joint's velocity limit, and the robot's
  ``[gait.curve_rates]`` bounds — by default twice the shipped styles' peaks, G1 about once):
  two knots too close for the change between them are flagged with the curve and the phase where
  its rate or acceleration peaks.

Each finding names the sample, the phase (% of its cycle, from left liftoff) and what to do in
an animator's words; findings are deduplicated per (sample, kind, joint or side): the first
phase where a problem shows. Cost: ~0.3 s of CPU per sample (half of it the balance part). What it
does not check (the recorded falls of ``studio bench styles`` show what is missed): the closed loop
(the robot leaving the plan, the feedback's step adjustments), the limbs' angular momentum and
friction.

What the check cannot predict from the reference (measured 2026-11-29 on the 32 random styles of
``studio bench styles --robot g1 --n 8 --seed S --duration 20 --extent 0.15``, S = 2…5: 13 falls,
12 of them not flagged). Per style, the largest over the samples the sweep reaches of: the
angular-momentum rate about the CoM of the kinematic reference in single support (limbs and
pelvis, 96 IK solves per cycle), peak leg joint acceleration, the swing sole's orientation and
position residuals, the stance sole's residual, the least leg-joint limit margin, swing apex,
cycle time. For each, the threshold that marks all 13 falls also marks 14–19 of the 19 walkers
(the least: the stance sole's residual, 14/19), so none of them is a flag here. The recordings
show falls that begin in the closed loop, not in the reference: the CoM falls 2–4 cm behind the
MPC's plan in the first forward steps of the command ramp (random-2-3 at 1.7 s, random-3-1 at
1.3–1.6 s; walkers' CoM lags > 15 mm too), then the step adjustment moves the swing foot's target
back (random-2-3: 20 cm in 50 ms at 1.71 s) and the robot walks backward under a forward command
until it falls (random-2-3, 2-4, 4-7: the CoM 0.2–0.4 m behind where it started under 0.4 m/s
forward; the "runaway" of README *Why the seed-2 styles fall*).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from engine.constants import GRAVITY_MPS2
from engine.gait.curve_rates import curve_peaks, rate_bound
from engine.gait.style import SIDES, Style, StyleContext, channel_side
from engine.gait.velocity_sampler import SAMPLE_NAMES
from engine.gait.zmp_feasibility import MIN_LOAD_SHARE, cop_demands, support_at
from engine.robot.model import RobotModel

TICKS_PER_CYCLE = 24
SETTLE_CYCLES = 2.0  # cycles at the sample's velocity before the checked one
REACH_TOLERANCE_M = 0.01  # a foot on the ground (or the pelvis height) this far out of reach: flagged
# A swing foot may miss its curve by a little more: walks of ``studio bench styles`` and one-factor
# variants of G1 neutral (README) show swing misses of 10–15 mm just after liftoff (the ankle at
# its limit) walk, while a heel pitch of 0.4 rad mid-swing (misses of 19–24 mm, the ankle at its
# limit for most of the swing) falls, and a foot on the ground 10 mm out of reach falls.
SWING_REACH_TOLERANCE_M = 0.018
COM_WEIGHT = 0.3
LIMIT_MARGIN_RAD = 0.01
VELOCITY_SHARE = 1.0  # joint speed beyond this share of the velocity limit is flagged
TORQUE_SHARE = 0.9  # the controller's torque limit (share of the URDF effort)
TORQUE_TOLERANCE = 1.25  # the estimate is static (no accelerations): flag beyond this × the limit
MIN_CLEARANCE_M = 0.01
# The CoP the MPC's plan needs (engine/gait/zmp_feasibility.py) beyond a sole's edge by more than this: flagged.
# The point-mass estimate leaves out what the closed loop also uses (the limbs' angular momentum, the feedback):
# random reachable styles that walk the 60 s sweep need up to 8 mm (G1) and 17 mm (TALOS) beyond a sole by it
# (README, stop 37), so the flag starts at 2 cm.
BALANCE_TOLERANCE_M = 0.02
FLOOR_TOLERANCE_M = 0.005

JOINT_WORDS = {"hip_pitch": "hip", "hip_roll": "hip (sideways)", "hip_yaw": "hip (twist)", "knee": "knee",
               "ankle_pitch": "ankle", "ankle_roll": "ankle (sideways)", "leg_1": "hip (twist)", "leg_2": "hip (sideways)",
               "leg_3": "hip", "leg_4": "knee", "leg_5": "ankle", "leg_6": "ankle (sideways)"}


@dataclass(frozen=True)
class Finding:
    sample: str
    phase_pct: float
    kind: str  # reach | joint_limit | joint_speed | torque | balance | clearance | curve_rate
    side: str | None
    message: str
    # "fall": the robot is expected to fall or stumble; "rating": beyond what the real robot is rated
    # for, which the simulation does not model (joint speeds: MuJoCo and the controller have no
    # velocity limit, and TALOS walks forward_fast with its knee at 8.2 rad/s, rated 7 — README).
    severity: str = "fall"

    def text(self) -> str:
        return f"{self.sample}, around {self.phase_pct:.0f} % of the cycle: {self.message}"


def _joint_words(name: str) -> tuple[str | None, str]:
    """("left", "knee") from left_knee_joint (G1) or leg_left_4_joint (TALOS)."""
    side = "left" if "left" in name else ("right" if "right" in name else None)
    base = name.removesuffix("_joint").replace("left_", "").replace("right_", "").replace("_left", "").replace("_right", "")
    return side, JOINT_WORDS.get(base, base.replace("_", " "))


def _hint(kind: str, words: str, bent: bool | None = None) -> str:
    if kind == "joint_limit" and words == "knee":
        return "raise the pelvis height" if bent else "lower the pelvis or shorten the stride"
    if kind == "joint_limit" and words == "ankle":
        return "raise the pelvis height, shorten the stride or reduce the heel/toe pitch"
    if kind in ("reach", "joint_limit"):
        return "raise or lower the pelvis height, shorten the stride or narrow the stance"
    if kind == "torque":
        return "raise the pelvis (less knee bend), soften the curves or lengthen the cycle"
    if kind == "joint_speed":
        return "lengthen the swing or soften the curve"
    return ""


class FeasibilityChecker:
    """Checks samples of styles of one robot (reuses the models between calls)."""

    def __init__(self, robot: RobotModel, ctx: StyleContext | None = None):
        from engine.control.foot_geometry import toe_trim_m
        from engine.control.walking_parameters import WalkingParameters
        from engine.gait.kinematic_preview import FOOT_FRAMES, KinematicPreview

        self.robot = robot
        self.ctx = ctx or StyleContext.for_robot(robot.name)
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.ik = KinematicPreview(robot, self.ctx.upper_joints)
        self.foot_ids = [self.model.getFrameId(f) for f in FOOT_FRAMES]
        self.walking = WalkingParameters.for_robot(robot.name)
        self.margin_m = self.walking.cop_margin_m
        self.toe_trim_m = toe_trim_m(robot, self.margin_m, self.walking.ankle_load_factor)
        names = robot.joint_names
        legs: set[int] = set()
        for fid in self.foot_ids:
            legs.update(j for j in self.model.supports[self.model.frames[fid].parentJoint] if j > 1)
        self.leg_joints = sorted(legs)
        self.leg_names = [self.model.names[j] for j in self.leg_joints]
        self.leg_q = np.array([self.model.joints[j].idx_q for j in self.leg_joints])
        self.leg_v = np.array([self.model.joints[j].idx_v for j in self.leg_joints])
        self.lower = self.model.lowerPositionLimit[self.leg_q]
        self.upper = self.model.upperPositionLimit[self.leg_q]
        self.vel_limit = self.model.velocityLimit[self.leg_v]
        effort = np.array([robot.effort_limits[names.index(n)] for n in self.leg_names])
        self.torque_limit = TORQUE_SHARE * np.where(effort > 0, effort, np.inf)
        half = 0.5 * robot.config.soles["left"].length_m
        self.sole_half = (half, 0.5 * robot.config.soles["left"].width_m)
        data = self.model.createData()
        self.com_offset_m = float(pin.centerOfMass(self.model, data, robot.q_standing)[2] - robot.q_standing[2])

    # ------------------------------------------------------------------ public
    def check_style(self, style: Style, samples: tuple[str, ...] = SAMPLE_NAMES) -> list[Finding]:
        out: list[Finding] = []
        for name in samples:
            out.extend(self.check_sample(style, name))
        return out

    def check_sample(self, style: Style, name: str, balance: bool = True) -> list[Finding]:
        """Findings for sample ``name``; ``balance=False`` leaves out the CoP the MPC's plan needs (the costliest
        part: an MPC solve per tick; the reachable style space's predicate reads only the kinematic findings)."""
        from engine.gait.kinematic_preview import SupportCenterComPlan
        from engine.gait.offline_plan import planner_for
        from engine.gait.zmp_feasibility import PlanFollower

        robot = self.robot
        planner = planner_for(robot, style, self.ctx)
        planner.preview_margin_m = self.margin_m
        planner.preview_toe_trim_m = self.toe_trim_m
        command = np.array(style.velocities.velocity_of(name))
        cycle = style.samples[name].intervals.cycle_s
        dt = cycle / TICKS_PER_CYCLE
        # The trailing CoM follower (no path feed-forward): the findings and the tests of constructed
        # failing styles were calibrated with it (issue 13's low-and-wide style is flagged in
        # reverse_fast only with it: with the feed-forward its stance ankle stays inside its limit).
        com_plan = SupportCenterComPlan(feed_forward=False)
        q = robot.q_standing.copy()
        findings: dict[tuple[str, str | None], Finding] = {}
        self._curve_rates(findings, style, name)  # (first: it names the curve the animator edits)
        q_prev = None
        # Like the controller: from standing, the command ramps up at the joystick's rate limits;
        # then two cycles settle at the sample's velocity and one is checked.
        limits = np.array(self.walking.command_accel_limits, dtype=float)
        ramp_s = float(np.max(np.abs(command) / limits))
        n_settle = int(math.ceil((ramp_s + planner.hold_s) / dt + SETTLE_CYCLES * TICKS_PER_CYCLE))
        n_total = n_settle + TICKS_PER_CYCLE
        apex = {s: 0.0 for s in SIDES}
        swung = {s: False for s in SIDES}
        commanded = np.zeros(3)
        follower = PlanFollower(self.walking.mpc_preview_s) if balance else None
        heights: deque[float] = deque(maxlen=TICKS_PER_CYCLE)  # the last cycle's CoM heights: their mean is the pendulum's
        walked: dict[str, list] = {k: [] for k in ("t", "z", "lip", "com", "cop", "support", "pct", "contact")}
        for k in range(n_total):
            commanded = commanded + np.clip(command - commanded, -limits * dt, limits * dt)
            ref = planner.step(dt, commanded, with_preview=False)
            com = com_plan.step(dt, ref)
            if follower is not None:
                heights.append(ref.pelvis_z + self.com_offset_m)
                supports = planner.preview()
                lip = float(np.mean(heights))
                plan_com, plan_cop, _ = follower.step(float(ref.t_s), supports, lip, ref.foot_pos[:, :2].mean(axis=0))
                if k >= n_settle:
                    for key, value in (("t", float(ref.t_s)), ("z", heights[-1]), ("lip", lip), ("com", plan_com),
                                       ("cop", plan_cop), ("support", support_at(supports, float(ref.t_s))),
                                       ("contact", ref.contact.copy())):
                        walked[key].append(value)
            if k < n_settle:
                continue
            blend = planner.blend
            assert blend is not None  # the planner blends on its first step
            pct = 100.0 * (blend.time_at(ref.phase) % cycle) / cycle
            walked["pct"].append(pct)
            if q_prev is None:  # start the IK at the pelvis's pose on the path
                yaw = float(ref.path_pose[2])
                q[0:3] = [ref.path_pose[0], ref.path_pose[1], ref.pelvis_z]
                q[3:7] = [0.0, 0.0, math.sin(0.5 * yaw), math.cos(0.5 * yaw)]  # pinocchio: x, y, z, w
            q, pelvis_err, foot_err = self._reach_ik(ref, q, com)
            short = [foot_err[i] - (REACH_TOLERANCE_M if ref.contact[i] else SWING_REACH_TOLERANCE_M) for i in range(2)]
            if max(short) > 0.0 or pelvis_err > REACH_TOLERANCE_M:
                at_limit = self._limits(q)  # which joints stop it
                i = int(np.argmax(short)) if max(short) > 0.0 else int(np.argmax(foot_err))
                side = SIDES[i]
                mine = [lim for lim in at_limit if lim[0].startswith(side)] or at_limit
                why, hint = (f", {mine[0][1]}", mine[0][2]) if mine else ("", _hint("reach", ""))
                if max(short) <= 0.0:
                    text = f"the pelvis cannot reach its height ({1000 * pelvis_err:.0f} mm off){why}"
                elif ref.contact[i]:
                    text = f"the {side} foot cannot stay where it is planned on the ground{why} ({1000 * foot_err[i]:.0f} mm short)"
                else:
                    text = f"the {side} foot's swing is out of the leg's reach{why} ({1000 * foot_err[i]:.0f} mm short)"
                self._add(findings, Finding(name, pct, "reach", side, f"{text}: {hint}"))
                for key, phrase, lim_hint in at_limit:
                    if not mine or key != mine[0][0]:  # (the one named above is not repeated)
                        self._add(findings, Finding(name, pct, "joint_limit", key, f"{phrase}: {lim_hint}"))
            if q_prev is not None:
                self._speed(findings, name, pct, pin.difference(self.model, q_prev, q) / dt)
            q_prev = q
            self._torque(findings, name, pct, ref, q)
            for i, side in enumerate(SIDES):
                if not ref.contact[i]:
                    swung[side] = True
                    apex[side] = max(apex[side], float(ref.foot_pos[i, 2]))
                    low = float(ref.sole_corners[i, :, 2].min())
                    if low < -FLOOR_TOLERANCE_M:
                        self._add(findings, Finding(name, pct, "clearance", side,
                                                    f"the {side} foot digs {1000 * -low:.0f} mm into the floor during its swing: "
                                                    "raise its swing height or reduce its heel/toe pitch"))
        if follower is not None:
            self._balance(findings, name, walked)
        for side in SIDES:
            if swung[side] and apex[side] < MIN_CLEARANCE_M:
                self._add(findings, Finding(name, 50.0, "clearance", side,
                                            f"the {side} foot barely lifts ({1000 * apex[side]:.0f} mm): raise its swing height"))
        return list(findings.values())

    # ------------------------------------------------------------------ checks
    def _curve_rates(self, findings: dict, style: Style, name: str) -> None:
        """Each curve of the sample against the rate and acceleration its channel can follow."""
        sample = style.samples[name]
        cycle = sample.intervals.cycle_s
        for channel, curve in sample.curves.items():
            bound = rate_bound(channel, self.ctx)
            peaks = curve_peaks(curve)
            side = channel_side(channel)
            start = sample.intervals.swing_s(side)[0] if side else 0.0
            unit = bound.unit
            if peaks.rate > bound.rate:
                t, what = peaks.rate_t_s, (f"changes at {peaks.rate:.3g} {unit}/s (the robot follows up to "
                                           f"{bound.rate:.3g} {unit}/s)")
            elif peaks.accel > bound.accel:
                t, what = peaks.accel_t_s, (f"turns too sharply: {peaks.accel:.3g} {unit}/s² (the robot follows up to "
                                            f"{bound.accel:.3g} {unit}/s²)")
            else:
                continue
            pct = 100.0 * ((start + t) % cycle) / cycle
            self._add(findings, Finding(name, pct, "curve_rate", channel,
                                        f"the {channel} curve {what}: move its knots further apart or make the change smaller"))

    def _balance(self, findings: dict, name: str, walked: dict[str, list]) -> None:
        """The CoP the MPC's plan needs once the pelvis height curve moves the CoM up and down
        (engine/gait/zmp_feasibility.py): beyond a sole's edge, or with the feet nearly unloaded."""
        demands = cop_demands(np.array(walked["t"]), np.array(walked["z"]), np.array(walked["com"]), np.array(walked["cop"]),
                              walked["support"], np.array(walked["lip"]), self.margin_m)
        if not demands or any(d.plan_diverged for d in demands):  # (the open-loop plan fell behind: no verdict)
            return
        j = int(np.argmin([d.load_share for d in demands]))
        if demands[j].load_share < MIN_LOAD_SHARE:  # (the CoP is meaningless there: the feet barely push)
            self._add(findings, Finding(name, walked["pct"][j], "balance", None,
                                        f"the pelvis drops almost as fast as falling (the feet carry "
                                        f"{100 * max(demands[j].load_share, 0.0):.0f} % of the weight): soften the pelvis height curve"))
            return
        i = int(np.argmax([d.outside_m for d in demands]))
        worst = demands[i]
        if worst.outside_m > BALANCE_TOLERANCE_M:
            contact = walked["contact"][i]
            where = f"the {SIDES[int(np.argmax(contact))]} sole's edge" if contact.sum() == 1 else "the feet"
            self._add(findings, Finding(name, walked["pct"][i], "balance", None,
                                        f"the body's up-and-down motion needs the centre of pressure "
                                        f"{1000 * worst.outside_m:.0f} mm beyond {where} to keep balance: "
                                        "soften the pelvis height curve or lengthen the cycle"))

    @staticmethod
    def _add(findings: dict, finding: Finding) -> None:
        findings.setdefault((finding.kind, finding.side), finding)

    def _reach_ik(self, ref, q0: np.ndarray, com_xy: np.ndarray) -> tuple[np.ndarray, float, list[float]]:
        """Least-squares IK of both soles (6-D each), pelvis height and rotation; the pelvis may
        move horizontally (the controller places the CoM): the residuals are what no posture of
        the legs reaches. Joints stay within their limits. The CoM is pulled toward the plan's
        (weight ``COM_WEIGHT``) so the posture is the one the controller would take.
        Returns (q, pelvis height error, [sole position error per foot])."""
        model, data = self.model, self.data
        q = q0.copy()
        if len(self.ik.upper_q_index):
            q[self.ik.upper_q_index] = ref.upper_q
        rows = np.zeros(18)
        jac = np.zeros((18, model.nv))
        active = self.ik.active_v
        lo, hi = model.lowerPositionLimit[7:], model.upperPositionLimit[7:]
        for _ in range(15):
            pin.computeJointJacobians(model, data, q)
            pin.updateFramePlacements(model, data)
            for i, fid in enumerate(self.foot_ids):
                cur = data.oMf[fid]
                rows[6 * i:6 * i + 3] = ref.foot_pos[i] - cur.translation
                rows[6 * i + 3:6 * i + 6] = pin.log3(ref.foot_rot[i] @ cur.rotation.T)
                jac[6 * i:6 * i + 6] = pin.getFrameJacobian(model, data, fid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            root = data.oMf[self.ik.root_id]
            jroot = pin.getFrameJacobian(model, data, self.ik.root_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            rows[12] = ref.pelvis_z - root.translation[2]
            jac[12] = jroot[2]
            rows[13:16] = pin.log3(ref.pelvis_rot @ root.rotation.T)
            jac[13:16] = jroot[3:6]
            com = pin.centerOfMass(model, data, q, False)
            rows[16:18] = COM_WEIGHT * (com_xy - com[:2])
            jac[16:18] = COM_WEIGHT * pin.jacobianCenterOfMass(model, data, q, False)[:2]
            ja = jac[:, active]
            step = np.linalg.solve(ja.T @ ja + 1e-3 * np.eye(len(active)), ja.T @ rows)
            norm = float(np.linalg.norm(step))
            if norm < 1e-6:
                break
            if norm > 0.2:  # Gauss–Newton far from the solution: small steps
                step *= 0.2 / norm
            dv = np.zeros(model.nv)
            dv[active] = step
            q = pin.integrate(model, q, dv)
            q[7:] = np.clip(q[7:], lo, hi)
        pin.framesForwardKinematics(model, data, q)
        foot_err = [float(np.linalg.norm(data.oMf[f].translation - ref.foot_pos[i])) for i, f in enumerate(self.foot_ids)]
        root = data.oMf[self.ik.root_id]
        return q, abs(ref.pelvis_z - float(root.translation[2])), foot_err

    def _limits(self, q: np.ndarray) -> list[tuple[str, str, str]]:
        """Leg joints at a limit: [("left:knee", "left knee straight", advice)]."""
        leg = q[self.leg_q]
        near_lo = leg <= self.lower + LIMIT_MARGIN_RAD
        near_hi = leg >= self.upper - LIMIT_MARGIN_RAD
        out = []
        for j in np.flatnonzero(near_lo | near_hi):
            side, words = _joint_words(self.leg_names[j])
            limit = self.upper[j] if near_hi[j] else self.lower[j]
            other = self.lower[j] if near_hi[j] else self.upper[j]
            straight = abs(limit) < abs(other)  # the knee's limit nearer zero is the straight leg
            what = ("straight" if straight else "fully bent") if words == "knee" else "at its limit"
            out.append((f"{side}:{words}", f"{side + ' ' if side else ''}{words} {what}",
                        _hint("joint_limit", words, bent=not straight)))
        return out

    def _speed(self, findings: dict, name: str, pct: float, v: np.ndarray) -> None:
        speed = np.abs(v[self.leg_v])
        over = speed > VELOCITY_SHARE * self.vel_limit
        for j in np.flatnonzero(over):
            side, words = _joint_words(self.leg_names[j])
            self._add(findings, Finding(name, pct, "joint_speed", f"{side}:{words}",
                                        f"{side + ' ' if side else ''}{words} would have to turn at {speed[j]:.1f} rad/s, "
                                        f"above its rated {self.vel_limit[j]:.1f} rad/s (the simulation walks it, a real "
                                        "motor may not keep up): " + _hint("joint_speed", words), severity="rating"))

    def _torque(self, findings: dict, name: str, pct: float, ref, q: np.ndarray) -> None:
        """Leg torques in single support: the links' gravity and the robot's weight carried through the stance
        sole at the CoP a quasi-static walk has there: under the CoM, kept within the sole less the controller's
        CoP margin."""
        leg = self.stance_torque_share(ref, q)
        if leg is None:
            return
        for j in np.flatnonzero(leg > TORQUE_TOLERANCE):
            side, words = _joint_words(self.leg_names[j])
            self._add(findings, Finding(name, pct, "torque", f"{side}:{words}",
                                        f"{side + ' ' if side else ''}{words} needs {leg[j]:.1f}× the "
                                        "torque it has to carry the robot: " + _hint("torque", words)))

    def stance_torque_share(self, ref, q: np.ndarray) -> np.ndarray | None:
        """|leg torque| ÷ the controller's torque limit per leg joint in single support (None in a double
        support or a flight). The weight's line of action: the CoM's projection onto the stance sole, clamped
        to the sole less the CoP margin. (Through the sole's middle, as before 2026-11-30, the estimate left
        the moment of a CoM off that middle on the stance leg: random reachable styles flagged at 1.26–1.9×
        walked the 60 s sweep, G1 five of six, TALOS 25 of 28 — README, *The reachable part of the style
        space*.)"""
        down = [i for i in range(2) if ref.contact[i]]
        if len(down) != 1:
            return None
        return np.abs(self.static_torques(down[0], q)[self.leg_v]) / self.torque_limit

    def static_torques(self, stance: int, q: np.ndarray) -> np.ndarray:
        """Generalized forces (the floating base's six first) that hold posture ``q`` still with the whole
        weight on sole ``stance`` (0 left, 1 right) at the CoM's projection clamped to the sole less the CoP
        margin: where that projection is inside, the base's six are zero (the weight's line of action balances
        the body) and the joints' are what the posture costs."""
        model, data = self.model, self.data
        tau = pin.computeGeneralizedGravity(model, data, q)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        com = pin.centerOfMass(model, data, q, False)
        sole = data.oMf[self.foot_ids[stance]]
        local = sole.actInv(com)
        up = sole.rotation[2]  # the world's vertical in the sole's frame
        if abs(up[2]) > 1e-6:  # down the CoM's vertical onto the sole's plane (the sole is flat in the check: straight down)
            local = local - (local[2] / up[2]) * up
        hx, hy = (max(h - self.margin_m, 0.0) for h in self.sole_half)
        cop = sole.act(np.array([np.clip(local[0], -hx, hx), np.clip(local[1], -hy, hy), 0.0]))
        force = np.array([0.0, 0.0, self.robot.mass_kg * GRAVITY_MPS2])
        wrench = np.concatenate([force, np.cross(cop - sole.translation, force)])  # at the sole frame, world axes
        jac = pin.getFrameJacobian(model, data, self.foot_ids[stance], pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        return tau - jac.T @ wrench


_CHECKERS: dict[str, FeasibilityChecker] = {}


def check_style(robot: RobotModel, style: Style, samples: tuple[str, ...] = SAMPLE_NAMES) -> list[Finding]:
    """Findings for ``samples`` of ``style`` (empty: nothing stands in the way of walking it)."""
    checker = _CHECKERS.get(robot.name)
    if checker is None:
        checker = _CHECKERS[robot.name] = FeasibilityChecker(robot)
    return checker.check_style(style, samples)
