"""``studio bench tmr`` and ``studio bench tmr-clips``: the temporal stage of STMR on this machine.

``tmr`` — wall time of TMR's stages and Ray's speed-up, measured side by side in one run: one inner solve (iLQR
tracking of a 1 s go1 trot at α = 1, receding horizon), then the same TMR (four BO evaluations, the same warm
start) in this process, on a local Ray with 1 worker and with 2 workers; the speed-up is the ratio of the wall
times. A local Ray that does not start (a loaded machine can miss raylet's start-up window) is one row saying
so; the in-process row is then the serial figure.

``tmr-clips`` (minutes per clip; only when asked for; ``--robot go1|a1|anymal_c`` for one robot) — the paper's
six clips (§VIII-C, Table II/Fig. 6) × go1, a1 and anymal_c: UVM's and SMR's motions tracked as they are (α = 1) and STMR (SMR + TMR), each judged the same way: open-loop replay
falls or not, DTW-normalised keypoint L1 (%) against SMR's motion at its frames (the same measure for both;
STMR's against its own re-timed target too), tracking error (mm) against the motion each tracked, plus α and
the durations, and the wall time of each stage; the CPU time of this process for the inner solve at α = 1 and the
whole TMR (the evaluations' own when they run in process) and their ratio — wall times on a shared machine are
inflated by its load, CPU times much less; ``bo_trace`` lists BO's evaluations in order: α, ✓ (stood) or ↓ and
the fall time (s), and the evaluation's wall time.
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
    from engine.retarget.quadruped.tmr.ray_jobs import RayAddressError, RayExecutor
    from engine.retarget.quadruped.tmr.tmr import TMRSettings, evaluate_alpha, temporal_retarget

    motion = _clip()
    settings = TMRSettings(budget=RAY_BUDGET, init_points=RAY_BUDGET)
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
        except RayAddressError as exc:
            note = f"{exc}: the evaluations ran one at a time in this process (row above); no Ray speed-up measured"
            print(f"bench tmr: {note}", file=sys.stderr, flush=True)
            rows.append(_row(f"whole TMR on Ray, {workers} worker(s)", None, note=note))
            break
        try:
            ex.collect([ex.submit(_warm)])  # worker start-up is not the job's cost
            par = TMRSettings(budget=RAY_BUDGET, init_points=RAY_BUDGET, parallel=workers)
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


def check_clip_options(clip_names: str | None, bo_budget: int | None) -> str | None:
    """The one-line complaint about ``--clips`` / ``--budget``, or None."""
    if clip_names is not None:
        names = [c.strip() for c in clip_names.split(",") if c.strip()]
        unknown = [c for c in names if c not in CLIPS] or ([] if names else [clip_names])
        if unknown:
            return f"--clips: unknown clip {unknown[0]!r}; expected some of {', '.join(CLIPS)}"
    if bo_budget is not None and bo_budget < 1:
        return f"--budget: expected ≥ 1 BO evaluations, got {bo_budget}"
    return None


def bench_tmr_clips(clips: tuple[str, ...] = CLIPS, robots: tuple[str, ...] = CLIP_ROBOTS, budget: int = CLIP_BUDGET,
                    address: str | None = None, parallel: int = 1, robot: str | None = None,
                    clip_names: str | None = None, bo_budget: int | None = None) -> list[dict]:
    """SMR (tracked at α = 1) against STMR on the paper's clips; see the module docstring. ``robot`` (the
    bench's ``--robot``) picks one of ``CLIP_ROBOTS``; any other value (the bench's default g1) keeps them all.
    ``clip_names`` (``--clips a,b``) picks clips among ``CLIPS``, ``bo_budget`` (``--budget``) the BO budget."""
    if robot in CLIP_ROBOTS:
        robots = (robot,)
    problem = check_clip_options(clip_names, bo_budget)
    if problem:
        raise ValueError(problem)
    if clip_names:
        clips = tuple(c.strip() for c in clip_names.split(",") if c.strip())
    if bo_budget is not None:
        budget = bo_budget
    from engine.bench.retarget import clip_path, shared_dir
    from engine.retarget.importers import import_source
    from engine.retarget.quadruped.pipeline import retarget_detailed
    from engine.retarget.quadruped.tmr.ray_jobs import LocalExecutor, RayAddressError, RayExecutor
    from engine.retarget.quadruped.tmr.tmr import TMRSettings, temporal_retarget, track_motion

    shared = shared_dir()
    if shared is None:
        return [{"section": "tmr-clips", "note": "shared data folder absent: set MOTION_STUDIO_SHARED"}]
    executor: LocalExecutor | RayExecutor = LocalExecutor()
    if address is not None or parallel > 1:
        try:
            executor = RayExecutor(address=address)
        except RayAddressError as exc:
            print(f"bench tmr-clips: {exc}; running the evaluations one at a time in this process", file=sys.stderr)
            parallel = 1
    settings = TMRSettings(budget=budget, init_points=min(3, budget), parallel=parallel)
    rows = []
    for robot in robots:
        for clip in clips:
            src = import_source(clip_path(shared, clip))
            t0 = time.perf_counter()
            smr = retarget_detailed(src, robot, "smr").motion
            t_smr = time.perf_counter() - t0
            c0 = time.process_time()
            tracked = track_motion(smr, settings)  # one inner solve at α = 1: SMR's motion as it is
            cpu_inner = time.process_time() - c0
            uvm = track_motion(retarget_detailed(src, robot, "uvm").motion, settings)  # UVM's, the same way
            t0, c0 = time.perf_counter(), time.process_time()
            res = temporal_retarget(smr, settings, executor=executor)
            t_tmr, cpu_tmr = time.perf_counter() - t0, time.process_time() - c0
            s = res.summary
            paper = PAPER_TABLE_II.get((robot, clip), ("", ""))
            rows.append({
                "section": "tmr-clips", "robot": robot, "clip": clip, "duration_s": s["duration_s"]["before"],
                "uvm_fell": uvm["replay_fell"], "uvm_dtw_pct": uvm["dtw_keypoint_l1_pct"],
                "uvm_track_mm": uvm["tracking_error_mm"],
                "smr_fell": tracked["replay_fell"], "smr_dtw_pct": tracked["dtw_keypoint_l1_pct"],
                "smr_track_mm": tracked["tracking_error_mm"],
                "stmr_alpha": ",".join(f"{a:.3f}" for a in s["alpha"]), "stmr_after_s": s["duration_s"]["after"],
                "stmr_fell": s["replay_fell"], "stmr_fell_at_s": s["replay_fell_at_s"],
                "stmr_dtw_pct": s["dtw_keypoint_l1_pct"], "stmr_dtw_vs_target_pct": s["dtw_vs_target_pct"], "stmr_track_mm": s["tracking_error_mm"],
                "evals": s["bo_evaluations"], "smr_s": round(t_smr, 2), "inner_solve_s": tracked["wall_time_s"],
                "tmr_s": round(t_tmr, 1),
                # CPU time of this process (the evaluations' own when they run in process, not on Ray workers)
                "inner_solve_cpu_s": round(cpu_inner, 1), "tmr_cpu_s": round(cpu_tmr, 1),
                "tmr_vs_inner_solve_cpu": round(cpu_tmr / cpu_inner, 2) if cpu_inner > 0 else None,
                "bo_trace": " ".join(f"{e['alpha'][0] if len(e['alpha']) == 1 else e['alpha']}"
                                     f"{'↓' + str(e['fell_at_s']) if e['replay_fell'] else '✓'}({e['wall_time_s']:g}s)"
                                     for e in res.evaluations),
                "paper_stmr_dtw_pct": paper[0], "paper_smr_dtw_pct": paper[1],
            })
            print(f"bench tmr-clips: {rows[-1]}", file=sys.stderr, flush=True)
    if isinstance(executor, RayExecutor):
        executor.shutdown()
    return rows
