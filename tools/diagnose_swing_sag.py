"""Why a swing foot meets the floor before its plan does: per control tick of the late swings, what sags.

    PYTHONPATH=. .venv/bin/python tools/diagnose_swing_sag.py --seed 4 --index 2 --extent 0.15 --duration 20 \
        [--shipped NAME] [--walking KEY=VALUE] [--wbc KEY=VALUE]

Walks one style (``studio bench styles``' random style ``random-<seed>-<index>`` or a shipped one) through
the ``sweep`` and, on every control tick where a foot swings in the plan, logs its planned and actual sole
height, the swing task's vertical acceleration three ways -- what the task asks (a* = feed-forward + PD), what
the whole-body QP's solution gives it (J q̈ + J̇ q̇) and what the simulation then did (finite difference of the
foot's vertical velocity) -- the pelvis height error, the swing knee's margin to its limits and the load the
floor already carries on that foot. It prints, over the swings' last 20 %:

* the sole's height error (actual − plan) percentiles, and at the first tick a foot carries > 20 N while its
  plan is still > 10 mm up ("early strikes"): the error, the pelvis error, the knee margin;
* the mean vertical acceleration deficits over the 60 ms before each early strike and over all late swing:
  task − QP (the QP trades the task away: weights, joint or torque limits) and QP − simulation (the joint
  servos / model do not deliver the QP's q̈).

Nothing is written; one walk at a time (~1 min of CPU per 20 s walk).
"""

from __future__ import annotations

import argparse
import dataclasses
import json

import numpy as np

from engine.bench.options import add_random_style_options
from engine.constants import CONTROL_PERIOD_S, GRAVITY_MPS2, SIDES
from engine.control.controller import JointCommand, RobotState
from engine.control.wbc import TaskSpaceInverseDynamics, WbcReference
from engine.control.wbc.tasks import DynamicsSnapshot

STRIKE_LOAD_N = 20.0
STRIKE_PLAN_ABOVE_M = 0.010
LATE_PROGRESS = 0.8
WINDOW_TICKS = 30  # 60 ms


def _overrides(items: list[str]) -> dict[str, float]:
    return {k: float(v) for k, v in (item.split("=", 1) for item in items)}


def main() -> None:
    ap = argparse.ArgumentParser()
    add_random_style_options(ap, n=8, seed=4, extent=0.15, duration_s=20.0)
    ap.add_argument("--index", type=int, default=2)
    ap.add_argument("--shipped", default="", help="a shipped style's name instead of a random one")
    ap.add_argument("--walking", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--strikes", action="store_true", help="list every early strike (default: their means)")
    ap.add_argument("--wbc", action="append", default=[], metavar="KEY=VALUE", help="a WbcGains override")
    args = ap.parse_args()

    from engine.bench.styles import style_jobs
    from engine.control.walking_controller import WalkingController
    from engine.control.walking_parameters import WalkingParameters
    from engine.control.wbc.reference import WbcGains
    from engine.gait.command_schedule import parse_command
    from engine.gait.style import StyleContext, load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import Simulation
    from engine.walk_runner import ContactMeter

    robot = load_robot(args.robot)
    if args.shipped:
        style = load_style(styles_dir(args.robot) / f"{args.shipped}.json", StyleContext.for_robot(args.robot))
    else:
        style = style_jobs(args.robot, args.n, args.seed, args.duration, args.extent, args.space)[args.index][0]
    if args.walking:
        changes = _overrides(args.walking)
        base_w = WalkingParameters.for_robot
        WalkingParameters.for_robot = staticmethod(  # type: ignore[method-assign]
            lambda name: dataclasses.replace(base_w(name), **changes))  # type: ignore[arg-type]
    if args.wbc:
        wchanges = _overrides(args.wbc)
        base_g = WbcGains.for_robot
        WbcGains.for_robot = staticmethod(  # type: ignore[method-assign,assignment]
            lambda r: dataclasses.replace(base_g(r), **wchanges))

    controller = WalkingController(robot, style)
    sim = Simulation(robot, controller)
    sim.reset()
    wbc = controller.wbc
    assert isinstance(wbc, TaskSpaceInverseDynamics)
    gains = wbc.gains
    model = robot.pin_model
    data = model.createData()
    frames = [model.getFrameId(f"{s}_foot") for s in SIDES]
    knee_v = [6 + robot.joint_names.index(f"{s}_knee_joint") for s in SIDES]
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit
    sole_bodies = [robot.mj_model.body(robot.config.soles[s].link).id for s in SIDES]
    meter = ContactMeter(robot.mj_model, sole_bodies)

    rows: list[list[float]] = []  # per tick and swinging foot
    tick_info: dict[str, object] = {}
    original = wbc.compute

    def compute(state: RobotState, ref: WbcReference) -> JointCommand:
        cmd = original(state, ref)
        plan = controller.ref
        qdd = wbc.diagnostics.qdd
        if plan is None or qdd is None:
            return cmd
        snap = DynamicsSnapshot.compute(model, data, state.q, state.v, frames)
        out = []
        for i in range(2):
            if plan.contact[i]:
                continue
            z_ref, z = float(ref.foot_pos_m[i, 2]), float(snap.frame_position_m[i, 2])
            vz_ref, vz = float(ref.foot_lin_vel_mps[i, 2]), float(snap.frame_velocity[i, 2])
            a_ff = 0.0 if ref.foot_lin_acc_mps2 is None else float(ref.foot_lin_acc_mps2[i, 2])
            a_task = a_ff + gains.swing_foot_kp * (z_ref - z) + gains.swing_foot_kd * (vz_ref - vz)
            a_qp = float(snap.frame_jacobian[i, 2] @ qdd + snap.frame_drift[i, 2])
            kq = float(state.q[1 + knee_v[i]])
            margin = min(kq - lower[1 + knee_v[i]], upper[1 + knee_v[i]] - kq)
            offsets = wbc.corner_offsets_m[i].T  # (3, 4) foot frame, from the sole centre
            corner_ref = z_ref + float((ref.foot_rotation[i] @ offsets)[2].min())
            corner = z + float((snap.frame_rotation[i] @ offsets)[2].min())
            out.append([state.t_s, i, float(plan.swing_progress[i]), z_ref, z, vz_ref, vz, a_ff, a_task, a_qp,
                        float(ref.pelvis_height_m), float(state.q[2]), margin, float(ref.contact[i].any()),
                        corner_ref, corner])
        tick_info["rows"] = out
        return cmd

    wbc.compute = compute  # type: ignore[method-assign]
    n = int(round(args.duration / CONTROL_PERIOD_S))
    prev_vz: dict[int, tuple[float, float]] = {}
    fell = False
    for k in range(n):
        tick_info["rows"] = []
        sim.step()
        if sim.fallen:
            fell = True
            break
        meter.cop(sim.data)
        for r in tick_info["rows"]:  # type: ignore[attr-defined]
            i = int(r[1])
            rows.append(r + [float(meter.foot_load_n[i])])
        # measured vertical acceleration of each swing foot over the tick just simulated: next tick's vz − this tick's
        # (filled in below from consecutive rows of the same foot)
    arr = np.array(rows)
    cols = ["t", "foot", "progress", "z_ref", "z", "vz_ref", "vz", "a_ff", "a_task", "a_qp", "pelvis_ref", "pelvis",
            "knee_margin", "wbc_contact", "corner_ref", "corner", "load"]
    c = {name: j for j, name in enumerate(cols)}
    a_sim = np.full(len(arr), np.nan)
    for i in range(2):
        idx = np.flatnonzero(arr[:, c["foot"]] == i)
        consecutive = np.isclose(np.diff(arr[idx, c["t"]]), CONTROL_PERIOD_S)
        a_sim[idx[:-1][consecutive]] = np.diff(arr[idx, c["vz"]])[consecutive] / CONTROL_PERIOD_S
    late = arr[:, c["progress"]] >= LATE_PROGRESS
    err = arr[:, c["z"]] - arr[:, c["z_ref"]]
    pelvis_err = arr[:, c["pelvis"]] - arr[:, c["pelvis_ref"]]
    d_task_qp = arr[:, c["a_task"]] - arr[:, c["a_qp"]]
    d_qp_sim = arr[:, c["a_qp"]] - a_sim
    # early strikes: first tick of each swing with load > 20 N while the plan is > 10 mm up
    strikes = []
    for i in range(2):
        idx = np.flatnonzero(arr[:, c["foot"]] == i)
        new_swing = np.r_[True, ~np.isclose(np.diff(arr[idx, c["t"]]), CONTROL_PERIOD_S)]
        swing_id = np.cumsum(new_swing)
        for s in np.unique(swing_id):
            rows_s = idx[swing_id == s]
            hit = rows_s[(arr[rows_s, c["load"]] > STRIKE_LOAD_N) & (arr[rows_s, c["z_ref"]] > STRIKE_PLAN_ABOVE_M)
                         & (arr[rows_s, c["progress"]] > 0.5)]
            if hit.size:
                strikes.append((int(hit[0]), rows_s))
    bw = robot.mass_kg * GRAVITY_MPS2

    def pct(x: np.ndarray) -> list[float]:
        x = x[np.isfinite(x)]
        return [round(float(v), 2) for v in np.percentile(x, [5, 25, 50, 75, 95])] if x.size else []

    report: dict[str, object] = {
        "style": style.name, "fell": fell, "swing_ticks_late": int(late.sum()),
        "late_z_err_mm_p5_25_50_75_95": pct(1000 * err[late]),
        "late_corner_err_mm_p5_25_50_75_95": pct(1000 * (arr[late, c["corner"]] - arr[late, c["corner_ref"]])),
        "late_pelvis_err_mm_p5_25_50_75_95": pct(1000 * pelvis_err[late]),
        "late_task_minus_qp_mps2_p5_25_50_75_95": pct(d_task_qp[late]),
        "late_qp_minus_sim_mps2_p5_25_50_75_95": pct(d_qp_sim[late & (arr[:, c["load"]] == 0)]),
        "late_knee_margin_rad_min": round(float(arr[late, c["knee_margin"]].min()), 3),
        "early_strikes": len(strikes),
    }
    detail = []
    for j, rows_s in strikes:
        before = rows_s[(rows_s <= j) & (rows_s > j - WINDOW_TICKS)]
        before_free = before[arr[before, c["load"]] == 0]
        detail.append({
            "t": round(float(arr[j, c["t"]]), 3), "foot": SIDES[int(arr[j, c["foot"]])],
            "progress": round(float(arr[j, c["progress"]]), 3),
            "z_ref_mm": round(1000 * float(arr[j, c["z_ref"]]), 1), "z_err_mm": round(1000 * float(err[j]), 1),
            "corner_ref_mm": round(1000 * float(arr[j, c["corner_ref"]]), 1),
            "corner_mm": round(1000 * float(arr[j, c["corner"]]), 1),
            "wbc_contact": bool(arr[j, c["wbc_contact"]]),
            "vz_ref": round(float(arr[j, c["vz_ref"]]), 3), "vz": round(float(arr[j, c["vz"]]), 3),
            "pelvis_err_mm": round(1000 * float(pelvis_err[j]), 1),
            "knee_margin_rad": round(float(arr[j, c["knee_margin"]]), 3),
            "load_bw": round(float(arr[j, c["load"]]) / bw, 2),
            "task_minus_qp_60ms": round(float(np.nanmean(d_task_qp[before])), 2),
            "qp_minus_sim_60ms": round(float(np.nanmean(d_qp_sim[before_free])), 2) if before_free.size else None,
            "a_ff_60ms": round(float(np.mean(arr[before, c["a_ff"]])), 2),
            "z_err_60ms_ago_mm": round(1000 * float(err[before[0]]), 1),
        })
    if args.strikes:
        report["strikes"] = detail
    if detail:
        report["strike_means"] = {k: round(float(np.nanmean([d[k] for d in detail if d[k] is not None])), 2)
                                  for k in ("z_ref_mm", "z_err_mm", "corner_ref_mm", "corner_mm", "pelvis_err_mm", "knee_margin_rad",
                                            "task_minus_qp_60ms", "qp_minus_sim_60ms", "a_ff_60ms",
                                            "z_err_60ms_ago_mm")}
        def values(key: str) -> list[float]:
            return [float(d[key]) for d in detail]  # type: ignore[arg-type]

        report["strike_extremes"] = {"corner_ref_mm_max": max(values("corner_ref_mm")),
                                     "z_err_mm_min": min(values("z_err_mm")), "load_bw_max": max(values("load_bw"))}
    print(json.dumps(report))


if __name__ == "__main__":
    main()
