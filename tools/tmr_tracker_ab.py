"""The TMR tracker against its previous settings, side by side on the short clips (SMR's motion at α = 1).

    python tools/tmr_tracker_ab.py                                  # trot0,trot1,pace0,pace1 on go1 and a1
    python tools/tmr_tracker_ab.py --robots go1 --clips trot1 --old "final_scale=5 polish_iterations=0"
    python tools/tmr_tracker_ab.py --clips pace0 --variant "w4=window_s=0.4 other_windows_s="   # a third variant

Per clip and robot, the old and the new tracker run alternately on the same target (the SMR motion tracked as
it is, as ``studio bench tmr-clips``'s "SMR replay" column): open-loop replay fell (and when), DTW keypoint L1 %
against the kinematic motion, mean keypoint error mm against the target, the solver's whole-clip cost, CPU s of the
solve (thread time).
``--old`` / ``--new`` / ``--variant NAME=...`` are space-separated ``name=value`` overrides of TMRSettings or
TrackingWeights fields (a tuple field takes comma-separated values, empty for none).
Prints one JSON line per run, then a summary per variant. Paper clips are read from the shared folder.
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

from engine.retarget.quadruped.tmr.ddp import TrackingWeights  # noqa: E402
from engine.retarget.quadruped.tmr.deformation import TemporalDeformation  # noqa: E402
from engine.retarget.quadruped.tmr.keypoints import keypoint_trajectory  # noqa: E402
from engine.retarget.quadruped.tmr.scoring import dtw_keypoint_l1_pct, tracking_error_mm  # noqa: E402
from engine.retarget.quadruped.tmr.tmr import TMRSettings, deformed_target, make_tracker  # noqa: E402
from engine.robot.model import load_robot  # noqa: E402

OLD = "other_windows_s="  # the tracker before issue 10's seventh round (one 0.25 s window)


def parse_overrides(text: str) -> tuple[dict, dict]:
    settings, weights = {}, {}
    for item in text.split():
        name, value = item.split("=")
        if isinstance(getattr(TMRSettings(), name, None), tuple):
            settings[name] = tuple(float(v) for v in value.split(",") if v)
        elif hasattr(TMRSettings, name):
            settings[name] = type(getattr(TMRSettings(), name))(float(value))
        elif hasattr(TrackingWeights, name):
            weights[name] = float(value)
        else:
            raise SystemExit(f"unknown setting {name!r}")
    return settings, weights


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="go1,a1")
    parser.add_argument("--clips", default="trot0,trot1,pace0,pace1")
    parser.add_argument("--old", default=OLD)
    parser.add_argument("--new", default="")
    parser.add_argument("--variant", action="append", default=[], metavar="NAME=OVERRIDES",
                        help="a further variant, e.g. --variant 'long=window_s=0.4 polish_iterations=10' (repeatable)")
    args = parser.parse_args(argv)
    from engine.bench.retarget import clip_path, shared_dir
    from engine.retarget.importers import import_source
    from engine.retarget.quadruped.pipeline import retarget_detailed

    shared = shared_dir()
    if shared is None:
        print("shared data folder absent: set MOTION_STUDIO_SHARED", file=sys.stderr)
        return 2
    texts = {"old": args.old, "new": args.new}
    for item in args.variant:
        name, _, text = item.partition("=")
        texts[name] = text
    variants = {name: parse_overrides(text) for name, text in texts.items()}
    rows: dict[str, list[dict]] = {name: [] for name in variants}
    for robot_name in args.robots.split(","):
        robot = load_robot(robot_name)
        for clip in args.clips.split(","):
            motion = retarget_detailed(import_source(clip_path(shared, clip)), robot_name, "smr").motion
            fps, qpos = float(motion.fps), np.asarray(motion.qpos, float)
            contact = np.asarray(motion.contact, bool)
            reference = keypoint_trajectory(robot, qpos)
            for name, (settings, weights) in variants.items():
                tracker = make_tracker(robot, TMRSettings(**settings))
                for field_name, value in weights.items():
                    setattr(tracker.weights, field_name, value)
                deformation = TemporalDeformation.from_log2(np.zeros(1), (len(qpos) - 1) / fps)
                target = deformed_target(robot, qpos, contact, fps, deformation, tracker)
                t0 = time.thread_time()
                res = tracker.track(target)
                cpu_s = time.thread_time() - t0
                row = {"clip": clip, "robot": robot_name, "variant": name, "replay_fell": bool(res.fell),
                       "fell_at_s": round(res.fall_fraction * target.horizon * tracker.dt_s, 2) if res.fell else None,
                       "dtw_keypoint_l1_pct": round(dtw_keypoint_l1_pct(res.keypoints, reference), 3),
                       "tracking_error_mm": round(tracking_error_mm(res.keypoints, target.keypoints), 1),
                       "cost": round(float(res.cost), 1), "cpu_s": round(cpu_s, 1)}
                rows[name].append(row)
                print(json.dumps(row), flush=True)
    for name, rs in rows.items():
        print(json.dumps({"variant": name, "overrides": texts[name],
                          "falls": f"{sum(r['replay_fell'] for r in rs)}/{len(rs)}",
                          "mean_dtw_pct": round(float(np.mean([r["dtw_keypoint_l1_pct"] for r in rs])), 3),
                          "mean_tracking_error_mm": round(float(np.mean([r["tracking_error_mm"] for r in rs])), 1),
                          "cpu_s": round(sum(r["cpu_s"] for r in rs), 1)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
