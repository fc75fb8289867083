"""Headless closed-loop walking (``studio walk``): the full stack in MuJoCo, as fast as it goes.

Records the run and measures what an animator and a controls engineer care about: did it
fall, real-time factor, velocity tracking, stance slip, CoP inside the support polygon and
the cost of every stage.
"""

from __future__ import annotations

import math
import time
from typing import Callable, Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from engine.control.walking_controller import WalkingController
from engine.gait.command_schedule import CommandSchedule
from engine.gait.style import SIDES, Style
from engine.gait.support_edges import outside_support_m, support_edges
from engine.constants import GRAVITY_MPS2
from engine.geometry.polygon import convex_hull_2d, point_in_polygon
from engine.robot.model import RobotModel
from engine.sim import Simulation
from engine.stance_slip import StanceSlipMeter

COP_MARGIN_M = 0.005
# A nudge: what tells apart the walks of one style that `studio bench styles --repeat` and a rehearsal of several
# walks make. 1 N for 10 ms (0.01 N·s: G1's velocity changes by 0.3 mm/s) while the sweep still stands (it moves at
# 1 s), far below the push observer's deadband (0.25 N/kg): physically nothing, yet the closed loop takes another
# path from there, and at the margin where many random styles sit, a fall and a walk are that close (README
# "Falls at a margin").
NUDGE_AT_S = 0.5
NUDGE_FORCE_N = 1.0
NUDGE_DURATION_S = 0.01


@dataclass(frozen=True)
class PushSpec:
    t_s: float
    force_n: tuple[float, float, float]
    duration_s: float

    @classmethod
    def nudge(cls, k: int, walks: int) -> "PushSpec":
        """The nudge of the k-th (k ≥ 1) of ``walks`` walks: a horizontal direction per k."""
        angle = 2.0 * math.pi * (k - 1) / max(walks - 1, 1)
        return cls(NUDGE_AT_S, (round(NUDGE_FORCE_N * math.cos(angle), 6), round(NUDGE_FORCE_N * math.sin(angle), 6), 0.0),
                   NUDGE_DURATION_S)

    @classmethod
    def parse(cls, text: str) -> "PushSpec":
        parts = text.split(",")
        if len(parts) != 5:
            raise ValueError(f"--push: expected t,fx,fy,fz,dur, got {text!r}")
        try:
            t, fx, fy, fz, dur = (float(p) for p in parts)
        except ValueError:
            raise ValueError(f"--push: expected five numbers t,fx,fy,fz,dur, got {text!r}") from None
        if not all(math.isfinite(v) for v in (t, fx, fy, fz, dur)) or t < 0 or dur <= 0:
            raise ValueError(f"--push: expected finite numbers with t ≥ 0 and dur > 0, got {text!r}")
        return cls(t, (fx, fy, fz), dur)


class ContactMeter:
    """Measured CoP and per-foot normal force from MuJoCo's floor contacts."""

    def __init__(self, model: mujoco.MjModel, foot_bodies: Sequence[int] = ()):
        self.model = model
        self.floor = model.geom("floor").id
        self._force = np.zeros(6)
        # geom id -> foot index, for the geoms of each foot's body (``foot_bodies[i]``)
        self._foot_of_geom = {g: i for i, b in enumerate(foot_bodies) for g in range(model.ngeom)
                              if int(model.geom_bodyid[g]) == b}
        self.foot_load_n = np.zeros(len(foot_bodies))

    def cop(self, data: mujoco.MjData) -> tuple[np.ndarray | None, float]:
        """(CoP or None, total normal force); also fills ``foot_load_n``: the normal force on each foot."""
        total, moment = 0.0, np.zeros(2)
        self.foot_load_n[:] = 0.0
        for i in range(data.ncon):
            c = data.contact[i]
            if c.geom1 == self.floor:
                other = c.geom2
            elif c.geom2 == self.floor:
                other = c.geom1
            else:
                continue
            mujoco.mj_contactForce(self.model, data, i, self._force)
            fn = self._force[0]  # normal component in the contact frame
            if fn <= 0:
                continue
            total += fn
            moment += fn * c.pos[:2]
            foot = self._foot_of_geom.get(int(other))
            if foot is not None:
                self.foot_load_n[foot] += fn
        return (moment / total if total > 1e-6 else None), total


def run_walk(robot: RobotModel, style: Style, schedule: CommandSchedule, duration_s: float,
             pushes: Sequence[PushSpec] = (), wbc: str = "paper", state_source: str = "truth",
             feedback: bool = True, record: bool = True, record_reference: bool = False,
             command_text: str | None = None, progress: Callable[[float], None] | None = None,
             progress_period_s: float = 0.5) -> tuple[dict, dict[str, np.ndarray]]:
    """Walk ``duration_s`` of simulated time; returns the summary and, with ``record``, the walk-run
    arrays (engine/walk_recording.py: a RobotMotion plus the analysis arrays, every 4th tick).
    ``record_reference`` adds ``reference_qpos``: the kinematic preview of the gait reference at each
    recorded instant (whole-body IK, the studio's ghost; costs one IK solve per recorded frame).
    ``progress(t_s)`` is called every ``progress_period_s`` of simulated time (an exception it raises stops the walk
    and propagates: a cancelled rehearsal)."""
    controller = WalkingController(robot, style, wbc=wbc, state_source=state_source, feedback=feedback)
    sim = Simulation(robot, controller)
    if state_source == "estimated":
        sim.enable_imu()
    sim.reset()
    sole_bodies = [robot.mj_model.body(robot.config.soles[s].link).id for s in SIDES]
    meter = ContactMeter(robot.mj_model, sole_bodies)
    dt = float(robot.mj_model.opt.timestep)
    n = int(round(duration_s / dt))
    root = robot.mj_model.body(robot.config.root_link).id
    site_ids = [robot.mj_model.site(f"{s}_foot").id for s in SIDES]
    corner_geoms = [[g for g in robot.contact_geom_ids if robot.mj_model.body(int(robot.mj_model.geom_bodyid[g])).name
                     == robot.config.soles[s].link] for s in SIDES]
    pending = sorted(pushes, key=lambda p: p.t_s)
    rec: dict[str, list] = {k: [] for k in ("t", "qpos", "qvel", "command", "contact", "com", "com_ref", "cop",
                                            "foot_pos", "foot_ref", "kappa", "step_adjust", "velocity_adjust",
                                            "sample_weights", "base_vel_body", "external_force",
                                            "pelvis_height_ref", "pelvis_height_achieved", "pelvis_yaw_ref",
                                            "pelvis_yaw_achieved", "elbow_ref", "elbow_achieved",
                                            "gait_phase", "stance_drift_m", "support_edge", "com_outside_support_m",
                                            "reference_qpos")}
    preview = None
    if record and record_reference:
        from engine.gait.kinematic_preview import KinematicPreview

        preview = KinematicPreview(robot, controller.ctx.upper_joints)
    # The paper's Fig. 14 tracking quantities: pelvis height, pelvis yaw and an elbow.
    upper = list(controller.ctx.upper_joints)
    elbow = next((j for j in upper if "elbow" in j and "left" in j), next((j for j in upper if "elbow" in j), None))
    elbow_ref_index = upper.index(elbow) if elbow is not None else None
    elbow_qpos = int(robot.mj_model.joint(elbow).qposadr[0]) if elbow is not None else None
    timings: dict[str, list[float]] = {"planner": [], "mpc": [], "wbc": [], "sim": [], "estimator": []}
    slip = StanceSlipMeter(dt, robot.mass_kg * GRAVITY_MPS2)
    cop_checks = cop_inside = 0
    fell, fall_time = False, None
    path_len, last_xy = 0.0, sim.data.qpos[:2].copy()
    window = int(1.0 / dt)
    # Running sums of body velocity and command: 1 s means without re-summing a window every tick.
    vel_sum = np.zeros((n + 1, 3))
    cmd_sum = np.zeros((n + 1, 3))
    vel_err: list[np.ndarray] = []
    com_err: list[float] = []
    wall0 = time.perf_counter()
    progress_every = max(1, int(round(progress_period_s / dt)))
    for k in range(n):
        t = k * dt
        if progress is not None and k % progress_every == 0:
            progress(t)
        while pending and pending[0].t_s <= t:
            p = pending.pop(0)
            sim.push(np.array(p.force_n), p.duration_s)
        controller.set_command(schedule(t))
        t0 = time.perf_counter()
        sim.step()
        step_s = time.perf_counter() - t0
        tm = controller.timings
        for key in ("planner", "mpc", "wbc", "estimator"):
            value = getattr(tm, key)
            if value is not None:
                timings[key].append(value)
        timings["sim"].append(max(step_s - sum(v for v in (tm.planner, tm.mpc, tm.wbc, tm.estimator) if v), 0.0))
        if sim.fallen:
            fell, fall_time = True, sim.time_s
            break
        ref = controller.ref
        assert ref is not None  # the controller has planned once it has stepped
        data = sim.data
        xy = data.qpos[:2]
        path_len += float(np.linalg.norm(xy - last_xy))
        last_xy = xy.copy()
        # Velocity tracking: body-frame base velocity averaged over ~1 s against the command.
        yaw = math.atan2(data.xmat[root][3], data.xmat[root][0])
        c, s = math.cos(yaw), math.sin(yaw)
        v_world = data.qvel[0:3]
        wz = float(data.qvel[5]) if False else float((data.xmat[root].reshape(3, 3) @ data.qvel[3:6])[2])
        v_body = np.array([c * v_world[0] + s * v_world[1], -s * v_world[0] + c * v_world[1], wz])
        vel_sum[k + 1] = vel_sum[k] + v_body
        cmd_sum[k + 1] = cmd_sum[k] + ref.command
        if k + 1 > window and t > 2.0:
            vel_err.append(((vel_sum[k + 1] - vel_sum[k + 1 - window]) - (cmd_sum[k + 1] - cmd_sum[k + 1 - window]))
                           / window)
        # CoM tracking: measured horizontal CoM against the MPC's reference.
        if k % 4 == 0 and controller.plan is not None:
            com_err.append(float(np.linalg.norm(data.subtree_com[root][:2] - controller.plan.com_at(ref.t_s)[0])))
        # CoP inside the support polygon of the feet the controller has on the ground (the plan's,
        # plus a landing foot from the moment it touches down a few ms early).
        cop, fz = meter.cop(data)
        # Stance slip: sole centre drift while the plan holds the foot flat and the floor carries it.
        flat = ref.contact & ~ref.sole_corners[:, :, 2].any(axis=1)
        stance_drift = slip.update(flat, data.site_xpos[site_ids][:, :2], meter.foot_load_n)
        if cop is not None and fz > 0.2 * robot.mass_kg * GRAVITY_MPS2:
            support = np.asarray(controller.wbc_contact.any(axis=1))  # the feet the controller stands on
            corners = [data.geom_xpos[g][:2] for i in range(2) if support[i] for g in corner_geoms[i]]
            if corners:
                cop_checks += 1
                cop_inside += point_in_polygon(cop, convex_hull_2d(np.array(corners)), COP_MARGIN_M)
        if record and k % 4 == 0:
            tel = controller.telemetry
            fb = tel.feedback
            rec["t"].append(t)
            rec["qpos"].append(data.qpos.copy())
            rec["qvel"].append(data.qvel.copy())
            rec["command"].append(ref.command.copy())
            rec["contact"].append(ref.contact.copy())
            com = data.subtree_com[root].copy()
            rec["com"].append(com)
            rec["com_ref"].append(tel.com_ref_xy.copy())
            rec["cop"].append(cop if cop is not None else np.full(2, np.nan))
            rec["foot_pos"].append(np.array([data.site_xpos[sid].copy() for sid in site_ids]))
            rec["foot_ref"].append(ref.foot_pos.copy())
            rec["kappa"].append(fb.kappa if fb else 1.0)
            rec["step_adjust"].append(fb.step_adjust_m.copy() if fb else np.zeros(2))
            rec["velocity_adjust"].append(fb.velocity_adjust_mps.copy() if fb else np.zeros(2))
            rec["sample_weights"].append(tel.sample_weights.copy())
            rec["base_vel_body"].append(v_body)
            rec["external_force"].append(tel.external_force_n.copy())
            rec["pelvis_height_ref"].append(ref.pelvis_z)
            rec["pelvis_height_achieved"].append(float(data.xpos[root][2]))
            rec["pelvis_yaw_ref"].append(math.atan2(ref.pelvis_rot[1, 0], ref.pelvis_rot[0, 0]))
            rec["pelvis_yaw_achieved"].append(yaw)
            rec["elbow_ref"].append(float(ref.upper_q[elbow_ref_index]) if elbow_ref_index is not None else math.nan)
            rec["elbow_achieved"].append(float(data.qpos[elbow_qpos]) if elbow_qpos is not None else math.nan)
            rec["gait_phase"].append(ref.phase)
            rec["stance_drift_m"].append(stance_drift)  # (2,) each sole's drift in stance (engine/stance_slip.py)
            # the edge each grounded sole of the reference rolls on, and the measured CoM outside the support its
            # grounded corners span (engine/gait/support_edges.py: the rehearsal's "edges" onset)
            rec["support_edge"].append(support_edges(ref.contact, ref.corner_contact, ref.sole_corners, ref.foot_pos,
                                                     ref.foot_rot))
            rec["com_outside_support_m"].append(outside_support_m(com[:2], ref.contact, ref.corner_contact,
                                                                  ref.sole_corners))
            if preview is not None:
                com_xy = controller.plan.com_at(ref.t_s)[0] if controller.plan is not None else data.subtree_com[root][:2]
                rec["reference_qpos"].append(robot.mj_qpos_from_pin(preview.solve(ref, np.asarray(com_xy))))
    wall = time.perf_counter() - wall0
    sim_time = sim.time_s
    err = np.array(vel_err) if vel_err else np.zeros((1, 3))

    def pct(values: list[float]) -> dict[str, float]:
        arr = np.asarray(values) * 1e6 if values else np.zeros(1)
        return {"median": round(float(np.median(arr)), 1), "p99": round(float(np.percentile(arr, 99)), 1)}

    recovery = controller.recovery
    summary = {
        "robot": robot.name, "style": style.name, "wbc": wbc, "state": state_source,
        "fell": fell, "fall_time_s": fall_time, "sim_time_s": round(sim_time, 3), "wall_time_s": round(wall, 3),
        "real_time_factor": round(sim_time / wall, 2) if wall > 0 else None,
        "distance_m": round(path_len, 3),
        "velocity_rmse": [round(float(x), 4) for x in np.sqrt(np.mean(err ** 2, axis=0))],
        "com_error_mm": {"rms": round(1000 * float(np.sqrt(np.mean(np.square(com_err)))), 1) if com_err else None,
                         "max": round(1000 * max(com_err), 1) if com_err else None},
        "max_stance_slip_mm": round(1000 * slip.max_slip_m, 2),
        "cop_inside_fraction": round(cop_inside / cop_checks, 5) if cop_checks else None,
        # balance recovery (engine/control/recovery_blend.py): how long the gait was blended toward neutral,
        # and the neutral gait's mean share over the walk (0: the style as authored throughout)
        "recovery_time_s": round(recovery.time_in_recovery_s, 3),
        "recovery_mean_share": round(recovery.share_time_s / sim_time, 4) if sim_time > 0 else 0.0,
        "timing_us": {k: pct(v) for k, v in timings.items()},
    }
    if preview is None:
        rec.pop("reference_qpos")
    arrays = {k: np.asarray(v) for k, v in rec.items()}
    if record:
        from engine.walk_recording import run_fields

        arrays.update(run_fields(robot, style.name, arrays, summary, 1.0 / (4 * dt), command_text))
    return summary, arrays
