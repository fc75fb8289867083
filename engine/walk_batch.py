"""Many closed-loop walks on Ray: each job is one ``run_walk`` keyed by a content hash.

A job is plain JSON (robot name, style as a dict, command spec, duration, pushes, and what to
measure afterwards), so it travels to any Ray worker and names its result file:
``<out_dir>/<key>.json`` is written atomically when the job ends, and a batch started again
with the same output folder skips every job whose result is there (resumable, cancellable:
Ctrl+C cancels the running tasks and keeps what finished) unless another version of the code
made it (``code_version()``: after a controller change the jobs run again). Ray runs locally by default
(``address=None``) or joins a cluster (``"host:6379"``, ``"ray://host:10001"`` or ``"auto"``): :mod:`engine.ray_cluster`.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from engine.atomic_io import atomic_write_text
from engine.ray_cluster import RayClusterError, connect_ray

REPO_ROOT = Path(__file__).resolve().parent.parent


_CODE_VERSION: str | None = None


def code_version() -> str:
    """A hash of what a walk runs (engine/**/*.py, robots/*.toml): a result stored under another
    version is stale (the controller changed since) and its job runs again."""
    global _CODE_VERSION
    if _CODE_VERSION is None:
        h = hashlib.sha256()
        for path in sorted([*(REPO_ROOT / "engine").rglob("*.py"), *(REPO_ROOT / "robots").glob("*.toml")]):
            h.update(str(path.relative_to(REPO_ROOT)).encode("utf-8"))
            h.update(path.read_bytes())
        _CODE_VERSION = h.hexdigest()[:16]
    return _CODE_VERSION


def job_key(job: dict[str, Any]) -> str:
    """A stable short hash of the job's content (style, command, pushes, duration, robot)."""
    text = json.dumps(job, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def window_velocity(rec: dict[str, np.ndarray], t0: float, t1: float) -> np.ndarray | None:
    """Mean horizontal CoM velocity over [t0, t1] (world), from the recorded CoM (None: out of range)."""
    t = rec["t"]
    if len(t) == 0 or t[-1] < t1 - 1e-6:
        return None
    i0, i1 = int(np.searchsorted(t, t0)), min(int(np.searchsorted(t, t1)), len(t) - 1)
    if i1 <= i0:
        return None
    return (rec["com"][i1, :2] - rec["com"][i0, :2]) / (t[i1] - t[i0])


def com_at(rec: dict[str, np.ndarray], t_s: float) -> np.ndarray:
    i = min(int(np.searchsorted(rec["t"], t_s)), len(rec["t"]) - 1)
    return rec["com"][i, :2].copy()


def tracking_errors(rec: dict[str, np.ndarray], ref: dict[str, np.ndarray] | None) -> dict[str, float]:
    """RMS tracking errors of the paper's Fig. 14 quantities, from the recording."""
    out: dict[str, float] = {}
    for key in ("pelvis_height", "pelvis_yaw", "elbow"):
        a, r = rec.get(f"{key}_achieved"), rec.get(f"{key}_ref")
        if a is not None and r is not None and len(a):
            d = a - r
            if key == "pelvis_yaw":
                d = np.remainder(d + math.pi, 2 * math.pi) - math.pi
            out[f"{key}_rms"] = float(np.sqrt(np.mean(d ** 2)))
    return out


def run_job(job: dict[str, Any]) -> dict[str, Any]:
    """One closed-loop walk (in this process). Never raises: a crash is reported in the result."""
    from engine.gait.command_schedule import parse_command
    from engine.gait.style import StyleContext, style_from_dict
    from engine.robot.model import load_robot
    from engine.walk_runner import PushSpec, run_walk

    t_wall = time.perf_counter()
    try:
        robot = load_robot(job["robot"])
        style = style_from_dict(job["style"], StyleContext.for_robot(robot.name), expected_robot=robot.name)
        schedule = parse_command(job["command"], style.velocities)
        pushes = [PushSpec(float(p[0]), (float(p[1]), float(p[2]), float(p[3])), float(p[4])) for p in job.get("pushes", [])]
        summary, rec = run_walk(robot, style, schedule, float(job["duration_s"]), pushes,
                                record=True)
    except Exception as exc:  # noqa: BLE001 - one broken job must not end the batch
        return {"error": f"{type(exc).__name__}: {exc}", "wall_s": time.perf_counter() - t_wall}
    result: dict[str, Any] = {k: summary[k] for k in ("fell", "fall_time_s", "max_stance_slip_mm",
                                                      "cop_inside_fraction", "distance_m", "sim_time_s",
                                                      "recovery_time_s", "recovery_mean_share")}
    result["wall_s"] = round(time.perf_counter() - t_wall, 2)
    result.update(tracking_errors(rec, None))
    if summary["fell"]:  # the fall's anatomy, as the rehearsal tells it (engine/gait/rehearsal.py)
        from engine.gait.rehearsal import describe

        verdict = describe(summary, rec, float(job["duration_s"]))
        result.update({"fall_sample": verdict.sample, "fall_phase_pct": verdict.phase_pct,
                       "fall_onset_s": verdict.onset_time_s, "fall_onset": verdict.onset_kind})
    for name, (t0, t1) in job.get("velocity_windows", {}).items():
        v = window_velocity(rec, t0, t1)
        result[f"velocity_{name}"] = None if v is None else [round(float(x), 4) for x in v]
    for name, (ta, tb) in job.get("displacements", {}).items():
        if len(rec["t"]) and rec["t"][-1] >= tb - 1e-6:
            result[f"displacement_{name}"] = round(float(np.linalg.norm(com_at(rec, tb) - com_at(rec, ta))), 4)
        else:
            result[f"displacement_{name}"] = None
    return result


def run_batch(jobs: Iterable[dict[str, Any]], out_dir: str | os.PathLike, address: str | None = None,
              progress: Callable[[int, int, str, dict[str, Any]], None] | None = None,
              local: bool = False) -> dict[str, dict[str, Any]]:
    """Run every job whose result is not in ``out_dir`` yet; return {key: result} for all jobs.

    ``local=True`` runs in this process, one after the other (tests, debugging); otherwise on Ray.
    ``progress(done, total, key, result)`` is called as each job ends.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    jobs = list(jobs)
    keyed = {job_key(j): j for j in jobs}
    results: dict[str, dict[str, Any]] = {}
    todo = []
    for key, job in keyed.items():
        path = out / f"{key}.json"
        if path.exists():
            try:
                stored = json.loads(path.read_text())
                if stored.get("code") == code_version():  # else made by other code: run it again
                    results[key] = stored["result"]
                    continue
            except (ValueError, KeyError, AttributeError):
                pass  # a damaged result: run the job again
        todo.append(key)
    done, total = len(results), len(keyed)

    def finish(key: str, result: dict[str, Any]) -> None:
        nonlocal done
        results[key] = result
        if "error" not in result:
            atomic_write_text(out / f"{key}.json", json.dumps({"job": keyed[key], "result": result, "code": code_version()},
                                                               indent=1))
        done += 1
        if progress:
            progress(done, total, key, result)

    if local:
        for key in todo:
            finish(key, run_job(keyed[key]))
        return results
    if not todo:
        return results
    try:
        # Ray lowers its workers' priority (niceness 15) by default: on a shared machine they would then wait
        # behind everything else.
        ray = connect_ray(address, worker_niceness=0)
    except RayClusterError as exc:  # e.g. a raylet too slow to start on a loaded machine
        if address:
            raise
        print(f"{exc}; running the jobs in this process", file=sys.stderr)
        for key in todo:
            finish(key, run_job(keyed[key]))
        return results
    remote = ray.remote(num_cpus=1, max_retries=0)(run_job)
    pending = {remote.remote(keyed[k]): k for k in todo}
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                key = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a worker died: report, keep going
                    result = {"error": f"{type(exc).__name__}: {exc}"}
                finish(key, result)
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref, force=True)
        print(f"cancelled: {done}/{total} done, results kept in {out}", file=sys.stderr)
        raise
    return results


def print_progress(done: int, total: int, key: str, result: dict[str, Any]) -> None:
    state = "error" if "error" in result else ("FELL" if result.get("fell") else "ok")
    print(f"  [{done}/{total}] {key} {state}", file=sys.stderr, flush=True)
