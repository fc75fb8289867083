"""``studio bench tmr`` and ``studio bench tmr-clips``: the temporal stage of STMR on this machine.

``tmr`` — wall time of TMR's stages and Ray's speed-up, measured side by side in one run: one inner solve (iLQR
tracking of a 1 s go1 trot at α = 1, receding horizon), then the same TMR (four BO evaluations, the same warm
start) in this process, on a local Ray with 1 worker and with 2 workers; the speed-up is the ratio of the wall
times. A local Ray that does not start (a loaded machine can miss raylet's start-up window) is one row saying
so; the in-process row is then the serial figure.

``tmr-clips`` (minutes per clip; only when asked for; ``--robot go1|a1|anymal_c`` for one robot) — an alias of
the UVM / SMR / STMR comparison that ``studio bench retarget`` prints (its ``retarget-methods`` rows,
:func:`engine.bench.retarget.bench_retarget_methods`), over go1, a1 and anymal_c by default.
"""

from __future__ import annotations

import sys
import time

import numpy as np

CLIP_DURATION_S = 1.0
RAY_BUDGET = 4  # two batches of two on 2 workers
CLIPS = ("trot0", "trot1", "pace0", "pace1", "sidesteps", "hopturn")
CLIP_ROBOTS = ("go1", "a1", "anymal_c")
CLIP_BUDGET = 6
CLIP_INIT_POINTS = 4  # BO's warm start in tmr-clips: α = 1, log2 α = −1, +1, −0.5 (the rest EI)
# Table II (STMR, SMR: DTW keypoint L1 %) for the flight-phase clips; Fig. 6 mean tracking error 48.7 mm
PAPER_TABLE_II = {("go1", "sidesteps"): (1.9, 5.3), ("a1", "sidesteps"): (2.7, 5.4), ("go1", "hopturn"): (2.1, 6.4),
                  ("a1", "hopturn"): (1.6, 8.2)}


def _clip():  # noqa: ANN202
    from engine.retarget.quadruped.tmr.kinematic_clips import trot
    from engine.robot.model import load_robot

    return trot(load_robot("go1"), duration_s=CLIP_DURATION_S, settle_s=0.2)


def _row(stage: str, wall_s: float | None, res=None, note: str = "", **extra) -> dict:  # noqa: ANN001
    s = res.summary if res is not None else {}
    return {"section": "tmr", "stage": stage, "clip": f"go1 trot {CLIP_DURATION_S:g} s",
            "wall_time_s": None if wall_s is None else round(wall_s, 2), "evaluations": s.get("bo_evaluations", ""),
            "tracking_error_mm": s.get("tracking_error_mm", ""), "fell": s.get("replay_fell", ""),
            "speedup_vs_1_worker": extra.get("speedup_vs_1_worker", ""),
            "speedup_vs_in_process": extra.get("speedup_vs_in_process", ""), "note": note}


def bench_tmr() -> list[dict]:
    from engine.ray_cluster import RayClusterError
    from engine.retarget.quadruped.tmr.ray_jobs import RayExecutor
    from engine.retarget.quadruped.tmr.tmr import TMRSettings, evaluate_alpha, temporal_retarget

    motion = _clip()
    # the same RAY_BUDGET evaluations in every row (no widened search: the rows compare how they are run)
    settings = TMRSettings(budget=RAY_BUDGET, init_points=RAY_BUDGET, widen_budget=0)
    rows = []
    t0 = time.perf_counter()
    ev = evaluate_alpha("go1", motion.qpos, motion.contact, motion.fps, np.zeros(1), settings)
    rows.append({**_row("inner solve (iLQR, α = 1)", time.perf_counter() - t0),
                 "evaluations": 1, "tracking_error_mm": round(ev.tracking_error_mm, 2), "fell": ev.fell})
    t0 = time.perf_counter()
    res = temporal_retarget(motion, settings)
    serial = time.perf_counter() - t0
    rows.append(_row(f"whole TMR (budget {RAY_BUDGET}, in process)", serial, res))
    import ray

    times = {}
    for workers in (1, 2):
        if ray.is_initialized():
            ray.shutdown()
        try:
            ex = RayExecutor(num_cpus=workers)
        except RayClusterError as exc:
            note = f"{exc}: the evaluations ran one at a time in this process (row above); no Ray speed-up measured"
            print(f"bench tmr: {note}", file=sys.stderr, flush=True)
            rows.append(_row(f"whole TMR on Ray, {workers} worker(s)", None, note=note))
            break
        try:
            ex.collect([ex.submit(_warm)])  # worker start-up is not the job's cost
            par = TMRSettings(budget=RAY_BUDGET, init_points=RAY_BUDGET, parallel=workers, widen_budget=0)
            t0 = time.perf_counter()
            res = temporal_retarget(motion, par, executor=ex)
            times[workers] = time.perf_counter() - t0
        finally:
            ex.shutdown()
        rows.append(_row(f"whole TMR on Ray, {workers} worker(s)", times[workers], res,
                         speedup_vs_1_worker=round(times[1] / times[workers], 2),
                         speedup_vs_in_process=round(serial / times[workers], 2)))
    return rows


def _warm() -> int:
    from engine.robot.model import load_robot

    load_robot("go1")
    return 0
