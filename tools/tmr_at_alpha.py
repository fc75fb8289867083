"""One TMR inner solve at a fixed α, and what its open-loop replay did (the evaluation BO makes, without BO).

    python tools/tmr_at_alpha.py hopturn --robot go1 --alpha 0.5            # a paper clip: SMR, then TMR at α
    python tools/tmr_at_alpha.py /tmp/backflip_b1.npz --alpha 1 --window-iterations 2
    python tools/tmr_at_alpha.py sidesteps --robot a1 --alpha 0.5 --crop-s 4
    python tools/tmr_at_alpha.py trot0 --contacts source                    # SMR on the clip's contact labels
    python tools/tmr_at_alpha.py /tmp/backflip_b1.npz --set "final_scale=5 polish_iterations=0 other_windows_s="

Prints one JSON line: the replay fell or not (and when), DTW keypoint L1 % against the kinematic motion at its
own frames (as ``studio bench tmr-clips`` measures), tracking error mm against the re-timed target, the lowest
base height, the final base height and tilt (the angle of the trunk's up axis from the vertical: a landing
ends upright), the share of torque-saturated controls, and per foot the first instant the replay's contact differs
from the schedule for 50 ms or more (which foot first deviates, and how: "air" = scheduled stance but in the air,
"ground" = scheduled swing but touching). Paper clips are read from the shared folder (non-commercial data).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

from engine.retarget.contacts import CONTACT_SCHEDULES  # noqa: E402
from engine.retarget.quadruped.tmr.deformation import TemporalDeformation  # noqa: E402
from engine.retarget.quadruped.tmr.keypoints import keypoint_trajectory  # noqa: E402
from engine.retarget.quadruped.tmr.scoring import dtw_keypoint_l1_pct, tracking_error_mm  # noqa: E402
from engine.retarget.quadruped.tmr.tmr import TMRSettings, deformed_target, make_tracker  # noqa: E402
from engine.robot.model import load_robot  # noqa: E402
from tools.tmr_tracker_ab import parse_overrides  # noqa: E402

LEGS = ("FL", "FR", "RL", "RR")


def first_deviations(contact_sim: np.ndarray, contact_target: np.ndarray, dt_s: float, hold_s: float = 0.05) -> dict:
    """Per foot: the first instant the replay's contact differs from the schedule for ``hold_s`` or more."""
    n_hold = max(1, int(round(hold_s / dt_s)))
    out = {}
    for leg, name in enumerate(LEGS):
        diff = contact_sim[:, leg] != contact_target[:, leg]
        diff[0] = False  # the initial state is placed, not simulated
        run = 0
        for k, d in enumerate(diff):
            run = run + 1 if d else 0
            if run >= n_hold:
                k0 = k - n_hold + 1
                out[name] = {"t_s": round(k0 * dt_s, 2), "kind": "air" if contact_target[k0, leg] else "ground"}
                break
    return out


def tilt_deg(quat_wxyz: np.ndarray) -> float:
    """Angle (degrees) between the trunk's up axis and the world's vertical: 0 upright, 180 on its back."""
    w, x, y, z = (float(v) for v in quat_wxyz / np.linalg.norm(quat_wxyz))
    up_z = 1.0 - 2.0 * (x * x + y * y)  # world z of the body z axis
    return float(np.degrees(np.arccos(np.clip(up_z, -1.0, 1.0))))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("clip", help="a paper clip (trot0 … hopturn) or a robot-motion npz")
    parser.add_argument("--robot", default="go1")
    parser.add_argument("--alpha", type=float, default=1.0)
    parser.add_argument("--window-iterations", type=int, default=TMRSettings().window_iterations)
    parser.add_argument("--set", default="", metavar="OVERRIDES",
                        help="space-separated name=value overrides of TMRSettings or TrackingWeights fields, as "
                             "tools/tmr_tracker_ab.py takes them (a tuple field: comma-separated, empty for none)")
    parser.add_argument("--contacts", choices=CONTACT_SCHEDULES, default="cleaned",
                        help="paper clips: the stance schedule SMR follows (RetargetOptions.contacts)")
    parser.add_argument("--crop-s", type=float, default=None, help="track only the first seconds of the clip")
    parser.add_argument("--pd-only", action="store_true",
                        help="no iLQR: the robot's PD servo on the (re-timed) kinematic joints plus the stance "
                             "feed-forward, replayed the same way (the motion without TMR's optimal control)")
    args = parser.parse_args(argv)
    if not 0.25 <= args.alpha <= 4.0:
        print(f"--alpha: expected 0.25..4, got {args.alpha}", file=sys.stderr)
        return 2
    if Path(args.clip).suffix == ".npz":
        from engine.retarget.motion import RobotMotion

        motion = RobotMotion.load(args.clip)
    else:
        from engine.bench.retarget import clip_path, shared_dir
        from engine.retarget.importers import import_source
        from engine.retarget.quadruped.pipeline import RetargetOptions, retarget_detailed

        shared = shared_dir()
        if shared is None:
            print("shared data folder absent: set MOTION_STUDIO_SHARED", file=sys.stderr)
            return 2
        motion = retarget_detailed(import_source(clip_path(shared, args.clip)), args.robot, "smr",
                                   RetargetOptions(contacts=args.contacts)).motion
    robot = load_robot(motion.robot)
    fps = float(motion.fps)
    n = len(motion.qpos) if args.crop_s is None else min(len(motion.qpos), int(args.crop_s * fps) + 1)
    qpos, contact = np.asarray(motion.qpos[:n], float), np.asarray(motion.contact[:n], bool)
    overrides, weights = parse_overrides(args.set)
    settings = TMRSettings(**{"window_iterations": args.window_iterations, **overrides})
    tracker = make_tracker(robot, settings)
    for field_name, value in weights.items():
        setattr(tracker.weights, field_name, value)
    deformation = TemporalDeformation.from_log2(np.array([np.log2(args.alpha)]), (n - 1) / fps)
    target = deformed_target(robot, qpos, contact, fps, deformation, tracker)
    t0 = time.perf_counter()
    if args.pd_only:
        res = tracker.replay(target.qpos[0], target.qvel[0],
                             tracker.pd_initial_controls(target, tracker.stance_torques(target)))
    else:
        res = tracker.track(target)
    lo, hi = tracker.dyn.u_lower, tracker.dyn.u_upper
    saturated = (np.abs(res.ctrl - hi) < 1e-6) | (np.abs(res.ctrl - lo) < 1e-6)
    H = target.horizon
    k_end = int(res.fall_fraction * H) if res.fell else H
    print(json.dumps({
        "clip": args.clip, "robot": motion.robot, "contacts": args.contacts, "overrides": args.set, "alpha": args.alpha, "window_iterations": None if args.pd_only else args.window_iterations,
        "duration_s": {"before": round((n - 1) / fps, 3), "after": round(H * tracker.dt_s, 3)},
        "replay_fell": bool(res.fell), "fell_at_s": round(k_end * tracker.dt_s, 2) if res.fell else None,
        "dtw_keypoint_l1_pct": round(dtw_keypoint_l1_pct(res.keypoints, keypoint_trajectory(robot, qpos)), 3),
        "tracking_error_mm": round(tracking_error_mm(res.keypoints, target.keypoints), 1),
        "min_base_z_m": round(float(res.qpos[:, 2].min()), 3), "target_min_base_z_m": round(float(target.qpos[:, 2].min()), 3),
        "final_base_z_m": round(float(res.qpos[-1, 2]), 3), "target_final_base_z_m": round(float(target.qpos[-1, 2]), 3),
        "final_tilt_deg": round(tilt_deg(res.qpos[-1, 3:7]), 1),
        "saturated_share": round(float(saturated[:max(k_end, 1)].mean()), 4),
        "first_contact_deviation": first_deviations(res.contact, target.contact, tracker.dt_s),
        "wall_time_s": round(time.perf_counter() - t0, 1),
    }))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
