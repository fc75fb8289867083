"""Headless planning (``studio plan``): run sampler → planner → kinematic preview over a command
schedule and collect everything into arrays (the npz format documented in the README)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engine.gait.command_schedule import CommandSchedule
from engine.gait.footsteps import Foothold
from engine.gait.kinematic_preview import FOOT_FRAMES, KinematicPreview, SupportCenterComPlan
from engine.gait.planner import PLANNER_RATE_HZ, GaitPlanner
from engine.gait.style import Style, StyleContext
from engine.gait.velocity_sampler import SAMPLE_NAMES
from engine.robot.model import RobotModel


def planner_for(robot: RobotModel, style: Style, ctx: StyleContext | None = None) -> GaitPlanner:
    """A planner for ``robot`` starting from its standing feet."""
    ctx = ctx or StyleContext.for_robot(robot.name)
    sole = robot.config.soles["left"]
    planner = GaitPlanner(style, ctx, sole.length_m, sole.width_m)
    data = robot.pin_model.createData()
    pin.framesForwardKinematics(robot.pin_model, data, robot.q_standing)
    feet = []
    for frame in FOOT_FRAMES:
        m = data.oMf[robot.pin_model.getFrameId(frame)]
        feet.append(Foothold(float(m.translation[0]), float(m.translation[1]), float(np.arctan2(m.rotation[1, 0], m.rotation[0, 0]))))
    root = robot.q_standing
    planner.reset(np.array([root[0], root[1], 0.0]), feet[0], feet[1])
    return planner


def run_plan(robot: RobotModel, style: Style, schedule: CommandSchedule, duration_s: float,
             with_preview_ik: bool = True) -> dict[str, np.ndarray]:
    ctx = StyleContext.for_robot(robot.name)
    planner = planner_for(robot, style, ctx)
    ik = KinematicPreview(robot, ctx.upper_joints)
    com_plan = SupportCenterComPlan()
    dt = 1.0 / PLANNER_RATE_HZ
    n = int(round(duration_s * PLANNER_RATE_HZ))
    out: dict[str, list] = {k: [] for k in (
        "t", "phase", "command", "command_requested", "contact", "foot_pos", "foot_quat", "sole_corners", "pelvis_z",
        "pelvis_quat", "upper_q", "sample_weights", "qpos", "footholds", "com_xy", "path_pose", "corner_contact",
        "ik_error_m", "com_error_m")}
    for _ in range(n):
        requested = schedule(planner.t_s + dt)
        ref = planner.step(dt, requested, with_preview=False)
        com = com_plan.step(dt, ref)
        q = ik.solve(ref, com) if with_preview_ik else robot.q_standing
        out["t"].append(ref.t_s)
        out["phase"].append(ref.phase)
        out["command"].append(ref.command)
        out["command_requested"].append(requested)
        out["contact"].append(ref.contact)
        out["corner_contact"].append(ref.corner_contact)
        out["foot_pos"].append(ref.foot_pos)
        out["foot_quat"].append([ref.foot_quat(0), ref.foot_quat(1)])
        out["sole_corners"].append(ref.sole_corners)
        out["pelvis_z"].append(ref.pelvis_z)
        out["pelvis_quat"].append(ref.pelvis_quat)
        out["upper_q"].append(ref.upper_q)
        out["sample_weights"].append(ref.sample_weights)
        out["qpos"].append(robot.mj_qpos_from_pin(q))
        out["footholds"].append([ref.footholds[s].as_array() for s in ("left", "right")])
        out["com_xy"].append(com)
        out["path_pose"].append(ref.path_pose)
        out["ik_error_m"].append(ik.last_error if with_preview_ik else 0.0)
        out["com_error_m"].append(ik.last_com_error if with_preview_ik else 0.0)
    arrays = {k: np.asarray(v, dtype=bool if k in ("contact", "corner_contact") else float) for k, v in out.items()}
    arrays["upper_joint_names"] = np.array(ctx.upper_joints, dtype=str)
    arrays["sample_names"] = np.array(SAMPLE_NAMES, dtype=str)
    arrays["joint_names"] = np.array(robot.joint_names, dtype=str)
    arrays["robot"] = np.array(robot.name)
    arrays["style"] = np.array(style.name)
    return arrays
