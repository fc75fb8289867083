"""Kinematic quadruped clips made with the robot's own kinematics: a base trajectory plus four foot trajectories
(or keyframed leg joints) solved to joint angles by per-leg damped least-squares IK in the MuJoCo model.

They are the project's own test and demo material for TMR: a standing clip (trivially feasible), a trot, a hop
with a ballistic flight phase, and the keyframed BackFlip of ``tools/make_backflip.py``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import mujoco
import numpy as np

from engine.constants import GRAVITY_MPS2
from engine.retarget.quadruped.tmr.keypoints import KeypointSet, keypoint_trajectory
from engine.retarget.motion import RobotMotion

if TYPE_CHECKING:
    from engine.robot.model import RobotModel



def quat_from_pitch_yaw(pitch_rad: float, yaw_rad: float = 0.0) -> np.ndarray:
    """w,x,y,z of yaw about z then pitch about the body y axis."""
    cy, sy = np.cos(yaw_rad / 2), np.sin(yaw_rad / 2)
    cp, sp = np.cos(pitch_rad / 2), np.sin(pitch_rad / 2)
    return np.array([cy * cp, -sy * sp, cy * sp, sy * cp])


@dataclass
class LegIK:
    """Per-leg damped least-squares IK on the foot points of a MuJoCo quadruped."""

    robot: RobotModel

    def __post_init__(self) -> None:
        r = self.robot
        self.m = r.mj_model
        self.d = mujoco.MjData(self.m)
        self.kp = KeypointSet.for_robot(r)
        self.leg_dofs = []
        self.leg_qpos = []
        names = list(r.joint_names)
        for leg in range(4):
            joints = [int(j) for j in self.kp.joint[4 * leg: 4 * leg + 3]]
            self.leg_qpos.append(np.array([int(self.m.jnt_qposadr[j]) for j in joints]))
            self.leg_dofs.append(np.array([int(self.m.jnt_dofadr[j]) for j in joints]))
        del names
        self.lower = self.m.jnt_range[:, 0]
        self.upper = self.m.jnt_range[:, 1]

    def nominal_feet(self, qpos: np.ndarray) -> np.ndarray:
        """(4, 3) foot positions of ``qpos`` in the base frame."""
        self.d.qpos[:] = qpos
        mujoco.mj_kinematics(self.m, self.d)
        pts = self.kp.positions(self.d)[self.kp.foot_index]
        rot = self.d.xmat[1].reshape(3, 3)
        return (pts - self.d.xpos[1]) @ rot

    def solve(self, qpos_guess: np.ndarray, feet_world: np.ndarray, iterations: int = 30) -> np.ndarray:
        """Joint angles putting the four feet at ``feet_world`` for the base pose in ``qpos_guess``."""
        m, d = self.m, self.d
        q = qpos_guess.copy()
        jac = np.zeros((3, m.nv))
        for _ in range(iterations):
            d.qpos[:] = q
            mujoco.mj_kinematics(m, d)
            mujoco.mj_comPos(m, d)
            pts = self.kp.positions(d)
            worst = 0.0
            for leg, fi in enumerate(self.kp.foot_index):
                err = feet_world[leg] - pts[fi]
                worst = max(worst, float(np.linalg.norm(err)))
                mujoco.mj_jac(m, d, jac, None, pts[fi], int(self.kp.body[fi]))
                J = jac[:, self.leg_dofs[leg]]
                dq = J.T @ np.linalg.solve(J @ J.T + 1e-4 * np.eye(3), err)
                idx = self.leg_qpos[leg]
                jid = [int(j) for j in self.kp.joint[4 * leg: 4 * leg + 3]]
                q[idx] = np.clip(q[idx] + dq, self.lower[jid], self.upper[jid])
            if worst < 1e-5:
                break
        return q


def _finish(robot, qpos: np.ndarray, contact: np.ndarray, fps: float, name: str) -> RobotMotion:  # noqa: ANN001
    return RobotMotion(fps=fps, qpos=qpos, joint_names=mujoco_joint_names(robot), contact=contact, robot=robot.name,
                       method="kinematic", keypoints=keypoint_trajectory(robot, qpos), source={"clip": name})


def mujoco_joint_names(robot) -> list[str]:  # noqa: ANN001
    """Joint names in MuJoCo qpos order (the order of qpos columns 7:)."""
    order = np.argsort(np.asarray(robot.mj_qpos_index))
    return [robot.joint_names[i] for i in order]


def standing(robot, duration_s: float = 1.0, fps: float = 50.0) -> RobotMotion:  # noqa: ANN001
    """The robot standing still: trivially feasible."""
    T = int(round(duration_s * fps)) + 1
    qpos = np.tile(robot.mj_standing_qpos(), (T, 1))
    return _finish(robot, qpos, np.ones((T, 4), dtype=bool), fps, "standing")


def trot(robot, duration_s: float = 2.0, fps: float = 50.0, speed_mps: float = 0.3, period_s: float = 0.5,  # noqa: ANN001
         swing_height_m: float = 0.06, settle_s: float = 0.3) -> RobotMotion:
    """Trot: diagonal pairs (FL+RR, FR+RL) swing alternately, half a period each, base at constant speed
    after ``settle_s`` standing; the feet stay where they land."""
    ik = LegIK(robot)
    q0 = robot.mj_standing_qpos()
    nominal = ik.nominal_feet(q0)
    T = int(round(duration_s * fps)) + 1
    t = np.arange(T) / fps
    base_x = q0[0] + speed_mps * np.clip(t - settle_s, 0.0, None)
    end = duration_s - settle_s  # stop stepping before the end so the clip ends standing
    anchors = q0[0:3] + nominal  # world foot anchors
    anchors[:, 2] = nominal[:, 2] + q0[2]
    qpos = np.zeros((T, len(q0)))
    contact = np.ones((T, 4), dtype=bool)
    pairs = ((0, 3), (1, 2))
    half = period_s / 2
    q = q0.copy()
    for k, tk in enumerate(t):
        q[0] = base_x[k]
        feet = anchors.copy()
        tau = tk - settle_s
        if 0.0 <= tau < end - half:
            step = int(tau // half)
            phase = (tau - step * half) / half
            swing = pairs[step % 2]
            t_td = settle_s + (step + 1) * half
            for leg in range(4):
                if leg in swing:
                    x_lo = anchors[leg, 0]
                    x_td = q0[0] + speed_mps * np.clip(t_td - settle_s, 0, None) + nominal[leg, 0] + speed_mps * half / 2
                    s = 0.5 - 0.5 * np.cos(np.pi * phase)
                    feet[leg, 0] = x_lo + (x_td - x_lo) * s
                    feet[leg, 2] = anchors[leg, 2] + swing_height_m * np.sin(np.pi * phase)
                    contact[k, leg] = False
            # commit touchdowns at the end of the swing
            next_tau = tau + 1.0 / fps
            if int(next_tau // half) != step:
                for leg in swing:
                    anchors[leg, 0] = q0[0] + speed_mps * (t_td - settle_s) + nominal[leg, 0] + speed_mps * half / 2
                    feet[leg, 0] = anchors[leg, 0]
        q = ik.solve(q, feet)
        qpos[k] = q
    return _finish(robot, qpos, contact, fps, "trot")


def _hermite(p0: float, v0: float, p1: float, v1: float, duration: float, s: np.ndarray) -> np.ndarray:
    h00 = 2 * s**3 - 3 * s**2 + 1
    h10 = s**3 - 2 * s**2 + s
    h01 = -2 * s**3 + 3 * s**2
    h11 = s**3 - s**2
    return h00 * p0 + h10 * duration * v0 + h01 * p1 + h11 * duration * v1


def hop(robot, fps: float = 50.0, takeoff_speed_mps: float = 1.0, crouch_m: float = 0.06,  # noqa: ANN001
        forward_mps: float = 0.0) -> RobotMotion:
    """A vertical hop: stand, crouch, push, a ballistic flight (feet hang as at take-off), land, absorb, stand."""
    ik = LegIK(robot)
    q0 = robot.mj_standing_qpos()
    nominal = ik.nominal_feet(q0)
    z0 = q0[2]
    v = takeoff_speed_mps
    flight = 2 * v / GRAVITY_MPS2
    phases = [("stand", 0.3), ("crouch", 0.3), ("push", 0.15), ("flight", flight), ("absorb", 0.15), ("recover", 0.4),
              ("stand", 0.3)]
    edges = np.cumsum([0.0] + [p[1] for p in phases])
    duration = edges[-1]
    T = int(np.floor(duration * fps)) + 1
    t = np.arange(T) / fps
    z_top = z0 + 0.02
    qpos = np.zeros((T, len(q0)))
    contact = np.ones((T, 4), dtype=bool)
    q = q0.copy()
    for k, tk in enumerate(t):
        i = min(int(np.searchsorted(edges, tk, side="right") - 1), len(phases) - 1)
        name, dur = phases[i]
        s = (tk - edges[i]) / dur
        x = q0[0]
        if name == "stand":
            z = z0
        elif name == "crouch":
            z = _hermite(z0, 0, z0 - crouch_m, 0, dur, s)
        elif name == "push":
            z = _hermite(z0 - crouch_m, 0, z_top, v, dur, s)
        elif name == "flight":
            tau = tk - edges[i]
            z = z_top + v * tau - 0.5 * GRAVITY_MPS2 * tau**2
            x = q0[0] + forward_mps * tau
            contact[k] = False
        elif name == "absorb":
            z = _hermite(z_top, -v, z0 - crouch_m * 0.7, 0, dur, s)
            x = q0[0] + forward_mps * flight
        else:
            z = _hermite(z0 - crouch_m * 0.7, 0, z0, 0, dur, s)
            x = q0[0] + forward_mps * flight
        if i > 3:
            x = q0[0] + forward_mps * flight
        q[0], q[2] = x, z
        if name == "flight":  # the legs keep their take-off posture
            feet = np.array([[x + nominal[leg, 0], nominal[leg, 1], z + (z0 + nominal[leg, 2] - z_top)] for leg in range(4)])
        else:
            feet = np.array([[x + nominal[leg, 0], nominal[leg, 1], z0 + nominal[leg, 2]] for leg in range(4)])
        q = ik.solve(q, feet)
        qpos[k] = q
    return _finish(robot, qpos, contact, fps, "hop")


def keyframed(robot, keyframes: list[dict], fps: float = 50.0, name: str = "keyframed") -> RobotMotion:  # noqa: ANN001
    """A clip from keyframes ``{t_s, x_m, z_m, pitch_rad, front: (thigh, calf), rear: (thigh, calf),
    contact: (FL, FR, RL, RR)}``. Base x, z and pitch are PCHIP-interpolated between keyframes on the ground and
    ballistic (constant pitch rate) between the last keyframe with contact and the next; leg joints are
    PCHIP-interpolated, except that a foot in contact keeps its touchdown point (IK). A keyframe's contact flags
    hold until the next keyframe."""
    from scipy.interpolate import PchipInterpolator

    ik = LegIK(robot)
    q0 = robot.mj_standing_qpos()
    times = np.array([kf["t_s"] for kf in keyframes])
    T = int(np.floor(times[-1] * fps + 1e-9)) + 1
    t = np.arange(T) / fps
    cont_kf = np.array([kf["contact"] for kf in keyframes], dtype=bool)
    x = PchipInterpolator(times, [kf["x_m"] for kf in keyframes])(t)
    z = PchipInterpolator(times, [kf["z_m"] for kf in keyframes])(t)
    pitch = PchipInterpolator(times, np.unwrap([kf["pitch_rad"] for kf in keyframes]))(t)
    legs = PchipInterpolator(times, [[*kf["front"], *kf["rear"]] for kf in keyframes])(t)
    # contact per frame: a keyframe's flags hold until the next keyframe
    idx = np.clip(np.searchsorted(times, t + 1e-9, side="right") - 1, 0, len(times) - 1)
    contact = cont_kf[idx]
    airborne = np.asarray(~contact.any(axis=1))
    # ballistic base through every flight interval (take-off state from the interpolants)
    k = 0
    while k < T:
        if not airborne[k]:
            k += 1
            continue
        k1 = k
        while k1 < T and airborne[k1]:
            k1 += 1
        a, b = max(k - 1, 0), min(k1, T - 1)
        ta, tb = t[a], t[b]
        dt = tb - ta
        vx = (x[b] - x[a]) / dt
        vz = (z[b] - z[a]) / dt + 0.5 * GRAVITY_MPS2 * dt
        for j in range(a, b + 1):
            tau = t[j] - ta
            x[j] = x[a] + vx * tau
            z[j] = z[a] + vz * tau - 0.5 * GRAVITY_MPS2 * tau**2
        pitch[a: b + 1] = np.linspace(pitch[a], pitch[b], b - a + 1)
        k = k1
    qpos = np.zeros((T, len(q0)))
    anchors = np.full((4, 3), np.nan)
    ground_z = ik.nominal_feet(q0)[:, 2] + q0[2]  # foot-centre height standing on the floor
    q = q0.copy()
    for k in range(T):
        q[0], q[1], q[2] = x[k], q0[1], z[k]
        q[3:7] = quat_from_pitch_yaw(pitch[k])
        for leg in range(4):
            thigh, calf = legs[k, 0:2] if leg < 2 else legs[k, 2:4]
            hip_adr, thigh_adr, calf_adr = ik.leg_qpos[leg]
            q[hip_adr], q[thigh_adr], q[calf_adr] = q0[hip_adr], thigh, calf
        ik.d.qpos[:] = q
        mujoco.mj_kinematics(ik.m, ik.d)
        feet = ik.kp.positions(ik.d)[ik.kp.foot_index]
        low = feet[:, 2] < ground_z - 1e-6
        for leg in range(4):
            if contact[k, leg]:
                if np.isnan(anchors[leg, 0]):
                    anchors[leg] = feet[leg]
                    anchors[leg, 2] = ground_z[leg]
                feet[leg] = anchors[leg]
            else:
                anchors[leg] = np.nan
                feet[leg, 2] = max(feet[leg, 2], ground_z[leg])  # a swinging foot never goes through the floor
        if contact[k].any() or low.any():
            q = ik.solve(q, feet)
        qpos[k] = q
    return _finish(robot, qpos, contact, fps, name)
