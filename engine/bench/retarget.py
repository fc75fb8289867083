"""``studio bench retarget``: the spatial and temporal stages of STMR on the paper's six clips.

* ``retarget`` — UVM and SMR (kinematic) over the clips × go1, a1, go2, b1, anymal_c, beside the paper's Table IV
  (foot slide, IoU), SMR's frame rate; ``retarget-contacts`` (the contact estimate against each clip's schedule);
  ``retarget-baseless`` (Table V's recovery).
* ``retarget-methods`` — UVM / SMR / STMR side by side, per clip and robot (go1, a1, anymal_c unless ``--robots``),
  each judged the same way: the method's motion tracked by the same receding-horizon iLQR in the robot's MuJoCo
  model — UVM's and SMR's as they are (α = 1), STMR's by TMR (BO over α) — and replayed open-loop: fell or
  not, DTW-normalised keypoint L1 (%) against the kinematic motion the method delivered (UVM's for UVM, SMR's for
  SMR and STMR) at its frames, tracking error (mm) against the motion each tracked, duration (s); and the wall
  time of each stage: UVM and SMR retargeting, the inner solve of UVM's and SMR's motions (one iLQR tracking at
  α = 1), the whole TMR (``evals`` BO evaluations), plus the CPU time of this process for SMR's inner solve and
  the TMR (wall times on a shared machine are inflated by its load, CPU times much less) and ``bo_trace``: BO's
  evaluations in order (α, ✓ stood or ↓ fell at s, wall s). Minutes per clip: ``--clips``, ``--robots`` and
  ``--budget`` (BO evaluations, default 6) make a small run; it runs when ``retarget`` is named (``studio bench
  retarget``), not in the default run of every section, and ``--kinematic`` leaves it out.
  ``studio bench tmr-clips`` is an alias of this part.

Reads the clips from the shared data folder (env MOTION_STUDIO_SHARED, else <repo>/../shared, else
/work/shared); prints one row saying so when it is absent.
"""

from __future__ import annotations

import os
import sys
import time
from typing import Any
from pathlib import Path

import numpy as np

from engine.bench.tmr import CLIP_BUDGET, CLIP_INIT_POINTS, CLIP_ROBOTS, CLIPS, PAPER_TABLE_II

ROBOTS = ("go1", "a1", "go2", "b1", "anymal_c")
BASELESS_CLIPS = ("trot0", "trot1", "pace0", "pace1")
BASELESS_ROBOTS = ("go1", "a1", "anymal_c")
# Table IV (foot slide mm UVM / ours, IoU UVM / ours); AlienGo stands where the paper has it.
PAPER_TABLE_IV = {
    ("go1", "trot0"): (110.19, 0.15, 0.46, 1.00), ("go1", "trot1"): (72.93, 0.09, 0.48, 1.00),
    ("go1", "pace0"): (88.90, 0.14, 0.47, 1.00), ("go1", "pace1"): (61.33, 0.09, 0.53, 0.99),
    ("go1", "sidesteps"): (34.74, 0.03, 0.60, 1.00), ("go1", "hopturn"): (33.35, 0.05, 0.59, 1.00),
    ("a1", "trot0"): (101.39, 0.15, 0.44, 1.00), ("a1", "trot1"): (86.29, 0.12, 0.50, 1.00),
    ("a1", "pace0"): (83.29, 0.12, 0.47, 1.00), ("a1", "pace1"): (63.58, 0.11, 0.53, 1.00),
    ("a1", "sidesteps"): (41.37, 0.04, 0.58, 1.00), ("a1", "hopturn"): (37.19, 0.05, 0.49, 1.00),
}


def shared_dir() -> Path | None:
    env = os.environ.get("MOTION_STUDIO_SHARED")
    repo = Path(__file__).resolve().parents[1]
    for cand in ([Path(env)] if env else []) + [repo.parent / "shared", Path("/work/shared")]:
        if (cand / "motions-src").is_dir():
            return cand
    return None


def clip_path(shared: Path, clip: str) -> Path:
    return shared / "motions-src" / "stmr_rl" / "datasets" / clip / f"{clip}_keypoints.npz"


def _names(value: str | None) -> tuple[str, ...] | None:
    return None if value is None else tuple(v.strip() for v in value.split(",") if v.strip())


def bench_retarget(clips: tuple[str, ...] = CLIPS, robots: tuple[str, ...] = ROBOTS, baseless: bool = True,
                   clip_names: str | None = None, robot_names: str | None = None, bo_budget: int | None = None,
                   tracked: bool = True, address: str | None = None) -> list[dict]:
    """The kinematic tables, then (``tracked``) the UVM / SMR / STMR comparison; see the module docstring.
    ``clip_names`` / ``robot_names`` (``--clips a,b`` / ``--robots a,b``) select among ``CLIPS`` / ``ROBOTS``
    (the comparison's robots default to go1, a1, anymal_c), ``bo_budget`` (``--budget``) is TMR's budget."""

    problem = check_clip_options(clip_names, bo_budget, robot_names)
    if problem:
        raise ValueError(problem)
    clips = _names(clip_names) or clips
    rows = bench_retarget_kinematic(clips, _names(robot_names) or robots, baseless)
    if tracked and shared_dir() is not None:
        rows += bench_retarget_methods(clips, _names(robot_names) or CLIP_ROBOTS, bo_budget or CLIP_BUDGET,
                                       address=address)
    return rows


def bench_retarget_kinematic(clips: tuple[str, ...] = CLIPS, robots: tuple[str, ...] = ROBOTS,
                             baseless: bool = True) -> list[dict]:
    """UVM and SMR (kinematic figures) beside the paper's Table IV, the contact estimate, baseless recovery."""
    from engine.retarget.contacts import contact_iou, estimate_contacts
    from engine.retarget.importers import import_source
    from engine.retarget.metrics import recovery_rate_percent, travel_distance_m
    from engine.retarget.quadruped.pipeline import RetargetOptions, retarget_detailed

    shared = shared_dir()
    if shared is None:
        return [{"section": "retarget", "note": "shared data folder absent: set MOTION_STUDIO_SHARED"}]
    rows: list[dict[str, Any]] = []
    for robot in robots:
        retarget_detailed(import_source(clip_path(shared, clips[0])), robot, "uvm")  # warm the model cache
    for robot in robots:
        for clip in clips:
            src = import_source(clip_path(shared, clip))
            row = {"section": "retarget", "robot": robot, "clip": clip, "frames": src.frames}
            for method in ("uvm", "smr"):
                out = retarget_detailed(src, robot, method)
                fig = out.motion.metrics
                row[f"{method}_slide_mm"] = "-" if fig["foot_slide_mm"] is None else round(fig["foot_slide_mm"], 3)
                row[f"{method}_iou"] = round(fig["contact_iou"], 3)
                row[f"{method}_pen_mm"] = round(fig["penetration_mm"], 2)
                if method == "smr":
                    row["smr_kp_err_mm"] = fig["keypoint_error_mm"]
                row[f"{method}_frames_per_s"] = round(fig["frames_per_s"], 0)
                row[f"{method}_frames_per_cpu_s"] = round(fig["frames_per_cpu_s"], 0)
            paper = PAPER_TABLE_IV.get((robot, clip))
            row["paper_uvm_slide_mm"], row["paper_smr_slide_mm"], row["paper_uvm_iou"], row["paper_smr_iou"] = (
                paper if paper else ("", "", "", ""))
            rows.append(row)
    smr_rows = [r for r in rows if r["robot"] in ("go1", "a1", "anymal_c")]

    def mean(key: str, digits: int) -> float:
        vals = [float(r[key]) for r in smr_rows if r[key] != "-"]
        return round(float(np.mean(vals)), digits) if vals else float("nan")

    if smr_rows:
        rows.append({"section": "retarget", "robot": "go1+a1+anymal_c", "clip": "mean", "frames": sum(r["frames"] for r in smr_rows),
                     "uvm_slide_mm": mean("uvm_slide_mm", 3),
                     "uvm_iou": round(float(np.mean([r["uvm_iou"] for r in smr_rows])), 3),
                     "uvm_pen_mm": round(float(np.max([r["uvm_pen_mm"] for r in smr_rows])), 2),
                     "smr_slide_mm": mean("smr_slide_mm", 3),
                     "smr_iou": round(float(np.mean([r["smr_iou"] for r in smr_rows])), 4),
                     "smr_pen_mm": round(float(np.max([r["smr_pen_mm"] for r in smr_rows])), 2),
                     "smr_kp_err_mm": round(float(np.mean([r["smr_kp_err_mm"] for r in smr_rows])), 1),
                     **{k: mean(k, 0) for k in ("uvm_frames_per_s", "uvm_frames_per_cpu_s", "smr_frames_per_s", "smr_frames_per_cpu_s")},
                     "paper_uvm_slide_mm": 73.92, "paper_smr_slide_mm": 0.34, "paper_uvm_iou": 0.513, "paper_smr_iou": 0.998})
    for clip in clips:  # the contact estimate (foot height + speed) against the clip's own schedule
        src = import_source(clip_path(shared, clip))
        est = estimate_contacts(src.feet, src.fps)
        rows.append({"section": "retarget-contacts", "clip": clip, "schedule_from": src.source.get("contact_from"),
                     "estimate_iou": round(contact_iou(est, src.contact), 3),
                     "contact_fraction_source": round(float(src.contact.mean()), 3),
                     "contact_fraction_estimate": round(float(est.mean()), 3)})
    if baseless:
        for clip in [c for c in BASELESS_CLIPS if c in clips]:
            src = import_source(clip_path(shared, clip))
            row = {"section": "retarget-baseless", "clip": clip}
            for robot in [r for r in BASELESS_ROBOTS if r in robots]:
                wb = retarget_detailed(src, robot, "smr").motion
                bl = retarget_detailed(src, robot, "smr", RetargetOptions(baseless=True)).motion
                d_wb, d_bl = travel_distance_m(wb.base_pos), travel_distance_m(bl.base_pos)
                row[f"{robot}_with_base_m"] = round(d_wb, 3)
                row[f"{robot}_baseless_m"] = round(d_bl, 3)
                row[f"{robot}_recovery_pct"] = round(recovery_rate_percent(d_bl, d_wb), 1)
            rows.append(row)
    return rows


METHOD_KEYS = ("fell", "dtw_pct", "track_mm", "duration_s")  # per method, side by side


def bench_retarget_methods(clips: tuple[str, ...] = CLIPS, robots: tuple[str, ...] = CLIP_ROBOTS,
                           budget: int = CLIP_BUDGET, address: str | None = None, parallel: int = 1,
                           clip_names: str | None = None, bo_budget: int | None = None,
                           robot_names: str | None = None) -> list[dict]:
    """UVM / SMR / STMR, each tracked and replayed the same way, per clip and robot (``retarget-methods`` rows;
    see the module docstring)."""
    from engine.retarget.importers import import_source
    from engine.retarget.quadruped.pipeline import retarget_detailed
    from engine.ray_cluster import RayClusterError
    from engine.retarget.quadruped.tmr.ray_jobs import LocalExecutor, RayExecutor
    from engine.retarget.quadruped.tmr.tmr import TMRSettings, temporal_retarget, track_motion

    problem = check_clip_options(clip_names, bo_budget, robot_names)
    if problem:
        raise ValueError(problem)
    clips = _names(clip_names) or clips
    robots = _names(robot_names) or robots
    budget = bo_budget if bo_budget is not None else budget
    shared = shared_dir()
    if shared is None:
        return [{"section": "retarget-methods", "note": "shared data folder absent: set MOTION_STUDIO_SHARED"}]
    executor: LocalExecutor | RayExecutor = LocalExecutor()
    if address is not None or parallel > 1:
        try:
            executor = RayExecutor(address=address)
        except RayClusterError as exc:
            print(f"bench retarget: {exc}; running the evaluations one at a time in this process", file=sys.stderr)
            parallel = 1
    # the warm start: α = 1, then every segment at log2 α = −1, +1 and −0.5 (bayes_opt.initial_design); EI after
    settings = TMRSettings(budget=budget, init_points=min(CLIP_INIT_POINTS, budget), parallel=parallel)
    rows: list[dict[str, Any]] = []
    try:
        for robot in robots:
            for clip in clips:
                src = import_source(clip_path(shared, clip))
                t0 = time.perf_counter()
                uvm = retarget_detailed(src, robot, "uvm").motion
                t_uvm = time.perf_counter() - t0
                t0 = time.perf_counter()
                smr = retarget_detailed(src, robot, "smr").motion
                t_smr = time.perf_counter() - t0
                uvm_tracked = track_motion(uvm, settings)  # UVM's motion as it is (α = 1)
                c0 = time.process_time()
                smr_tracked = track_motion(smr, settings)  # one inner solve at α = 1: SMR's motion as it is
                cpu_inner = time.process_time() - c0
                t0, c0 = time.perf_counter(), time.process_time()
                res = temporal_retarget(smr, settings, executor=executor)
                t_tmr, cpu_tmr = time.perf_counter() - t0, time.process_time() - c0
                s = res.summary
                first_widened = s["bo_evaluations"] - s["bo_evaluations_widened"]  # (none when 0 widened)
                before = s["duration_s"]["before"]
                paper = PAPER_TABLE_II.get((robot, clip), ("", ""))
                smr_dtw, stmr_dtw = smr_tracked["dtw_keypoint_l1_pct"], s["dtw_keypoint_l1_pct"]
                rows.append({
                    "section": "retarget-methods", "clip": clip, "robot": robot,
                    "uvm_fell": uvm_tracked["replay_fell"], "uvm_dtw_pct": uvm_tracked["dtw_keypoint_l1_pct"],
                    "uvm_track_mm": uvm_tracked["tracking_error_mm"], "uvm_duration_s": before,
                    "smr_fell": smr_tracked["replay_fell"], "smr_dtw_pct": smr_dtw,
                    "smr_track_mm": smr_tracked["tracking_error_mm"], "smr_duration_s": before,
                    "stmr_fell": s["replay_fell"], "stmr_dtw_pct": stmr_dtw, "stmr_track_mm": s["tracking_error_mm"],
                    "stmr_duration_s": s["duration_s"]["after"],
                    "stmr_alpha": ",".join(f"{a:.3f}" for a in s["alpha"]), "stmr_fell_at_s": s["replay_fell_at_s"],
                    "stmr_log2_bound_searched": s["log2_bound_searched"],
                    "stmr_dtw_vs_target_pct": s["dtw_vs_target_pct"],
                    "stmr_vs_smr_dtw_pct": (round(100.0 * (stmr_dtw - smr_dtw) / smr_dtw, 1)
                                            if stmr_dtw is not None and smr_dtw else None),
                    # per-stage wall times (s)
                    "uvm_s": round(t_uvm, 2), "smr_s": round(t_smr, 2), "uvm_track_s": uvm_tracked["wall_time_s"],
                    "smr_track_s": smr_tracked["wall_time_s"], "tmr_s": round(t_tmr, 1), "evals": s["bo_evaluations"],
                    # CPU time of this process (the evaluations' own when they run in process, not on Ray workers)
                    "smr_track_cpu_s": round(cpu_inner, 1), "tmr_cpu_s": round(cpu_tmr, 1),
                    "tmr_vs_inner_solve_cpu": round(cpu_tmr / cpu_inner, 2) if cpu_inner > 0 else None,
                    "paper_smr_dtw_pct": paper[1], "paper_stmr_dtw_pct": paper[0],
                    # (the widened search's evaluations come last: "widened:" before them)
                    "bo_trace": " ".join(("widened: " if k == first_widened else "")
                                         + f"{e['alpha'][0] if len(e['alpha']) == 1 else e['alpha']}"
                                         f"{'↓' + str(e['fell_at_s']) if e['replay_fell'] else '✓'}({e['wall_time_s']:g}s)"
                                         for k, e in enumerate(res.evaluations)),
                })
                print(f"bench retarget: {rows[-1]}", file=sys.stderr, flush=True)
    finally:
        if isinstance(executor, RayExecutor):
            executor.shutdown()
    return rows


def _cell(*values: Any) -> str:
    out = []
    for v in values:
        if isinstance(v, bool):
            out.append("**yes**" if v else "no")
        elif v is None or v == "":
            out.append("–")
        else:
            out.append(f"{v:g}" if isinstance(v, float) else str(v))
    return " / ".join(out)


def methods_table(rows: list[dict]) -> str:
    """The ``retarget-methods`` rows as the side-by-side table ``studio bench retarget`` prints (markdown)."""
    head = ("| clip | robot | UVM: fell / DTW % / mm / s | SMR: fell / DTW % / mm / s | STMR: fell / DTW % / mm / s "
            "| STMR α | STMR vs SMR DTW | wall s: UVM / SMR / UVM track / SMR track / TMR (evals) "
            "| CPU s: SMR track / TMR | BO evaluations (α, ✓ stood / ↓ fell at s) |")
    lines = [head, "|" + "---|" * head.count(" | ") + "---|"]
    for r in rows:
        if "note" in r:
            lines.append(f"| {r['note']} |")
            continue
        fell = r["stmr_fell"]
        stmr_fell = (f"**yes** (at {r['stmr_fell_at_s']:g} s)" if fell and r.get("stmr_fell_at_s") is not None
                     else _cell(fell))
        change = r.get("stmr_vs_smr_dtw_pct")
        lines.append(
            f"| {r['clip']} | {r['robot']} "
            f"| {_cell(r['uvm_fell'], r['uvm_dtw_pct'], r['uvm_track_mm'], r['uvm_duration_s'])} "
            f"| {_cell(r['smr_fell'], r['smr_dtw_pct'], r['smr_track_mm'], r['smr_duration_s'])} "
            f"| {stmr_fell} / {_cell(r['stmr_dtw_pct'], r['stmr_track_mm'], r['stmr_duration_s'])} "
            f"| {r['stmr_alpha']} | {'–' if change is None else f'{change:+.0f} %'} "
            f"| {_cell(r['uvm_s'], r['smr_s'], r['uvm_track_s'], r['smr_track_s'], r['tmr_s'])} ({r['evals']}) "
            f"| {_cell(r['smr_track_cpu_s'], r['tmr_cpu_s'])} | {r['bo_trace']} |")
    return "\n".join(lines)


def check_clip_options(clip_names: str | None, bo_budget: int | None, robot_names: str | None = None) -> str | None:
    """The one-line complaint about ``--clips`` / ``--budget`` / ``--robots``, or None."""
    if clip_names is not None:
        names = [c.strip() for c in clip_names.split(",") if c.strip()]
        unknown = [c for c in names if c not in CLIPS] or ([] if names else [clip_names])
        if unknown:
            return f"--clips: unknown clip {unknown[0]!r}; expected some of {', '.join(CLIPS)}"
    if robot_names is not None:
        names = [r.strip() for r in robot_names.split(",") if r.strip()]
        unknown = [r for r in names if r not in ROBOTS] or ([] if names else [robot_names])
        if unknown:
            return f"--robots: unknown robot {unknown[0]!r}; expected some of {', '.join(ROBOTS)}"
    if bo_budget is not None and bo_budget < 1:
        return f"--budget: expected ≥ 1 BO evaluations, got {bo_budget}"
    return None


def bench_tmr_clips(clips: tuple[str, ...] = CLIPS, robots: tuple[str, ...] = CLIP_ROBOTS, budget: int = CLIP_BUDGET,
                    address: str | None = None, parallel: int = 1, robot: str | None = None,
                    clip_names: str | None = None, bo_budget: int | None = None,
                    robot_names: str | None = None) -> list[dict]:
    """An alias of ``studio bench retarget``'s UVM / SMR / STMR comparison (its ``retarget-methods`` rows, without
    the kinematic tables): ``robot`` (the bench's ``--robot``) picks one of ``CLIP_ROBOTS``, any other value (the
    bench's default g1) keeps them all; ``robot_names`` (``--robots a,b``) overrides it."""
    if robot in CLIP_ROBOTS:
        robots = (robot,)
    return bench_retarget_methods(clips, robots, budget, address=address, parallel=parallel, clip_names=clip_names,
                                  bo_budget=bo_budget, robot_names=robot_names)
