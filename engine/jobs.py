"""Long jobs in the engine process: retargeting, import, export, playback poses.

``StartJob(job, params, job_id)`` starts one on a worker thread; it reports ``JobProgress(fraction, message)``
and ends with one ``JobProgress`` whose ``result`` is ``{"ok": True, ...}`` or ``{"ok": False, "error": ...,
"cancelled": bool}``. ``CancelJob(job_id)`` sets the job's cancel event; a cancelled job writes nothing (every file
is written atomically, and only once the job has succeeded). The engine's simulation loop keeps running: workers
never touch the simulation, and their events go through a queue that the loop drains (:meth:`JobRunner.drain`),
so only the loop's thread writes to the pipe.

Jobs (all paths relative to the motion library, :mod:`engine.motion_files`):

* ``retarget``  {source: "source/x.npz" | "demo:trot", robot, method: uvm|smr|stmr, baseless, terrain: [box:…],
  name, uvm_ghost, budget, segments} → writes ``<robot>/<name>.npz`` (and the kinematic comparison beside it:
  ``<robot>/<name>.uvm.npz`` for smr, ``<robot>/<name>.smr.npz`` — the motion TMR started from — for stmr)
  → {path, metrics, playback}
* ``import``    {root: "shared"|"motions", path, name} → writes ``source/<name>.npz`` → {path, frames, fps}
* ``export``    {motion, format: amp-json|unitree-csv|beyondmimic-npz|npz, amp_full, fps?, take?: simulated|reference}
  → writes ``exports/<stem>.<ext>`` → {path, frames, fps}
* ``poses``     {motion, source?, ghost?} → {playback} (nothing written)

``playback`` holds what a viewer needs to show a motion without any kinematics of its own: the robot's body poses
per frame (forward kinematics here, in MuJoCo), the source keypoints and contacts, the result's contacts, and for
a re-timed (TMR) result its α segments and, per frame, the source frame and the kinematic ghost at the same point
of the motion (s_α(t), :func:`retiming`).
"""

from __future__ import annotations

import queue
import threading
import time
import traceback
from types import SimpleNamespace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from engine import protocol as msg
from engine.retarget.motion import LEGS
from engine.motion_files import (
    EXPORTS_DIR, SOURCE_DIR, check_name, confined, motions_root, shared_root,
)

JOBS = ("retarget", "import", "export", "poses")
DEMO_SOURCES = {"demo:trot": "synthetic trot (a1 proportions, 2 s, 30 fps)"}
EXPORT_SUFFIX = {"amp-json": ".json", "unitree-csv": ".csv", "beyondmimic-npz": ".npz", "npz": ".npz"}
PROGRESS_PERIOD_S = 0.1  # at most ten progress events a second per job


class JobCancelled(Exception):
    pass


class JobError(ValueError):
    """A user-facing failure: one line naming the file or parameter and what was expected."""


class JobRunner:
    """Runs jobs on worker threads; their events wait in a queue for the engine loop (thread-safe)."""

    def __init__(self, root: Path | None = None):
        self.root = Path(root) if root is not None else motions_root()
        self._events: queue.Queue[msg.JobProgress] = queue.Queue()
        self._cancel: dict[str, threading.Event] = {}
        self._threads: dict[str, threading.Thread] = {}
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ control (engine loop thread)
    def start(self, job: str, params: dict[str, Any], job_id: str = "") -> None:
        job_id = job_id or f"{job}-{time.monotonic_ns()}"
        if job not in JOBS:
            self._events.put(msg.JobProgress(job, 1.0, "failed", {"ok": False, "cancelled": False,
                             "error": f"job: expected one of {', '.join(JOBS)}, got {job!r}"}, job_id=job_id))
            return
        cancel = threading.Event()
        thread = threading.Thread(target=self._run, args=(job, dict(params), job_id, cancel),
                                  name=f"job-{job_id}", daemon=True)
        with self._lock:
            self._cancel[job_id] = cancel
            self._threads[job_id] = thread
        thread.start()

    def cancel(self, job_id: str) -> bool:
        with self._lock:
            event = self._cancel.get(job_id)
        if event is not None:
            event.set()
        return event is not None

    def drain(self) -> list[msg.JobProgress]:
        out = []
        while True:
            try:
                out.append(self._events.get_nowait())
            except queue.Empty:
                return out

    def busy(self) -> bool:
        with self._lock:
            return any(t.is_alive() for t in self._threads.values())

    def join(self, timeout_s: float = 60.0) -> None:
        deadline = time.monotonic() + timeout_s
        for thread in list(self._threads.values()):
            thread.join(max(0.0, deadline - time.monotonic()))

    # ------------------------------------------------------------------ worker
    def _run(self, job: str, params: dict, job_id: str, cancel: threading.Event) -> None:
        last = [0.0]

        def report(fraction: float, message: str = "") -> None:
            if cancel.is_set():
                raise JobCancelled
            now = time.monotonic()
            if now - last[0] >= PROGRESS_PERIOD_S:
                last[0] = now
                self._events.put(msg.JobProgress(job, float(np.clip(fraction, 0.0, 0.999)), message, None,
                                                 job_id=job_id))

        report(0.0, "started")
        try:
            result = getattr(self, f"_job_{job}")(params, report, cancel)
            result["ok"] = True
            self._events.put(msg.JobProgress(job, 1.0, "done", result, job_id=job_id))
        except BaseException as exc:  # noqa: BLE001 - every failure becomes a message, the engine lives on
            from engine.retarget.quadruped.uvm import RetargetCancelled

            cancelled = isinstance(exc, (JobCancelled, RetargetCancelled)) or cancel.is_set()
            if cancelled:
                error = "cancelled: nothing written"
            elif isinstance(exc, (ValueError, OSError, KeyError)):
                error = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            else:
                error = f"{type(exc).__name__}: {exc}"
                traceback.print_exc()
            self._events.put(msg.JobProgress(job, 1.0, "cancelled" if cancelled else "failed",
                                             {"ok": False, "cancelled": cancelled, "error": error}, job_id=job_id))
        finally:
            with self._lock:
                self._cancel.pop(job_id, None)

    # ------------------------------------------------------------------ jobs
    def _load_source(self, spec: str):
        from engine.retarget.motion import KeypointMotion

        if spec in DEMO_SOURCES:
            from engine.retarget.synthetic import synthetic_trot

            motion = synthetic_trot()
            motion.source.setdefault("file", spec)
            return motion
        return KeypointMotion.load(confined(self.root, spec))

    def _job_retarget(self, params: dict, report: Callable, cancel: threading.Event) -> dict:
        from engine.retarget.heightmap import parse_terrain
        from engine.retarget.quadruped.pipeline import METHODS, QUADRUPEDS, RetargetOptions, retarget_detailed

        robot = str(params.get("robot", ""))
        if robot not in QUADRUPEDS:
            raise JobError(f"robot: expected a quadruped ({', '.join(QUADRUPEDS)}), got {robot!r}")
        method = str(params.get("method", "smr"))
        if method not in (*METHODS, "stmr"):
            raise JobError(f"method: expected one of {', '.join((*METHODS, 'stmr'))}, got {method!r}")
        source_spec = str(params.get("source", ""))
        source = self._load_source(source_spec)
        name = check_name(str(params.get("name") or f"{Path(source_spec.split(':')[-1]).stem}_{method}"))
        options = RetargetOptions(baseless=bool(params.get("baseless", False)),
                                  heightmap=parse_terrain(list(params.get("terrain") or [])))
        if method == "stmr":
            return self._stmr(source, source_spec, robot, name, options, params, report, cancel)
        ghost = bool(params.get("uvm_ghost", True)) and method != "uvm"
        span = 0.8 if ghost else 1.0
        output = retarget_detailed(source, robot, method, options,
                                   progress=lambda f: report(span * f, f"{method.upper()}: frame "
                                                             f"{int(f * source.frames)} of {source.frames}"),
                                   cancel=cancel)
        uvm = None
        if ghost:
            uvm = retarget_detailed(source, robot, "uvm", options,
                                    progress=lambda f: report(span + (1 - span) * f, "UVM comparison"),
                                    cancel=cancel).motion
        report(0.999, "writing")
        if cancel.is_set():
            raise JobCancelled
        out = confined(self.root, f"{robot}/{name}.npz")
        output.motion.source["studio_source"] = source_spec
        output.motion.save(out)
        result = {"path": str(out.relative_to(self.root.resolve())), "metrics": dict(output.motion.metrics)}
        if uvm is not None:
            ghost_path = confined(self.root, f"{robot}/{name}.uvm.npz")
            uvm.save(ghost_path)
            result["ghost_path"] = str(ghost_path.relative_to(self.root.resolve()))
        result["playback"] = playback_data(output.motion, source, uvm)
        return result

    def _stmr(self, source, source_spec: str, robot: str, name: str, options, params: dict, report: Callable,
              cancel: threading.Event) -> dict:
        """SMR, then TMR (BO over time scaling α + iLQR tracking in MuJoCo): the dynamic motion, SMR as the ghost."""
        from engine.retarget.quadruped.pipeline import retarget_detailed
        from engine.retarget.quadruped.tmr.tmr import TMRSettings, temporal_retarget

        smr_span = 0.15
        kinematic = retarget_detailed(source, robot, "smr", options, cancel=cancel,
                                      progress=lambda f: report(smr_span * f, f"SMR: frame {int(f * source.frames)} "
                                                                f"of {source.frames}")).motion
        budget = int(params.get("budget", 6))
        if not 1 <= budget <= 100:
            raise JobError(f"budget: expected 1..100 BO evaluations, got {budget}")
        segments = int(params.get("segments", 1))
        from engine.retarget.quadruped.tmr.deformation import DeformationError, check_segments

        try:
            check_segments(segments, kinematic.frames, kinematic.fps)
        except DeformationError as exc:
            raise JobError(f"segments: {exc}") from None

        done = [smr_span]
        settings = TMRSettings(segments=segments, budget=budget, init_points=min(3, budget))
        # The bar spans every evaluation TMR may run: the budget, and the widened search's when every α within the
        # bound falls (a search that needs no widening ends the bar early rather than pinning it at the end)
        most = budget + (settings.widen_budget if settings.widens else 0)

        def on_bo(p) -> None:
            alpha = ", ".join(f"{a:.2f}" for a in 2.0 ** np.asarray(p.current_log2_alpha, float).ravel())
            done[0] = max(done[0], smr_span + (1 - smr_span) * min(p.evaluation / max(most, 1), 1.0))
            stage = " (widened search: nothing stood within the bound)" if p.stage == "widened" else ""
            report(done[0], f"TMR: BO evaluation {p.evaluation} of {p.budget}{stage} · best score {p.best_score:.4f} "
                            f"· α {alpha}")

        report(smr_span, f"TMR: BO evaluation 0 of {budget}")
        result = temporal_retarget(kinematic, settings, progress=on_bo, cancel=cancel.is_set)
        if cancel.is_set():
            raise JobCancelled
        motion = result.motion
        motion.source["studio_source"] = source_spec
        out = confined(self.root, f"{robot}/{name}.npz")
        ghost_path = confined(self.root, f"{robot}/{name}.smr.npz")
        motion.save(out)
        kinematic.save(ghost_path)
        return {"path": str(out.relative_to(self.root.resolve())), "metrics": dict(result.summary),
                "ghost_path": str(ghost_path.relative_to(self.root.resolve())),
                "playback": playback_data(motion, source, kinematic)}

    def _job_import(self, params: dict, report: Callable, cancel: threading.Event) -> dict:
        from engine.retarget.importers import import_source

        where = str(params.get("root", "motions"))
        if where == "shared":
            shared = shared_root()
            if shared is None:
                raise JobError("shared data: not found (MOTION_STUDIO_SHARED, ../shared or /work/shared)")
            root = shared / "motions-src"
        elif where == "motions":
            root = self.root
        else:
            raise JobError(f"root: expected 'shared' or 'motions', got {where!r}")
        src = confined(root, str(params.get("path", "")))
        if not src.is_file():
            raise JobError(f"{params.get('path')}: no such file in {root.name}/")
        name = check_name(str(params.get("name") or src.stem.replace(" ", "_")))
        report(0.1, f"importing {src.name}")
        motion = import_source(src)
        if cancel.is_set():
            raise JobCancelled
        out = confined(self.root, f"{SOURCE_DIR}/{name}.npz")
        motion.save(out)
        return {"path": str(out.relative_to(self.root.resolve())), "frames": motion.frames, "fps": motion.fps,
                "format": motion.source.get("format", "")}

    def _job_export(self, params: dict, report: Callable, cancel: threading.Event) -> dict:
        from engine.export import FORMATS, export_motion
        from engine.retarget.motion import RobotMotion

        fmt = str(params.get("format", ""))
        if fmt not in FORMATS:
            raise JobError(f"format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
        src = confined(self.root, str(params.get("motion", "")))
        take = str(params.get("take", "simulated"))
        fps = params.get("fps")
        if fps is not None:
            from engine.export.resample import check_fps

            try:
                fps = check_fps(fps)
            except ValueError as exc:
                raise JobError(str(exc).replace("--fps", "fps")) from None
        if take == "simulated":
            motion = RobotMotion.load(src)
        else:
            from engine.walk_recording import load_run_motion

            motion = load_run_motion(src, take)
        check_playable(motion, src.name)
        amp_full = bool(params.get("amp_full", False))
        out = confined(self.root, export_name(motion.robot, src.stem, fmt, amp_full, take, fps))
        report(0.5, f"exporting {fmt}")
        written = export_motion(motion, fmt, out, amp_full=amp_full, fps=fps)
        return {"path": str(out.relative_to(self.root.resolve())), "format": fmt, "frames": written.frames,
                "fps": written.fps}

    def _job_poses(self, params: dict, report: Callable, cancel: threading.Event) -> dict:
        from engine.retarget.motion import KeypointMotion, RobotMotion

        path = confined(self.root, str(params.get("motion", "")))
        motion = check_playable(RobotMotion.load(path), path.name)
        source = params.get("source")
        source_motion = self._load_source(str(source)) if source else None
        ghost = params.get("ghost")
        ghost_path = confined(self.root, str(ghost)) if ghost else None
        ghost_motion = check_playable(RobotMotion.load(ghost_path), ghost_path.name) if ghost_path else None
        if source_motion is not None and not isinstance(source_motion, KeypointMotion):
            raise JobError(f"{source}: expected a keypoint motion")
        return {"path": str(params.get("motion")), "metrics": dict(motion.metrics or {}),
                "playback": playback_data(motion, source_motion, ghost_motion)}


def export_name(robot: str, stem: str, fmt: str, amp_full: bool = False, take: str = "simulated",
                fps: float | None = None) -> str:
    """``exports/<robot>_<stem>[_full][_<take>][_<fps>fps].<ext>``: the file the ``export`` job writes for a motion
    of ``robot`` read from ``<stem>.npz`` (the one naming rule of the job and of the panels that start it)."""
    name = (f"{robot}_{stem}" + ("_full" if amp_full and fmt == "amp-json" else "")
            + ("" if take == "simulated" else f"_{take}") + (f"_{fps:g}fps" if fps is not None else ""))
    return f"{EXPORTS_DIR}/{check_name(name)}{EXPORT_SUFFIX[fmt]}"


def export_outputs(root: Path, params: dict[str, Any]) -> tuple[str, ...]:
    """The file (relative to the motion library ``root``) an ``export`` job with ``params`` will write, known before
    it starts — so that a studio whose engine dies during the export removes the temporary a cut write left. Read
    from the motion file's ``robot`` entry only (engine/safe_io.py); () when the file or the parameters cannot say
    (the job then fails before it writes anything)."""
    from engine.export.resample import check_fps
    from engine.safe_io import ReadError, read_npz

    try:
        fmt = str(params.get("format", ""))
        if fmt not in EXPORT_SUFFIX:
            return ()
        src = confined(root, str(params.get("motion", "")))
        robot = read_npz(src, source=src.name, only=("robot",)).get("robot")
        if robot is None or robot.ndim != 0 or robot.dtype.kind != "U":
            return ()
        fps = params.get("fps")
        return (export_name(str(robot), src.stem, fmt, bool(params.get("amp_full", False)),
                            str(params.get("take", "simulated")), None if fps is None else check_fps(fps)),)
    except (ReadError, ValueError):  # OutsideLibrary and check_name's refusals are ValueErrors too
        return ()


def check_playable(motion, where: str):  # noqa: ANN001, ANN201 - RobotMotion in, the same out
    """A robot motion whose robot exists and whose joints are that robot's (what :func:`body_poses` needs), else a
    JobError naming the file and the field (a loadable file may still name another robot or unknown joints)."""
    from engine.robot.config import RobotConfigError, load_robot_config
    from engine.robot.model import load_robot

    try:
        load_robot_config(motion.robot)
    except RobotConfigError as exc:
        raise JobError(f"{where}: robot: expected a known robot, {exc}") from None
    model = load_robot(motion.robot).mj_model
    known = {model.joint(i).name for i in range(model.njnt)}
    unknown = [name for name in motion.joint_names if name not in known]
    if unknown:
        raise JobError(f"{where}: joint_names: expected joints of {motion.robot}, got {unknown[0][:40]!r}")
    return motion


def body_poses(motion) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Forward kinematics (MuJoCo) of every frame of a robot motion: body names, (T,B,3) positions, (T,B,4) wxyz."""
    import mujoco

    from engine.robot.model import load_robot

    robot = load_robot(motion.robot)
    model = robot.mj_model
    data = mujoco.MjData(model)
    data.qpos[:] = robot.mj_standing_qpos()
    adr = [int(model.jnt_qposadr[model.joint(name).id]) for name in motion.joint_names]
    T, B = motion.frames, model.nbody - 1
    pos = np.empty((T, B, 3), dtype=np.float32)
    quat = np.empty((T, B, 4), dtype=np.float32)
    for t in range(T):
        data.qpos[:7] = motion.qpos[t, :7]
        data.qpos[adr] = motion.qpos[t, 7:]
        mujoco.mj_kinematics(model, data)
        pos[t], quat[t] = data.xpos[1:], data.xquat[1:]
    return list(robot.body_names), pos, quat


def retiming(motion):  # noqa: ANN001, ANN201 - a RobotMotion → TemporalDeformation | None
    """The temporal deformation s_α of a re-timed (TMR) motion, from the α and segment knots it carries (None
    for a motion that was not re-timed). Its source time is the kinematic motion's (SMR's) time."""
    extra = getattr(motion, "extra", None) or {}
    if "alpha" not in extra or "segment_knots_s" not in extra:
        return None
    from engine.retarget.quadruped.tmr.deformation import TemporalDeformation

    alpha = np.asarray(extra["alpha"], dtype=float).ravel()
    knots = np.asarray(extra["segment_knots_s"], dtype=float).ravel()
    source_duration = float(np.sum(np.diff(knots) / alpha))  # segment i lasts α_i · T_s / S of control time
    return TemporalDeformation(tuple(float(a) for a in alpha), source_duration)


def source_times(motion) -> np.ndarray:  # noqa: ANN001
    """Per frame of ``motion``, the time (s) of the kinematic motion / source it shows: s_α(t) for a re-timed
    motion, t otherwise."""
    t = np.arange(motion.frames) / float(motion.fps)
    deformation = retiming(motion)
    return t if deformation is None else deformation(t)


def playback_data(motion, source=None, ghost=None) -> dict:
    """What the studio needs to play a robot motion beside its source (see module docstring). A re-timed (TMR)
    motion plays its kinematic ghost (SMR's motion) and its source at s_α(t), the same point of the motion as
    the robot in physics, and carries ``segments``: α and the segment boundaries in playback time."""
    names, pos, quat = body_poses(motion)
    data: dict[str, Any] = {
        "robot": motion.robot, "method": motion.method, "fps": float(motion.fps), "frames": int(motion.frames),
        "body_names": names, "body_pos": pos, "body_quat": quat,
        "contact": np.asarray(motion.contact, dtype=bool), "foot_names": list(getattr(motion, "foot_names", LEGS)),  # TMR's motion class has none
    }
    deformation = retiming(motion)
    t_src = source_times(motion)
    if deformation is not None:
        data["segments"] = {"alpha": [float(a) for a in deformation.alpha],
                            "knots_s": [float(k) for k in motion.extra["segment_knots_s"]],
                            "duration_before_s": float(deformation.source_duration_s)}
    if source is not None:
        data["source_keypoints"] = np.asarray(source.keypoints, dtype=np.float32)
        data["source_contact"] = np.asarray(source.contact, dtype=bool)
        data["source_fps"] = float(source.fps)
        if deformation is None and source.frames != motion.frames:  # another rate: the same fraction of the clip
            t_src = t_src * ((source.frames - 1) / source.fps) / max((motion.frames - 1) / motion.fps, 1e-9)
        data["source_frame"] = np.clip(np.rint(t_src * source.fps), 0, source.frames - 1).astype(np.int32)
    if ghost is not None and ghost.robot == motion.robot:
        if deformation is not None and ghost.frames != motion.frames:
            from engine.retarget.quadruped.tmr.deformation import interpolate_qpos

            ghost_qpos = interpolate_qpos(ghost.qpos, float(ghost.fps), t_src)  # LI(s_α(t)) of the kinematic motion
            _, gpos, gquat = body_poses(SimpleNamespace(robot=ghost.robot, joint_names=ghost.joint_names,
                                                        qpos=ghost_qpos, frames=len(ghost_qpos)))
        elif ghost.frames == motion.frames:
            _, gpos, gquat = body_poses(ghost)
        else:
            return data
        data["ghost_pos"], data["ghost_quat"] = gpos, gquat
        data["ghost_method"] = str(ghost.method)
    return data

