"""Fall anatomy of random styles: what the stance ankles, servos, CoM and feet did before each fall (issue 13).

Walks random styles of ``studio bench styles`` (engine/bench/styles.py: same robot, seed, count and extent, so
index i is the same style) through the sweep up to their fall, recorded, and reports over the ``window`` seconds
before the fall, per style:

* ``ank_p`` / ``ank_r``: share of the stance time (a foot the plan has on the ground) its ankle pitch / roll sits
  within 0.02 rad of a joint limit (the larger of the two sides; ``L``/``R`` names it);
* ``sat_p`` / ``sat_r``: share of the stance ticks that ankle's servo torque is at its bound (≥ 89 % of the effort
  limit: the controller bounds its torques at 90 %, engine/sim.py clips at 100 %); ``sat_leg``: any leg joint;
* ``com_lon`` / ``com_lat``: the largest CoM error against the MPC plan along / across the pelvis heading (mm,
  signed: + ahead / to the left); ``step_adj``: the largest step adjustment (m);
* ``roll`` / ``pitch``: pelvis roll / pitch at the fall (rad; + pitch leans forward, + roll to the right), and
  ``roll_max`` / ``pitch_max`` the largest before the last 0.3 s; ``v``: mean body-frame base velocity over the
  last 0.5 s, ``cmd`` the command at the fall;
* ``strike``: the largest normal force on a foot the plan has in the air (N; tens of N and more: an early strike);
* ``seg``: the sweep's leg at the fall (forward, reverse, strafe_l/r, turn_l/r, stop(...) after one of them);
* ``limits``: other joints within 0.02 rad of a limit more than 30 % of the window;
* ``onset_s`` / ``onset_dir`` / ``onset_seg``: the start of the final divergence — the first time the CoM is 40 mm
  off its plan after it was last within 20 mm of it (after 1 s) — in which
  direction (``lon-40``: behind), in which leg of the sweep; the ``pre_*`` columns are the indicators above over
  the 0.5 s before that onset (what started the fall rather than the fall itself).

Usage (from the tree, one core): ``python tools/fall_anatomy.py --robot g1 --n 40 --seed 0 --extent 0.3
--duration 60 --bench /path/bench.json 8 9 13`` — ``--bench`` (the JSON ``studio bench styles`` wrote) gives each
style's fall time so the walk stops 0.1 s after it; without it the walk runs ``--duration``. ``--json OUT``
writes the rows.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

import numpy as np

from engine.bench.options import add_random_style_options
from engine.bench.styles import style_jobs
from engine.gait.command_schedule import parse_command
from engine.geometry.rotation import matrix_from_quat, roll_pitch_of
from engine.robot.model import RobotModel, load_robot
from engine.sim import Simulation
from engine.walk_runner import ContactMeter, run_walk

NEAR_LIMIT_RAD = 0.02
SATURATED = 0.89  # of the effort limit: the controller bounds its torques at 90 % of it
ONSET_M = 0.04
CALM_M = 0.02
SEGMENTS = ("forward", "reverse", "strafe_l", "strafe_r", "turn_l", "turn_r")


class TickProbe:
    """Per-tick servo torques, plan contacts and foot loads, kept from ``t_from_s`` on (patched into the sim)."""

    def __init__(self, t_from_s: float):
        self.t_from_s = t_from_s
        self.t: list[float] = []
        self.tau: list[np.ndarray] = []
        self.plan_contact: list[np.ndarray] = []
        self.load: dict[float, np.ndarray] = {}
        self.limits: np.ndarray | None = None

    def install(self) -> tuple[Any, Any]:
        probe = self
        servos, cop = Simulation._apply_servos, ContactMeter.cop

        def apply_servos(sim: Simulation, cmd: Any, joint_q: Any = None, joint_qd: Any = None) -> None:
            servos(sim, cmd, joint_q, joint_qd)
            t = float(sim.data.time)
            ref = getattr(sim.controller, "ref", None)
            if t >= probe.t_from_s and ref is not None:
                probe.limits = sim._effort_limits
                probe.t.append(t)
                probe.tau.append(np.asarray(sim.data.ctrl[sim._ctrl_index]).copy())
                probe.plan_contact.append(np.asarray(ref.contact, dtype=bool).copy())

        def meter_cop(meter: ContactMeter, data: Any) -> Any:
            out = cop(meter, data)
            if data.time >= probe.t_from_s:
                probe.load[round(float(data.time), 6)] = meter.foot_load_n.copy()
            return out

        Simulation._apply_servos = apply_servos  # type: ignore[method-assign,assignment]
        ContactMeter.cop = meter_cop  # type: ignore[method-assign,assignment]
        return servos, cop

    @staticmethod
    def uninstall(saved: tuple[Any, Any]) -> None:
        Simulation._apply_servos, ContactMeter.cop = saved  # type: ignore[method-assign]


def sweep_segment(t_s: float, command: np.ndarray) -> str:
    """The sweep's leg at ``t_s`` (engine/gait/command_schedule.sweep_keyframes' timing)."""
    if t_s < 1.0:
        return "stand"
    leg = int((t_s - 1.0) // 8.5)
    if leg >= len(SEGMENTS):
        return "stop"
    moving = np.abs(command).max() > 1e-3
    return SEGMENTS[leg] if moving else f"stop({SEGMENTS[leg]})"


def leg_joint_names(robot: RobotModel, side: str) -> list[str]:
    """The joints from the pelvis down to ``side``'s sole, hip first (G1: hip pitch … ankle roll; TALOS: leg 1 … 6),
    read from the kinematic chain of the ``{side}_foot`` frame: the ankle's pitch and roll are the last two."""
    model = robot.pin_model
    joint = model.frames[robot.frame_id(f"{side}_foot")].parentJoint
    chain = [model.names[j] for j in model.supports[joint] if j > 0 and model.joints[j].nv == 1]
    return chain[-6:]


def ankle_joint_name(robot: RobotModel, side: str, axis: str) -> str:
    """The ankle's ``pitch`` or ``roll`` joint of ``side`` (the leg chain's second-last / last joint)."""
    return leg_joint_names(robot, side)[-2 if axis == "pitch" else -1]


def window_indicators(robot: RobotModel, rec: dict[str, np.ndarray], probe: TickProbe, t0: float, t1: float,
                      prefix: str = "") -> dict[str, Any]:
    """Stance-ankle limits, servo saturation, swing-foot loads and other joints at limits over (t0, t1]."""
    m = robot.mj_model
    t = np.asarray(rec["t"])
    sel = (t > t0) & (t <= t1)
    q = np.asarray(rec["qpos"])
    con = np.asarray(rec["contact"], dtype=bool)
    row: dict[str, Any] = {}
    for axis in ("pitch", "roll"):
        best, side_best = 0.0, "-"
        for si, side in enumerate(("left", "right")):
            j = m.joint(ankle_joint_name(robot, side, axis))
            lo, hi = m.jnt_range[j.id]
            v = q[sel, j.qposadr[0]]
            stance = con[sel, si]
            if stance.sum() == 0:
                continue
            share = float(np.mean(np.minimum(v - lo, hi - v)[stance] < NEAR_LIMIT_RAD))
            if share > best:
                best, side_best = share, side[0].upper()
        row[f"{prefix}ank_{axis[0]}"] = f"{best:.2f}{side_best}"
    tt = np.asarray(probe.t)
    tsel = (tt > t0) & (tt <= t1)
    tau = np.asarray(probe.tau)[tsel]
    pc = np.asarray(probe.plan_contact)[tsel]
    clipped = np.abs(tau) >= SATURATED * np.asarray(probe.limits)
    names = robot.joint_names
    for axis in ("pitch", "roll"):
        best = 0.0
        for si, side in enumerate(("left", "right")):
            k = names.index(ankle_joint_name(robot, side, axis))
            if pc[:, si].sum():
                best = max(best, float(np.mean(clipped[pc[:, si], k])))
        row[f"{prefix}sat_{axis[0]}"] = round(best, 2)
    leg_names = leg_joint_names(robot, "left") + leg_joint_names(robot, "right")
    legs = [k for k, n in enumerate(names) if n in leg_names]
    ankles = {ankle_joint_name(robot, side, axis) for side in ("left", "right") for axis in ("pitch", "roll")}
    row[f"{prefix}sat_leg"] = round(float(np.mean(clipped[:, legs].any(axis=1))), 2) if len(clipped) else 0.0
    dt = float(m.opt.timestep)
    loads = np.array([probe.load.get(round(x + dt, 6), np.zeros(2)) for x in tt[tsel]]).reshape(-1, 2)
    swing_load = np.where(~pc, loads, 0.0)
    row[f"{prefix}strike"] = int(round(float(swing_load.max()))) if swing_load.size else 0
    hits = []
    for j in range(1, m.njnt):
        if not m.jnt_limited[j] or m.joint(j).name in ankles:
            continue
        lo, hi = m.jnt_range[j]
        v = q[sel, m.jnt_qposadr[j]]
        share = float(np.mean(np.minimum(v - lo, hi - v) < NEAR_LIMIT_RAD)) if v.size else 0.0
        if share > 0.3:
            hits.append(f"{m.joint(j).name.replace('_joint', '')}:{share:.1f}")
    row[f"{prefix}limits"] = " ".join(hits)
    return row


def anatomy(robot: RobotModel, style: Any, duration_s: float, window_s: float) -> dict[str, Any]:
    """One walk to its fall (or ``duration_s``) and the indicators of the module docstring."""
    probe = TickProbe(0.0)
    saved = probe.install()
    try:
        summary, rec = run_walk(robot, style, parse_command("sweep", style.velocities), duration_s)
    finally:
        TickProbe.uninstall(saved)
    t = np.asarray(rec["t"])
    tf = summary["fall_time_s"] if summary["fell"] else float(t[-1])
    sel = (t > tf - window_s) & (t <= tf)
    q = np.asarray(rec["qpos"])
    cmd = np.asarray(rec["command"])
    row: dict[str, Any] = {"fell": bool(summary["fell"]), "fall_s": round(tf, 3),
                           "slip_mm": round(float(summary["max_stance_slip_mm"]), 2)}
    # CoM error against the MPC plan in the pelvis heading frame.
    e = np.asarray(rec["com"])[:, :2] - np.asarray(rec["com_ref"])[:, :2]
    yaw = np.asarray(rec["pelvis_yaw_achieved"])
    lon = np.cos(yaw) * e[:, 0] + np.sin(yaw) * e[:, 1]
    lat = -np.sin(yaw) * e[:, 0] + np.cos(yaw) * e[:, 1]
    late = np.where(sel)[0]
    kl, ka = late[np.argmax(np.abs(lon[late]))], late[np.argmax(np.abs(lat[late]))]
    row["com_lon"], row["com_lat"] = int(round(1000 * lon[kl])), int(round(1000 * lat[ka]))
    # Onset: the first time after the first second the CoM is ONSET_M off its plan.
    err = np.hypot(lon, lat)
    calm = np.where((t > 1.0) & (t < tf) & (err < CALM_M))[0]
    big = np.where((t > (t[calm[-1]] if calm.size else 1.0)) & (t <= tf) & (err > ONSET_M))[0]
    if not big.size:  # the CoM swung back through its plan as it fell: the first divergence after 1 s
        big = np.where((t > 1.0) & (t <= tf) & (err > ONSET_M))[0]
    if big.size:
        k = int(big[0])
        row["onset_s"] = round(float(t[k]), 2)
        row["onset_dir"] = (f"lon{lon[k] * 1000:+.0f}" if abs(lon[k]) >= abs(lat[k]) else f"lat{lat[k] * 1000:+.0f}")
        row["onset_seg"] = sweep_segment(float(t[k]), cmd[k])
        row.update(window_indicators(robot, rec, probe, float(t[k]) - 0.5, float(t[k]), "pre_"))
    else:
        row["onset_s"], row["onset_dir"], row["onset_seg"] = None, "", ""
    row["step_adj"] = round(float(np.linalg.norm(np.asarray(rec["step_adjust"])[sel], axis=1).max()), 3)
    rp = np.array([roll_pitch_of(matrix_from_quat(x)) for x in q[sel, 3:7]])
    row["roll"], row["pitch"] = round(float(rp[-1, 0]), 2), round(float(rp[-1, 1]), 2)
    early = rp[:-int(0.3 / (t[1] - t[0]))] if len(rp) > 60 else rp  # before the last 0.3 s of the fall itself
    row["roll_max"] = round(float(early[np.argmax(np.abs(early[:, 0])), 0]), 2)
    row["pitch_max"] = round(float(early[np.argmax(np.abs(early[:, 1])), 1]), 2)
    last = (t > tf - 0.5) & (t <= tf)
    vb = np.asarray(rec["base_vel_body"])[last].mean(axis=0)
    row["v"] = f"{vb[0]:+.2f},{vb[1]:+.2f}"
    row["cmd"] = f"{cmd[-1][0]:+.2f},{cmd[-1][1]:+.2f},{cmd[-1][2]:+.2f}"
    row["seg"] = sweep_segment(tf, cmd[-1])
    row.update(window_indicators(robot, rec, probe, tf - window_s, tf))
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("indices", type=int, nargs="+")
    add_random_style_options(ap)
    ap.add_argument("--window", type=float, default=1.5)
    ap.add_argument("--bench", help="the bench JSON with each style's fall time")
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args(argv)
    falls: dict[int, float] = {}
    if a.bench:
        try:
            for r in json.load(open(a.bench))["rows"]:
                if isinstance(r.get("i"), int) and r.get("fell"):
                    falls[r["i"]] = float(r["fall_s"])
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
            print(f"{a.bench}: expected the JSON of `studio bench styles` (rows with i, fell, fall_s): {exc}",
                  file=sys.stderr)
            return 2
    robot = load_robot(a.robot)
    pairs = style_jobs(a.robot, a.n, a.seed, a.duration, a.extent, a.space)
    rows = []
    for i in a.indices:
        if not 0 <= i < len(pairs):
            print(f"index {i}: expected 0..{len(pairs) - 1}", file=sys.stderr)
            return 2
        dur = min(a.duration, falls[i] + 0.1) if i in falls else a.duration
        row = {"i": i, **anatomy(robot, pairs[i][0], dur, a.window)}
        rows.append(row)
        print(json.dumps(row), flush=True)
        if a.json:
            with open(a.json, "w") as f:
                json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
