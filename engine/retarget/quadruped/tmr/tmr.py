"""TMR, the temporal stage of STMR (§IV-B, §VI): RobotMotion (kinematic) → RobotMotion (dynamic).

For each temporal parameter α the Bayesian optimisation proposes, the kinematic motion is deformed in time
(s_α over S segments, LI of the configurations as control targets), tracked by box-iLQR in the robot's full
MuJoCo model, replayed open-loop from the initial state, and scored (Eq. 15). The best evaluation is the result:
its replayed ``qpos``/``qvel``, the torques ``ctrl``, the PD targets that reproduce those torques, α and the
durations before and after.

``evaluate_alpha`` is a plain function of plain arrays, so it runs unchanged inside a Ray worker.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Callable

import numpy as np

from engine.retarget.quadruped.tmr.bayes_opt import BOProgress, BOSettings, bayes_optimise
from engine.retarget.quadruped.tmr.ddp import Cancelled, ILQRSettings, MotionTracker, TrackingTarget
from engine.retarget.quadruped.tmr.deformation import (
    DEFAULT_LOG2_BOUND,
    TemporalDeformation,
    ballistic_flights,
    check_log2_bound,
    check_segments,
    finite_difference_qvel,
    interpolate_qpos,
    sample_contact,
)
from engine.retarget.quadruped.tmr.keypoints import keypoint_trajectory
from engine.retarget.motion import RobotMotion
from engine.retarget.quadruped.tmr.ray_jobs import LocalExecutor
from engine.retarget.quadruped.tmr.scoring import dtw_keypoint_l1_pct, tmr_score, tracking_error_mm


#: A segment whose best (fallen) log2 α lies within this of 0 counts as the identity: the widened search shortens it.
WIDEN_DEAD_BAND_LOG2 = 0.05


@dataclass
class TMRSettings:
    segments: int = 1  # S (the paper uses 1 for short clips, 3 for long varied ones)
    log2_bound: float = DEFAULT_LOG2_BOUND  # log2 α ∈ [−B, B]
    budget: int = 8  # BO evaluations at most
    # When every evaluation within ±log2_bound falls, the search goes on over ±widen_log2_bound (≤ 2, the studio's
    # limit) for widen_budget more evaluations, the first at the far end on the side of the fall that got furthest
    # (shortening when that was within WIDEN_DEAD_BAND_LOG2 of the identity): a1's HopTurn falls at every α in [½, 2]
    # BO tried and stands at α = 0.33 (log2 −1.6; README, issue 10). A budget of 0 turns it off; the summary names
    # the bound searched (the best result may still lie within ±log2_bound)
    widen_log2_bound: float = 1.6
    widen_budget: int = 2
    init_points: int = 3  # warm start: the identity, log2 α = −B, +B, −B/2, +B/2 in every segment, then random
    parallel: int = 1  # evaluations in flight (Ray workers)
    w_contact: float = 0.2  # w_c of Eq. 15
    w_alpha: float = 0.05  # regularisation of extreme α
    w_keypoints: float = 1.0  # −w_k · mean keypoint L1 (m) in the score (ours; 0: Eq. 15's base-only score)
    timestep_s: float = 0.01  # control interval of the tracker
    mode: str = "receding"  # "receding" (MuJoCo MPC style) or "full" horizon iLQR
    window_s: float = 0.25
    # further receding windows, each solved (and polished) from the same start; the tracker answers with the
    # candidate whose replay stands (else falls latest), then of least whole-clip cost. A 0.4 s window sees
    # past the one-foot phases of the mocap schedules: alone it tracks the four short clips (go1, a1, α = 1) to
    # mean DTW 3.39 % (was 3.92 %; go1 trot0 4.49 → 3.15 %), but lengths beside it fall (0.35 s: go1 trot1;
    # 0.45 s: go1 trot0, trot1) and it fell where 0.25 s stood in earlier rounds (SideSteps α = 0.5, BackFlip):
    # with both, an answer never costs more nor falls where the 0.25 s one stood, at 2.5× the CPU
    other_windows_s: tuple[float, ...] = (0.4,)
    # windows tried one by one only while every answer so far falls: a1 trot1 (α = 1) falls at 1.34 s with 0.25 s
    # and 0.4 s windows and stands with 0.5 s (2.01 % DTW, 15.3 mm); 0.5 s as a standing candidate fell on go1
    # trot1, pace0, pace1
    fallback_windows_s: tuple[float, ...] = (0.5,)
    # then ``window_s`` with these terminal weights (TrackingWeights.final_scale, 20), one at a time while every
    # answer still falls. The terminal weight 20 (for go1 trot1's one-foot landings) makes each window reach for
    # its end state: through b1's BackFlip the rear feet leave the ground at 0.46 s instead of 0.55 s and the
    # α = 1 replay falls (1.08 s with the 0.25 s window alone; 1.21 s, a thigh touching at the absorb, with all
    # three windows); with 5 (the third round's) it lands upright (6.1 % DTW, 161 mm). Clips that stand with a
    # regular or fallback window never solve it
    fallback_final_scales: tuple[float, ...] = (5.0,)
    replan_s: float = 0.05
    # iLQR iterations per receding window (each stops early once the cost decreases < 0.1 %). 2 left the
    # solve short of converged: SideSteps at α = 0.5 fell at 1.89 s (go1); with 4 it tracks the whole clip
    # (go1 0.69 % DTW, 8.1 mm; a1 0.61 %, 6.5 mm) at about twice the solve time
    window_iterations: int = 4
    full_iterations: int = 30
    # full-horizon iLQR iterations after the receding pass (skipped once the receding replay fell; kept only if
    # its replay does not fall where the receding one stood). 5 on the four short clips, go1 and a1, α = 1 (after
    # the terminal weight 20): mean DTW 4.37 → 3.92 %, keypoint error 26.6 → 23.6 mm, CPU 1.5× the receding pass
    polish_iterations: int = 5
    seed: int = 0

    @property
    def widens(self) -> bool:
        """Whether a search in which every evaluation fell goes on over the wider ``widen_log2_bound``."""
        return self.widen_budget > 0 and self.widen_log2_bound > self.log2_bound


@dataclass
class Evaluation:
    log2_alpha: np.ndarray
    score: dict
    fell: bool
    tracking_error_mm: float
    duration_s: float
    qpos: np.ndarray
    qvel: np.ndarray
    ctrl: np.ndarray
    contact_sim: np.ndarray
    contact_target: np.ndarray
    keypoints: np.ndarray
    keypoints_target: np.ndarray
    wall_time_s: float


@dataclass
class TMRResult:
    motion: RobotMotion  # the dynamic motion
    summary: dict
    evaluations: list[dict] = field(default_factory=list)


def deformed_target(robot, qpos: np.ndarray, contact: np.ndarray, fps: float, deformation: TemporalDeformation,  # noqa: ANN001
                    tracker: MotionTracker) -> TrackingTarget:
    """LI(s_α(t_k)) at the tracker's control instants: configurations, velocities, schedule, keypoints."""
    t_control = deformation.control_times(tracker.dt_s)
    # equal spacing is what the tracker needs: drop a last, shorter interval
    t_control = t_control[: int(np.floor(deformation.duration_s / tracker.dt_s + 1e-9)) + 1]
    src = deformation(t_control)
    q = interpolate_qpos(qpos, fps, src)
    c = sample_contact(contact, fps, src)
    q = ballistic_flights(q, c, tracker.dt_s, float(-tracker.model.opt.gravity[2]))
    v = finite_difference_qvel(tracker.model, q, tracker.dt_s)
    return TrackingTarget(tracker.dt_s, q, v, c, keypoint_trajectory(robot, q, tracker.keypoints))


def make_tracker(robot, settings: TMRSettings) -> MotionTracker:  # noqa: ANN001
    return MotionTracker(robot, timestep_s=settings.timestep_s, settings=ILQRSettings(max_iterations=settings.full_iterations),
                         mode=settings.mode, window_s=settings.window_s, replan_s=settings.replan_s,
                         window_iterations=settings.window_iterations, polish_iterations=settings.polish_iterations,
                         other_windows_s=tuple(settings.other_windows_s),
                         fallback_windows_s=tuple(settings.fallback_windows_s),
                         fallback_final_scales=tuple(settings.fallback_final_scales))


def evaluate_alpha(robot_name: str, qpos: np.ndarray, contact: np.ndarray, fps: float, log2_alpha: np.ndarray,
                   settings: TMRSettings, cancel: Callable[[], bool] | None = None) -> Evaluation:
    """One BO evaluation: deform, track (iLQR), replay open-loop, score. Runs in any process."""
    from engine.robot.model import load_robot

    t0 = time.perf_counter()
    robot = load_robot(robot_name)
    tracker = make_tracker(robot, settings)
    source_duration = (len(qpos) - 1) / fps
    deformation = TemporalDeformation.from_log2(log2_alpha, source_duration)
    target = deformed_target(robot, qpos, contact, fps, deformation, tracker)
    result = tracker.track(target, cancel=cancel)
    score = tmr_score(result.qpos, result.contact, target.qpos, target.contact, np.asarray(log2_alpha), result.fell,
                      settings.w_contact, settings.w_alpha, result.fall_fraction, result.keypoints, target.keypoints,
                      settings.w_keypoints)
    score["fell_at_s"] = round(result.fall_fraction * target.horizon * tracker.dt_s, 3) if result.fell else None
    return Evaluation(np.asarray(log2_alpha, float), score, result.fell,
                      tracking_error_mm(result.keypoints, target.keypoints), target.horizon * tracker.dt_s,
                      result.qpos, result.qvel, result.ctrl, result.contact, target.contact, result.keypoints,
                      target.keypoints, time.perf_counter() - t0)


def _check(motion, settings: TMRSettings) -> None:  # noqa: ANN001
    check_log2_bound(settings.log2_bound)
    if settings.widens:
        check_log2_bound(settings.widen_log2_bound)  # before the first search, not after it
    check_segments(settings.segments, len(motion.qpos), motion.fps)


def temporal_retarget(motion, settings: TMRSettings | None = None, executor: Any = None,  # noqa: ANN001
                      progress: Callable[[BOProgress], None] | None = None,
                      cancel: Callable[[], bool] | None = None) -> TMRResult:
    """TMR of a kinematic motion (any object with fps, qpos, joint_names, contact (T, 4), robot)."""
    from engine.robot.model import load_robot

    settings = settings or TMRSettings()
    _check(motion, settings)
    t0 = time.perf_counter()
    executor = executor or LocalExecutor()
    qpos = np.asarray(motion.qpos, float)
    contact = np.asarray(motion.contact, bool)
    fps = float(motion.fps)
    robot = load_robot(motion.robot)
    _check_joint_order(robot, motion)

    def submit(x: np.ndarray) -> Any:
        return executor.submit(evaluate_alpha, motion.robot, qpos, contact, fps, x, settings,
                               cancel if isinstance(executor, LocalExecutor) else None)

    def collect(handles: list[Any]) -> list[tuple[Any, float, Evaluation]]:
        return [(h, ev.score["score"], ev) for h, ev in executor.collect(handles)]

    bo = bayes_optimise(submit, collect, settings.segments, settings.log2_bound,
                        BOSettings(budget=settings.budget, init_points=settings.init_points, parallel=settings.parallel,
                                   seed=settings.seed), progress=progress, cancel=cancel, abort=executor.cancel)
    searched_bound, narrow_evaluations = settings.log2_bound, bo.evaluations
    if bo.best_payload.fell and settings.widens:
        searched_bound = check_log2_bound(settings.widen_log2_bound)
        far = np.where(bo.best_log2_alpha > WIDEN_DEAD_BAND_LOG2, searched_bound, -searched_bound)
        bo = bayes_optimise(submit, collect, settings.segments, searched_bound,
                            BOSettings(budget=settings.widen_budget, parallel=settings.parallel, seed=settings.seed),
                            progress=None if progress is None else (lambda p: progress(replace(p, stage="widened"))),
                            cancel=cancel, abort=executor.cancel,
                            known=[(x, sc, ev) for (x, sc), ev in zip(bo.history, bo.payloads)], warm_start=[far])
    best: Evaluation = bo.best_payload
    # DTW keypoint L1 of the replay against the kinematic input at its own frames — measured as track_motion
    # measures UVM's and SMR's replays, so the methods compare — and against the re-timed (re-arced) target
    dtw = dtw_keypoint_l1_pct(best.keypoints, keypoint_trajectory(robot, qpos))
    dtw_target = dtw_keypoint_l1_pct(best.keypoints, best.keypoints_target)
    out = dynamic_motion(robot, motion, best, settings)
    alpha = (2.0 ** best.log2_alpha).tolist()
    summary = {
        "robot": motion.robot, "segments": settings.segments, "alpha": [round(a, 4) for a in alpha],
        "log2_bound": settings.log2_bound, "log2_bound_searched": searched_bound,
        "bo_evaluations_widened": bo.evaluations - narrow_evaluations,
        "duration_s": {"before": round((len(qpos) - 1) / fps, 4), "after": round(best.duration_s, 4)},
        "bo_evaluations": bo.evaluations, "bo_converged": bo.converged, "score": round(best.score["score"], 5),
        "replay_fell": bool(best.fell), "replay_fell_at_s": best.score["fell_at_s"], "dtw_keypoint_l1_pct": None if not np.isfinite(dtw) else round(dtw, 3),
        "dtw_vs_target_pct": None if not np.isfinite(dtw_target) else round(dtw_target, 3),
        "tracking_error_mm": round(best.tracking_error_mm, 2), "contact_iou": round(best.score["contact_iou"], 4),
        "base_l1_m": round(best.score["d_b_m"], 5), "euler_l1_rad": round(best.score["d_E_rad"], 5),
        "wall_time_s": round(time.perf_counter() - t0, 2),
    }
    out.metrics = {**summary}
    evaluations = [{"alpha": [round(2.0 ** float(v), 4) for v in x], "score": round(s, 5), "replay_fell": bool(ev.fell),
                    "fell_at_s": ev.score["fell_at_s"],
                    "tracking_error_mm": round(ev.tracking_error_mm, 2), "duration_s": round(ev.duration_s, 3),
                    "wall_time_s": round(ev.wall_time_s, 1)}
                   for (x, s), ev in zip(bo.history, bo.payloads)]
    return TMRResult(out, summary, evaluations)


def _check_joint_order(robot, motion) -> None:  # noqa: ANN001
    from engine.retarget.quadruped.tmr.kinematic_clips import mujoco_joint_names

    expected = mujoco_joint_names(robot)
    if list(motion.joint_names) != expected:
        raise ValueError(f"joint_names: expected {robot.name}'s joints in MuJoCo order ({', '.join(expected)})")


def dynamic_motion(robot, motion, ev: Evaluation, settings: TMRSettings) -> RobotMotion:  # noqa: ANN001
    """The dynamic RobotMotion of an evaluation: at the control rate, ctrl[k] applied over [t_k, t_k+1) (the last
    row repeats the last control), PD targets θ + (τ + K_d θ̇)/K_p with the robot's gains reproduce the torques."""
    from engine.retarget.quadruped.tmr.kinematic_clips import mujoco_joint_names

    names = mujoco_joint_names(robot)
    act = [int(robot.mj_actuator_index[robot.joint_names.index(n)]) for n in names]
    qadr = [int(robot.mj_qpos_index[robot.joint_names.index(n)]) for n in names]
    dadr = [int(robot.mj_dof_index[robot.joint_names.index(n)]) for n in names]
    kp = np.array([robot.kp[robot.joint_names.index(n)] for n in names])
    kd = np.array([robot.kd[robot.joint_names.index(n)] for n in names])
    tau = ev.ctrl[:, act]
    tau = np.vstack([tau, tau[-1:]])
    theta, dtheta = ev.qpos[:, qadr], ev.qvel[:, dadr]
    pd = theta + (tau + kd * dtheta) / kp
    deformation = TemporalDeformation.from_log2(ev.log2_alpha, (len(motion.qpos) - 1) / motion.fps)
    return RobotMotion(
        fps=1.0 / settings.timestep_s, qpos=ev.qpos, joint_names=names, contact=ev.contact_target, robot=robot.name,
        method="stmr", keypoints=ev.keypoints, qvel=ev.qvel, ctrl=tau,
        source={**getattr(motion, "source", {}), "kinematic_method": getattr(motion, "method", "unknown"),
                "tmr": {k: v for k, v in asdict(settings).items()}},
        extra={"pd_targets": pd, "pd_kp": kp, "pd_kd": kd, "alpha": 2.0 ** ev.log2_alpha,
               "segment_knots_s": deformation.control_knots_s, "contact_sim": ev.contact_sim})


def track_motion(motion, settings: TMRSettings | None = None, cancel: Callable[[], bool] | None = None) -> dict:  # noqa: ANN001
    """Track any robot motion (UVM, SMR, STMR, keyframed) as it is (α = 1) with the same tracker and report the
    figures the benchmark compares methods by: open-loop replay falls or not, tracking error (mm, against the
    motion's own keypoints in time), DTW keypoint L1 (%)."""
    from engine.robot.model import load_robot

    settings = settings or TMRSettings()
    robot = load_robot(motion.robot)
    _check_joint_order(robot, motion)
    qpos = np.asarray(motion.qpos, float)
    ev = evaluate_alpha(motion.robot, qpos, np.asarray(motion.contact, bool), float(motion.fps), np.zeros(1), settings,
                        cancel)
    dtw = dtw_keypoint_l1_pct(ev.keypoints, keypoint_trajectory(robot, qpos))
    return {"robot": motion.robot, "method": getattr(motion, "method", "unknown"), "replay_fell": bool(ev.fell),
            "tracking_error_mm": round(ev.tracking_error_mm, 2),
            "dtw_keypoint_l1_pct": None if not np.isfinite(dtw) else round(dtw, 3),
            "contact_iou": round(ev.score["contact_iou"], 4), "wall_time_s": round(ev.wall_time_s, 2)}
