"""``studio bench tmr``: wall time of TMR's stages on this machine and Ray's speed-up, measured side by side.

Rows: one inner solve (iLQR tracking of a 1 s go1 trot at α = 1, receding horizon), the whole TMR of that clip
(budget 3), and four BO evaluations on Ray with 1 and with 2 workers (speed-up = ratio).
"""

from __future__ import annotations

import time

import numpy as np

CLIP_DURATION_S = 1.0
BUDGET = 3
RAY_BUDGET = 4  # two batches of two on 2 workers


def _clip():  # noqa: ANN202
    from engine.retarget.quadruped.tmr.kinematic_clips import trot
    from engine.robot.model import load_robot

    return trot(load_robot("go1"), duration_s=CLIP_DURATION_S, settle_s=0.2)


def bench_tmr() -> list[dict]:
    from engine.retarget.quadruped.tmr.ray_jobs import RayAddressError, RayExecutor
    from engine.retarget.quadruped.tmr.tmr import TMRSettings, evaluate_alpha, temporal_retarget

    motion = _clip()
    settings = TMRSettings(budget=BUDGET, init_points=BUDGET)
    rows = []
    t0 = time.perf_counter()
    ev = evaluate_alpha("go1", motion.qpos, motion.contact, motion.fps, np.zeros(1), settings)
    rows.append({"section": "tmr", "stage": "inner solve (iLQR, α = 1)", "clip": f"go1 trot {CLIP_DURATION_S:g} s",
                 "wall_time_s": round(time.perf_counter() - t0, 2), "evaluations": 1,
                 "tracking_error_mm": round(ev.tracking_error_mm, 2), "fell": ev.fell})
    t0 = time.perf_counter()
    res = temporal_retarget(motion, settings)
    rows.append({"section": "tmr", "stage": f"whole TMR (budget {BUDGET}, in process)", "clip": f"go1 trot {CLIP_DURATION_S:g} s",
                 "wall_time_s": round(time.perf_counter() - t0, 2), "evaluations": res.summary["bo_evaluations"],
                 "tracking_error_mm": res.summary["tracking_error_mm"], "fell": res.summary["replay_fell"]})
    import ray

    times = {}
    for workers in (1, 2):
        if ray.is_initialized():
            ray.shutdown()
        try:
            ex = RayExecutor(num_cpus=workers)
        except RayAddressError as exc:  # a machine too loaded for Ray's fixed start-up timeouts
            rows.append({"section": "tmr", "stage": f"whole TMR on Ray, {workers} worker(s)", "clip": str(exc)})
            break
        ex.collect([ex.submit(_warm)])  # worker start-up is not the job's cost
        par = TMRSettings(budget=RAY_BUDGET, init_points=RAY_BUDGET, parallel=workers)
        t0 = time.perf_counter()
        res = temporal_retarget(motion, par, executor=ex)
        times[workers] = time.perf_counter() - t0
        rows.append({"section": "tmr", "stage": f"whole TMR on Ray, {workers} worker(s)", "clip": f"go1 trot {CLIP_DURATION_S:g} s",
                     "wall_time_s": round(times[workers], 2), "evaluations": res.summary["bo_evaluations"],
                     "tracking_error_mm": res.summary["tracking_error_mm"], "fell": res.summary["replay_fell"],
                     "speedup_vs_1_worker": round(times[1] / times[workers], 2)})
        ex.shutdown()
    return rows


def _warm() -> int:
    from engine.robot.model import load_robot

    load_robot("go1")
    return 0
