"""``studio bench retarget``: UVM and SMR over the six STMR clips × go1, a1, go2, b1, anymal_c, beside the
paper's Table IV (foot slide, IoU), plus baseless recovery (Table V) and SMR's frame rate.

Reads the clips from the shared data folder (env MOTION_STUDIO_SHARED, else <repo>/../shared, else
/work/shared); prints one row saying so when it is absent.
"""

from __future__ import annotations

import os
from typing import Any
from pathlib import Path

import numpy as np

CLIPS = ("trot0", "trot1", "pace0", "pace1", "sidesteps", "hopturn")
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


def bench_retarget(clips: tuple[str, ...] = CLIPS, robots: tuple[str, ...] = ROBOTS, baseless: bool = True) -> list[dict]:
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
