"""`studio bench arms`: LWL2 against per-frame IK (with collision fixing) and the glue-only feed-forward
network, on held-out clips (CMU 141_16; every Bandai Namco clip — evaluation only), measured side by side.

Errors are hand / elbow distances (mm) to the optimisation-based targets (:func:`ik.arm_errors_m`: bone
directions scaled to the robot's arm, from its own shoulders); collision-free is the capsule check of every
output frame; times are per frame on this machine, in the same run (the ratio is what to compare).
Also: capsules against MuJoCo's collision detection on random poses.

Methods: ``lwl2`` (the shipped run-time path: LWR then a few refinement steps and the fixer,
:data:`puppeteer.REFINE_ITERS`), ``lwl2-paper`` (LWR alone, refine_iters = 0: the paper's method),
``ik+fix`` (per-frame optimisation-based retargeting warm-started from the previous frame, then the
fixer), ``feed-forward`` (glue-only network). Every method sees the same frames, interleaved frame by frame
so machine load hits them alike. A ``LWL2 vs IK`` row per clip group puts the per-frame medians side by
side with their ratio (``ik_over_lwl2`` > 1: LWL2 is faster) and the hand-error ratio (goal ≤ 1.2).
"""

from __future__ import annotations

import time

import numpy as np


def _clip_groups() -> dict[str, list]:
    from engine.retarget.humanoid_arm import sources

    groups: dict[str, list] = {}
    for path in sources.evaluation_clips():
        key = "cmu-held-out" if "cmu" in str(path) else "bandai-namco"
        groups.setdefault(key, []).append(path)
    return groups


def bench_arms(robots: tuple[str, ...] = ("g1", "talos"), fps: float = 30.0, agreement_poses: int = 300,
               weights_dir: str | None = None) -> list[dict]:
    """``weights_dir``: a folder of ``<robot>_lwl2.*`` weights (e.g. ``studio train-arms --out DIR/g1_lwl2``) instead
    of the shipped ones."""
    from pathlib import Path

    from engine.retarget.humanoid_arm.capsules import mujoco_agreement
    from engine.retarget.humanoid_arm.ik import ArmIK, arm_errors_m
    from engine.retarget.humanoid_arm.metadata import weights_path
    from engine.retarget.humanoid_arm.pose15 import bvh_points
    from engine.retarget.humanoid_arm.puppeteer import ArmRetargeter
    from engine.retarget.importers.bvh import load_bvh

    rows: list[dict] = []
    groups = _clip_groups()
    if not groups:
        return [{"section": "arms", "note": "shared mocap clips absent (set MOTION_STUDIO_SHARED)"}]
    for robot in robots:
        path = weights_path(robot, Path(weights_dir) if weights_dir is not None else None)
        if not path.with_suffix(".json").is_file():
            rows.append({"section": "arms", "robot": robot, "note": f"no trained weights at {path} (studio train-arms --robot {robot})"})
            continue
        try:
            arms = ArmRetargeter.load(robot, path)
        except ValueError as exc:  # weights of another robot, or damaged files: one line in the table
            rows.append({"section": "arms", "robot": robot, "note": str(exc)})
            continue
        ub, cm = arms.ub, arms.capsules
        paper = ArmRetargeter.load(robot, path, capsules=cm, refine_iters=0)
        ik = ArmIK(ub, cm)
        agree = mujoco_agreement(cm, agreement_poses)
        rows.append({"section": "arms", "robot": robot, "method": "capsules-vs-mujoco", "clips": f"{agree['poses']} random poses",
                     "agreement": agree["agreement"], "mujoco_only": agree["mujoco_only"],
                     "capsules_only": agree["capsules_only"], "conservative": agree["conservative"]})
        for group, paths in groups.items():
            stats: dict[str, dict[str, list[float]]] = {
                m: {"hand": [], "elbow": [], "free": [], "t": []} for m in ("lwl2", "lwl2-paper", "ik+fix", "feed-forward")}
            stages: dict[str, dict[str, list[float]]] = {"lwl2": {}, "lwl2-paper": {}, "ik+fix": {}}
            fallbacks = holds = frames = 0
            for path in paths:
                pts = bvh_points(load_bvh(path))
                poses = pts.pose15()[:: max(1, int(round(pts.fps / fps)))]
                frames += len(poses)
                for a in (arms, paper):
                    a.reset()
                    a.graph_fallbacks = a.holds = 0
                x_ik = None
                for p in poses:
                    for a, method in ((arms, "lwl2"), (paper, "lwl2-paper")):
                        step = a.retarget(p)
                        s = stats[method]
                        h, e = arm_errors_m(ub, step.x, p)
                        s["hand"].append(h)
                        s["elbow"].append(e)
                        s["free"].append(cm.is_free(step.x))
                        s["t"].append(step.inference_s)
                        for stage, dt in step.stages_s.items():
                            stages[method].setdefault(stage, []).append(dt)
                    # ik.solve(p, x_ik) (Gauss–Newton to 1e-4 rad, then the fixer), its two stages timed apart
                    t0 = time.perf_counter()
                    x_ik = ik.gauss_newton(p, x_ik)
                    t1 = time.perf_counter()
                    x_ik, ok = cm.fix(x_ik)
                    t2 = time.perf_counter()
                    stages["ik+fix"].setdefault("gauss_newton", []).append(t1 - t0)
                    stages["ik+fix"].setdefault("fix", []).append(t2 - t1)
                    s = stats["ik+fix"]
                    s["t"].append(t2 - t0)
                    h, e = arm_errors_m(ub, x_ik, p)
                    s["hand"].append(h)
                    s["elbow"].append(e)
                    s["free"].append(cm.is_free(x_ik))
                    if arms.feed_forward is not None:
                        t0 = time.perf_counter()
                        x_ff = arms.feed_forward_pose(p)
                        s = stats["feed-forward"]
                        s["t"].append(time.perf_counter() - t0)
                        h, e = arm_errors_m(ub, x_ff, p)
                        s["hand"].append(h)
                        s["elbow"].append(e)
                        s["free"].append(cm.is_free(x_ff))
                fallbacks += arms.graph_fallbacks
                holds += arms.holds
            lwl2_median = float(np.median(stats["lwl2"]["t"]))
            for method, s in stats.items():
                if not s["t"]:
                    continue
                t = np.array(s["t"])
                row = {"section": "arms", "robot": robot, "method": method, "clips": f"{group} ({len(paths)} files, {frames} frames)",
                       "hand_mm": round(float(np.mean(s["hand"]) * 1000), 1), "elbow_mm": round(float(np.mean(s["elbow"]) * 1000), 1),
                       "collision_free": round(float(np.mean(s["free"])), 4),
                       "median_us": round(float(np.median(t) * 1e6), 1), "p99_us": round(float(np.percentile(t, 99) * 1e6), 1),
                       "time_vs_lwl2": round(float(np.median(t)) / lwl2_median, 2)}
                if method == "lwl2":
                    row.update({"graph_steps": fallbacks, "holds": holds, "goal_p99_us": 2000,
                                "refine_iters": arms.refine_iters})
                rows.append(row)
            for method, per_stage in stages.items():  # where the time goes (medians per frame, µs)
                rows.append({"section": "arms", "robot": robot, "method": f"{method} stages", "clips": group,
                             **{f"{k}_us": round(float(np.median(v)) * 1e6, 1) for k, v in per_stage.items()}})
            ik_median = float(np.median(stats["ik+fix"]["t"]))
            hand = {m: float(np.mean(stats[m]["hand"])) for m in ("lwl2", "lwl2-paper", "ik+fix")}
            rows.append({"section": "arms", "robot": robot, "method": "LWL2 vs IK", "clips": group,
                         "lwl2_median_us": round(lwl2_median * 1e6, 1),
                         "lwl2_paper_median_us": round(float(np.median(stats["lwl2-paper"]["t"])) * 1e6, 1),
                         "ik_median_us": round(ik_median * 1e6, 1),
                         "ik_over_lwl2": round(ik_median / lwl2_median, 2),
                         "ik_over_lwl2_paper": round(ik_median / float(np.median(stats["lwl2-paper"]["t"])), 2),
                         "goal_ik_over_lwl2": 10.0,
                         "hand_lwl2_over_ik": round(hand["lwl2"] / hand["ik+fix"], 2),
                         "hand_lwl2_paper_over_ik": round(hand["lwl2-paper"] / hand["ik+fix"], 2),
                         "goal_hand_over_ik": 1.2})
    keys: list[str] = []
    for row in rows:  # one column set for the whole section (the table prints the first row's keys)
        keys += [k for k in row if k not in keys]
    return [{k: row.get(k, "") for k in keys} for row in rows]


__all__ = ["bench_arms"]
