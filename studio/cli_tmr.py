"""``studio tmr`` and ``studio retarget-batch``: the temporal stage of STMR from the command line.

``studio tmr --motion F.npz [--robot R] --out G.npz`` re-times a kinematic robot motion (SMR output, a
keyframed clip) and finds the torques that make the robot do it in MuJoCo. ``studio retarget-batch`` runs
clips × robots on Ray, resumable: a finished job's file is keyed by a content hash and skipped next time.
Bad input is one line and exit 2; nothing is written unless a job finishes (atomic writes).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np

from studio.cli import CliError, check_ray_address

GENERATED_CLIPS = ("standing", "trot", "hop")


def register(sub: argparse._SubParsersAction) -> None:
    tmr = sub.add_parser("tmr", help="temporal retargeting (STMR TMR): re-time a kinematic motion and track it in MuJoCo")
    tmr.add_argument("--motion", required=True, help="kinematic robot motion (.npz, robot-motion/1)")
    tmr.add_argument("--robot", default=None, help="target robot (default: the motion's robot; must match it)")
    add_tmr_options(tmr)
    tmr.add_argument("--out", required=True, help="output dynamic motion (.npz)")
    tmr.add_argument("--json", action="store_true", help="print the summary as JSON")

    batch = sub.add_parser("retarget-batch", help="run TMR for clips × robots on Ray (resumable)")
    batch.add_argument("clips", nargs="+", help="robot motions (.npz), source motions (keypoint npz or any importable "
                       "file: SMR to each robot first) or generated clips gen:standing|gen:trot|gen:hop")
    batch.add_argument("--robots", default=None, help="comma-separated robots (default: each file's own robot)")
    batch.add_argument("--method", default="stmr", choices=("stmr",), help="retargeting method (TMR on the clip)")
    add_tmr_options(batch)
    batch.add_argument("--jobs", type=int, default=None,
                       help="clips running at once (default: Ray's CPUs; 1 without --address runs in this process)")
    batch.add_argument("--out", required=True, help="output folder")
    batch.add_argument("--json", action="store_true", help="print the summary as JSON")


def add_tmr_options(p: argparse.ArgumentParser, prefix: str = "") -> None:
    """The TMR options (``studio tmr``, ``studio retarget-batch``, ``studio retarget --method stmr``)."""
    p.add_argument("--segments", type=int, default=1, help=prefix + "S, the number of equal time segments (default 1)")
    p.add_argument("--alpha-bound", type=float, default=1.0, help=prefix + "B: log2 α ∈ [−B, B], 0 < B ≤ 2 (default 1)")
    p.add_argument("--widen-bound", type=float, default=1.6, help=prefix + "when every α within ±B falls, BO goes "
                   "on over log2 α ∈ [−W, W] (W ≤ 2) for --widen-budget more evaluations (default 1.6; 0: never)")
    p.add_argument("--widen-budget", type=int, default=2, help=prefix + "evaluations of the widened search (default 2)")
    p.add_argument("--budget", type=int, default=8, help=prefix + "Bayesian-optimisation evaluations at most (default 8)")
    p.add_argument("--parallel", type=int, default=1, help=prefix + "BO evaluations in flight on Ray (default 1: in "
                   "process; more starts a local Ray unless --address)")
    p.add_argument("--address", default=None, help=prefix + "Ray cluster address (default: a local Ray when one is needed)")
    p.add_argument("--mode", choices=("receding", "full"), default="receding", help=prefix + "iLQR horizon (default receding)")
    p.add_argument("--window", type=float, default=0.25, help=prefix + "receding-horizon window in seconds (default "
                   "0.25; flips need the whole flight, e.g. 0.6). The tracker also solves a 0.4 s window and keeps "
                   "the standing answer of least cost, and tries 0.5 s, then this window with the terminal weight 5 instead "
                   "of 20, while every answer falls (TMRSettings)")
    p.add_argument("--seed", type=int, default=0, help=prefix + "seed of the BO warm start")


def _settings(args: argparse.Namespace):  # noqa: ANN202
    from engine.retarget.quadruped.tmr.deformation import DeformationError, check_log2_bound
    from engine.retarget.quadruped.tmr.tmr import TMRSettings

    try:
        check_log2_bound(args.alpha_bound)
    except DeformationError as exc:
        raise CliError(f"--alpha-bound: {exc}") from None
    if args.widen_bound != 0:
        try:
            check_log2_bound(args.widen_bound)
        except DeformationError as exc:
            raise CliError(f"--widen-bound: {exc} (or 0: never widen)") from None
        if args.widen_bound <= args.alpha_bound:
            raise CliError(f"--widen-bound: expected a bound above --alpha-bound {args.alpha_bound:g} (or 0: never "
                           f"widen), got {args.widen_bound:g}")
    if not 0 <= args.widen_budget <= 1000:
        raise CliError(f"--widen-budget: expected 0..1000 evaluations, got {args.widen_budget}")
    if args.segments < 1:
        raise CliError(f"--segments: expected S ≥ 1, got {args.segments}")
    if not 1 <= args.budget <= 1000:
        raise CliError(f"--budget: expected 1..1000 evaluations, got {args.budget}")
    if not 1 <= args.parallel <= 256:
        raise CliError(f"--parallel: expected 1..256, got {args.parallel}")
    if not 0.02 <= args.window <= 5.0:
        raise CliError(f"--window: expected 0.02..5 s, got {args.window}")
    return TMRSettings(segments=args.segments, log2_bound=args.alpha_bound, budget=args.budget,
                       init_points=min(3, args.budget), parallel=args.parallel, mode=args.mode, seed=args.seed,
                       window_s=args.window, widen_log2_bound=args.widen_bound if args.widen_budget > 0 else 0.0,
                       widen_budget=args.widen_budget if args.widen_bound > 0 else 0)  # (off: one job key)


def _executor(address: str | None, parallel: int):  # noqa: ANN202
    """In process for one evaluation at a time; Ray otherwise. A cluster that does not answer is a user error (exit
    2); a local Ray that fails to start (a loaded machine can miss raylet's start-up window) is one line on stderr
    and the evaluations run one after the other in this process."""
    from engine.ray_cluster import RayClusterError
    from engine.retarget.quadruped.tmr.ray_jobs import LocalExecutor, RayExecutor

    if address is None and parallel <= 1:
        return LocalExecutor()
    try:
        return RayExecutor(address=address, num_cpus=None)
    except RayClusterError as exc:
        if address is not None:
            raise CliError(str(exc)) from None
        print(f"studio: {exc}; running the evaluations one at a time in this process", file=sys.stderr, flush=True)
        return LocalExecutor()


def run_tmr(motion, settings, address: str | None, parallel: int):  # noqa: ANN001, ANN201
    """TMR of a kinematic motion with progress lines on stderr; None when interrupted (nothing written)."""
    from engine.retarget.quadruped.tmr.ddp import Cancelled
    from engine.retarget.quadruped.tmr.ray_jobs import LocalExecutor
    from engine.retarget.quadruped.tmr.tmr import temporal_retarget

    executor = _executor(address, parallel)
    if isinstance(executor, LocalExecutor):
        from dataclasses import replace

        settings = replace(settings, parallel=1)
    # Ctrl-C (SIGINT) sets a flag the search and the tracker poll, instead of a KeyboardInterrupt: one raised
    # inside a finaliser or a library's callback is printed and swallowed, and the job would then finish and
    # write its file (seen in CI: a cancelled `studio tmr` exiting 0).
    interrupted = threading.Event()
    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGINT, lambda _signum, _frame: interrupted.set())
    try:
        result = temporal_retarget(motion, settings, executor=executor, progress=_progress_line(""),
                                   cancel=interrupted.is_set)
    except (KeyboardInterrupt, Cancelled):
        result = None
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
    if result is None or interrupted.is_set():
        print("studio: cancelled; nothing written", file=sys.stderr)
        return None
    return result


def _quadruped(name: str, where: str = "--robot"):  # noqa: ANN202
    """The robot model of a quadruped; ``where`` names what gave the name (``--robot`` or ``FILE: robot``)."""
    from engine.robot.config import RobotConfigError, load_robot_config
    from engine.robot.model import load_robot

    try:
        cfg = load_robot_config(name)
    except RobotConfigError as exc:
        raise CliError(str(exc) if where == "--robot" else f"{where}: expected a known robot, {exc}") from None
    if cfg.kind != "quadruped":
        raise CliError(f"{where}: expected a quadruped (TMR retargets quadruped motions), {name} is a {cfg.kind}")
    return load_robot(name)


def _load_motion(path: str):  # noqa: ANN202
    from engine.retarget.motion import MotionFormatError, RobotMotion

    try:
        return RobotMotion.load(path)
    except MotionFormatError as exc:
        raise CliError(str(exc)) from None


def _check_motion(motion, robot, where: str, settings) -> None:  # noqa: ANN001
    from engine.retarget.motion import LEGS
    from engine.retarget.quadruped.tmr.deformation import DeformationError, check_segments
    from engine.retarget.quadruped.tmr.kinematic_clips import mujoco_joint_names

    if motion.robot != robot.name:
        raise CliError(f"{where}: robot: expected a motion of {robot.name} (spatial retargeting to another robot is "
                       f"SMR's job), got {motion.robot}")
    if tuple(motion.foot_names) != LEGS:
        raise CliError(f"{where}: foot_names: expected {', '.join(LEGS)}, got {', '.join(motion.foot_names)}")
    expected = mujoco_joint_names(robot)
    if list(motion.joint_names) != expected:
        raise CliError(f"{where}: joint_names: expected {robot.name}'s {len(expected)} joints in MuJoCo order")
    if motion.qpos.shape[1] != robot.mj_model.nq:
        raise CliError(f"{where}: qpos: expected {robot.mj_model.nq} columns for {robot.name}, got {motion.qpos.shape[1]}")
    try:
        check_segments(settings.segments, motion.frames, motion.fps)
    except DeformationError as exc:
        raise CliError(f"{where}: qpos: {exc}") from None


def _out_npz(spec: str) -> Path:
    out = Path(spec)
    if out.suffix != ".npz":
        raise CliError(f"--out: expected a .npz file, got {spec!r}")
    return out


def _progress_line(prefix: str):  # noqa: ANN202
    def show(p) -> None:  # noqa: ANN001
        alpha = ", ".join(f"{2 ** float(b):.3f}" for b in p.current_log2_alpha)
        best = ", ".join(f"{2 ** float(b):.3f}" for b in p.best_log2_alpha)
        print(f"{prefix}evaluation {p.evaluation}/{p.budget}: α = [{alpha}]  best score {p.best_score:.4f} at α = [{best}]",
              file=sys.stderr, flush=True)
    return show


def cmd_tmr(args: argparse.Namespace) -> int:
    settings = _settings(args)
    out = _out_npz(args.out)
    check_ray_address(args.address)
    motion = _load_motion(args.motion)
    robot = _quadruped(args.robot) if args.robot else _quadruped(motion.robot, f"{Path(args.motion).name}: robot")
    _check_motion(motion, robot, Path(args.motion).name, settings)
    result = run_tmr(motion, settings, args.address, args.parallel)
    if result is None:
        return 130
    result.motion.save(out)
    s = result.summary
    if args.json:
        print(json.dumps({**s, "out": str(out), "evaluations": result.evaluations}, indent=1))
    else:
        print(f"{out}: α = {s['alpha']} ({s['duration_s']['before']} s → {s['duration_s']['after']} s), "
              f"{s['bo_evaluations']} evaluations; replay {'FELL' if s['replay_fell'] else 'stays up'}; tracking "
              f"{s['tracking_error_mm']} mm, DTW keypoint L1 {s['dtw_keypoint_l1_pct']} %; {s['wall_time_s']} s")
    return 0


# ----------------------------------------------------------------------------- batch


def _batch_clip(spec: str):  # noqa: ANN202
    """A batch clip: a robot motion (npz, robot-motion/1) or a source motion (keypoint npz or any importable
    file, which each robot gets through SMR first)."""
    from engine.retarget.importers import import_source
    from engine.retarget.motion import ROBOT_FORMAT, MotionFormatError, RobotMotion

    from engine.safe_io import ReadError, read_npz

    path = Path(spec)
    if path.suffix == ".npz":
        try:  # only the format entry (safe_io: nothing else inflated)
            fmt = read_npz(path, source=path.name, only=("format",)).get("format")
        except ReadError as exc:
            raise CliError(str(exc)) from None
        if fmt is not None and fmt.ndim == 0 and str(fmt) == ROBOT_FORMAT:
            try:
                return RobotMotion.load(path)
            except MotionFormatError as exc:
                raise CliError(str(exc)) from None
    try:
        return import_source(path)
    except MotionFormatError as exc:
        raise CliError(str(exc)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CliError(f"{path.name}: cannot read ({exc.__class__.__name__})") from None


def _clip_motion(spec: str, robot):  # noqa: ANN001, ANN202
    from engine.retarget.motion import RobotMotion
    from engine.retarget.quadruped.pipeline import retarget_detailed
    from engine.retarget.quadruped.tmr import kinematic_clips

    if spec.startswith("gen:"):
        name = spec[4:]
        if name not in GENERATED_CLIPS:
            raise CliError(f"{spec}: expected gen:{'|gen:'.join(GENERATED_CLIPS)}")
        return getattr(kinematic_clips, name)(robot)
    motion = _batch_clip(spec)
    if isinstance(motion, RobotMotion):
        return motion
    return retarget_detailed(motion, robot.name, "smr").motion  # a source: SMR to this robot, then TMR


def job_key(spec: str, robot: str, settings) -> str:  # noqa: ANN001
    """Content hash of a job: the clip's bytes (or generator name), the robot, the settings, the TMR code."""
    from dataclasses import asdict

    import engine.retarget.quadruped.tmr as pkg

    h = hashlib.sha256()
    h.update(spec.encode() if spec.startswith("gen:") else Path(spec).read_bytes())
    h.update(robot.encode())
    h.update(json.dumps(asdict(settings), sort_keys=True).encode())
    for f in sorted(Path(pkg.__file__).parent.glob("*.py")):
        h.update(f.read_bytes())
    return h.hexdigest()[:12]


def run_batch_job(spec: str, robot_name: str, settings, out_path: str) -> dict:  # noqa: ANN001
    """One clip × robot (runs in a Ray worker or in process): TMR, then the npz and its summary, atomically."""
    from engine.atomic_io import atomic_write_text
    from engine.retarget.quadruped.tmr.tmr import temporal_retarget
    from engine.robot.model import load_robot

    robot = load_robot(robot_name)
    motion = _clip_motion(spec, robot)
    result = temporal_retarget(motion, settings)
    result.motion.save(out_path)
    summary = {"clip": spec, **result.summary}
    atomic_write_text(Path(out_path).with_suffix(".json"), json.dumps(summary, indent=1))
    return summary


def cmd_retarget_batch(args: argparse.Namespace) -> int:
    from engine.retarget.motion import RobotMotion
    from engine.retarget.quadruped.tmr.deformation import DeformationError, check_segments

    settings = _settings(args)
    check_ray_address(args.address)
    out_dir = Path(args.out)
    if out_dir.exists() and not out_dir.is_dir():
        raise CliError(f"--out: expected a folder, {out_dir} is a file")
    robots = [r for r in (args.robots or "").split(",") if r]
    for r in robots:
        _quadruped(r)
    jobs: list[tuple[str, str]] = []  # (clip spec, robot)
    for spec in args.clips:
        if spec.startswith("gen:"):
            if not robots:
                raise CliError(f"{spec}: a generated clip needs --robots")
            if spec[4:] not in GENERATED_CLIPS:
                raise CliError(f"{spec}: expected gen:{'|gen:'.join(GENERATED_CLIPS)}")
            jobs.extend((spec, r) for r in robots)
            continue
        motion = _batch_clip(spec)
        if not isinstance(motion, RobotMotion):  # a source motion: SMR to each robot first
            if not robots:
                raise CliError(f"{Path(spec).name}: a source motion needs --robots")
            try:
                check_segments(settings.segments, motion.frames, motion.fps)
            except DeformationError as exc:
                raise CliError(f"{Path(spec).name}: keypoints: {exc}") from None
            jobs.extend((spec, r) for r in robots)
            continue
        targets = robots or [motion.robot]
        for r in targets:
            model = _quadruped(r) if robots else _quadruped(r, f"{Path(spec).name}: robot")
            _check_motion(motion, model, Path(spec).name, settings)
            jobs.append((spec, r))
    if args.jobs is not None and args.jobs < 1:
        raise CliError(f"--jobs: expected ≥ 1, got {args.jobs}")
    out_dir.mkdir(parents=True, exist_ok=True)
    plan = []
    for spec, r in jobs:
        stem = spec[4:] if spec.startswith("gen:") else Path(spec).stem
        path = out_dir / f"{stem}__{r}__{job_key(spec, r, settings)}.npz"
        plan.append((spec, r, path))
    summaries: dict[Path, dict] = {}
    todo = []
    for spec, r, path in plan:
        done_json = path.with_suffix(".json")
        if path.is_file() and done_json.is_file():
            summaries[path] = {**json.loads(done_json.read_text()), "status": "skipped (done)"}
        else:
            todo.append((spec, r, path))
    t0 = time.perf_counter()
    total = len(plan)
    _bar(len(summaries), total, t0)
    if todo:
        from engine.ray_cluster import RayClusterError
        from engine.retarget.quadruped.tmr.ray_jobs import LocalExecutor, RayExecutor

        executor: LocalExecutor | RayExecutor
        if args.address is None and args.jobs == 1:
            executor = LocalExecutor()  # one job at a time needs no Ray
        else:
            try:
                executor = RayExecutor(address=args.address, num_cpus=args.jobs)
            except RayClusterError as exc:
                raise CliError(str(exc)) from None
        limit = args.jobs or executor.workers
        pending = list(todo)
        running: dict = {}
        try:
            while pending or running:
                while pending and len(running) < limit:
                    spec, r, path = pending.pop(0)
                    running[executor.submit(run_batch_job, spec, r, settings, str(path))] = path
                for handle, summary in executor.collect(list(running)):
                    path = running.pop(handle)
                    summaries[path] = {**summary, "status": "done"}
                    _bar(len(summaries), total, t0)
        except KeyboardInterrupt:
            executor.cancel(list(running))
            print(f"\nstudio: cancelled; {len(summaries)} of {total} jobs finished (they are kept; run again to resume)",
                  file=sys.stderr)
            return 130
    print(file=sys.stderr)
    rows = [summaries[p] | {"file": p.name} for _, _, p in plan]
    if args.json:
        print(json.dumps({"jobs": rows, "wall_time_s": round(time.perf_counter() - t0, 2)}, indent=1))
    else:
        _table(rows)
    return 0


def _bar(done: int, total: int, t0: float) -> None:
    width = 30
    fill = int(width * done / max(total, 1))
    print(f"\r[{'#' * fill}{'.' * (width - fill)}] {done}/{total} jobs  {time.perf_counter() - t0:6.1f} s", end="",
          file=sys.stderr, flush=True)


def _table(rows: list[dict]) -> None:
    keys = ("clip", "robot", "alpha", "before_s", "after_s", "fell", "track_mm", "dtw_pct", "evals", "status")
    cells = []
    for r in rows:
        cells.append([str(r.get("clip", "")), str(r.get("robot", "")), ",".join(f"{a:.3f}" for a in r.get("alpha", [])),
                      str(r.get("duration_s", {}).get("before", "")), str(r.get("duration_s", {}).get("after", "")),
                      str(r.get("replay_fell", "")), str(r.get("tracking_error_mm", "")),
                      str(r.get("dtw_keypoint_l1_pct", "")), str(r.get("bo_evaluations", "")), str(r.get("status", ""))])
    widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]
    print("  ".join(k.ljust(w) for k, w in zip(keys, widths)))
    for c in cells:
        print("  ".join(v.ljust(w) for v, w in zip(c, widths)))
