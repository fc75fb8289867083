"""``studio bench push``: push recovery across the gait cycle (issue 13 item 4, issue 16 item 0).

A 1 s push at the pelvis from the front, back, left and right (the force points *from* that side:
a push from the front is −x), at ``phases`` evenly spread gait phases while the robot walks at
0.15 m/s, and from standing (command 0). Per run: survived, the CoM displacement from the
push's start to 3 s after its end (standing), and the mean velocity over the first whole gait
cycle that starts 3 s after the push, against the command (a whole cycle: over a window of another
length the step-to-step sway biases the mean — at 0.15 m/s G1 sways ±0.033 m/s sideways over 1 s,
±0.003 m/s over its 0.816 s cycle). Runs on Ray (local by default), resumable in ``out_dir``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from engine.walk_batch import print_progress, run_batch

DIRECTIONS: dict[str, tuple[float, float]] = {"front": (-1.0, 0.0), "back": (1.0, 0.0), "left": (0.0, -1.0), "right": (0.0, 1.0)}
PUSH_DURATION_S = 1.0
SETTLE_S = 3.0  # the robot must be back at rest / at the commanded velocity this long after the push
WALK_SPEED_MPS = 0.15
STAND_PUSH_T_S = 3.0
WALK_PUSH_T0_S = 4.0


def gait_cycle(robot: str, style: Any, speed_mps: float, t0_s: float) -> tuple[float, float]:
    """(start, duration) in seconds of the first whole gait cycle (left liftoff to left liftoff)
    that starts after ``t0_s`` walking at ``speed_mps`` (0: stepping in place), from the open-loop
    gait clock (the closed loop's clock runs within a few % of it: κ ≈ 1 while nothing pushes)."""
    from engine.gait.offline_plan import planner_for
    from engine.robot.model import load_robot

    planner = planner_for(load_robot(robot), style)
    dt = 1.0 / 125.0
    starts: list[float] = []
    last = planner.phi
    while len(starts) < 2 and planner.t_s < t0_s + 20.0:
        planner.step(dt, np.array([speed_mps, 0.0, 0.0]), with_preview=False)
        if planner.t_s >= t0_s and math.floor(planner.phi) > math.floor(last):
            starts.append(planner.t_s)
        last = planner.phi
    a, b = starts
    return a, b - a


def push_times(robot: str, style: Any, speed_mps: float, t0_s: float, phases: int) -> list[float]:
    """``phases`` times evenly spread over the first whole gait cycle that starts after ``t0_s``."""
    a, cycle = gait_cycle(robot, style, speed_mps, t0_s)
    return [round(a + k * cycle / phases, 3) for k in range(phases)]


def settled_window(t_end_s: float, cycle_s: float) -> tuple[float, float]:
    """Where the velocity after a push ending at ``t_end_s`` is measured: one whole gait cycle
    from SETTLE_S after the push."""
    return round(t_end_s + SETTLE_S, 3), round(t_end_s + SETTLE_S + cycle_s, 3)


def push_jobs(robot: str, style_path: str | Path, force_n_per_kg: float = 1.5, phases: int = 16,
              standing: bool = True, walking: bool = True) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """[(label, job)] for the whole matrix."""
    from engine.gait.style import load_style, style_to_json_dict
    from engine.robot.model import load_robot

    model = load_robot(robot)
    style = load_style(style_path)
    style_dict = style_to_json_dict(style)
    force = force_n_per_kg * model.mass_kg
    out = []
    cases: list[tuple[str, float, str, float]] = []
    if standing:
        cases.append(("stand", STAND_PUSH_T_S, "0,0,0", gait_cycle(robot, style, 0.0, STAND_PUSH_T_S)[1]))
    if walking:
        cycle = gait_cycle(robot, style, WALK_SPEED_MPS, WALK_PUSH_T0_S)[1]
        for k, t in enumerate(push_times(robot, style, WALK_SPEED_MPS, WALK_PUSH_T0_S, phases)):
            cases.append((f"walk φ{k:02d}/{phases}", t, f"{WALK_SPEED_MPS},0,0", cycle))
    for phase_label, t_push, command, cycle_s in cases:
        for direction, (ux, uy) in DIRECTIONS.items():
            t_end = t_push + PUSH_DURATION_S
            window = settled_window(t_end, cycle_s)
            job = {"robot": robot, "style": style_dict, "command": command,
                   "duration_s": round(window[1] + 0.1, 3),
                   "pushes": [[t_push, force * ux, force * uy, 0.0, PUSH_DURATION_S]],
                   "velocity_windows": {"settled": list(window)},
                   "displacements": {"push": [t_push, t_end + SETTLE_S]}}
            out.append(({"phase": phase_label, "direction": direction, "command": command}, job))
    return out


def push_verdict(label: dict[str, Any], result: dict[str, Any]) -> dict[str, Any]:
    """The figures of one run and whether it recovered as issue 16 asks."""
    row: dict[str, Any] = {"phase": label["phase"], "from": label["direction"]}
    if "error" in result:
        return {**row, "survived": "error", "recovered": False, "note": result["error"][:60]}
    vx_cmd = float(label["command"].split(",")[0])
    v = result.get("velocity_settled")
    disp = result.get("displacement_push")
    survived = not result["fell"]
    speed_err = None if v is None else float(math.hypot(v[0] - vx_cmd, v[1]))
    standing = vx_cmd == 0.0
    recovered = survived and speed_err is not None and speed_err < 0.05 and (not standing or (disp or 9.0) < 0.6)
    row.update({"survived": survived, "fall_s": result.get("fall_time_s"),
                "displacement_m": disp, "velocity_error_mps": None if speed_err is None else round(speed_err, 3),
                "recovered": recovered})
    return row


def bench_push(robot: str = "g1", style: str | None = None, n_per_kg: float = 1.5, phases: int = 16,
               out_dir: str | None = None, address: str | None = None) -> list[dict]:
    from engine.gait.style import styles_dir

    style_path = Path(style) if style else styles_dir(robot) / "neutral.json"
    labelled = push_jobs(robot, style_path, n_per_kg, phases)
    from engine.walk_batch import job_key

    out = Path(out_dir) if out_dir else Path.home() / ".cache" / "motion-studio" / "bench-push"
    results = run_batch([j for _, j in labelled], out, address=address, progress=print_progress)
    rows = []
    for label, job in labelled:
        rows.append({"section": "push", "robot": robot, "n_per_kg": n_per_kg,
                     **push_verdict(label, results.get(job_key(job), {"error": "missing"}))})
    for kind in ("stand", "walk"):
        sub = [r for r in rows if r["phase"].startswith(kind)]
        if sub:
            rows.append({"section": "push", "robot": robot, "n_per_kg": n_per_kg, "phase": f"{kind} total",
                         "from": "all", "survived": f"{sum(r['survived'] is True for r in sub)}/{len(sub)}",
                         "recovered": f"{sum(bool(r['recovered']) for r in sub)}/{len(sub)}",
                         "displacement_m": max((r.get("displacement_m") or 0.0) for r in sub)})
    return rows
