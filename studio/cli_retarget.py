"""Bodies of ``studio import``, ``studio retarget`` and ``studio export`` (quadruped retargeting, STMR).

``studio retarget --method stmr`` is SMR then TMR: the SMR motion is re-timed by Bayesian optimisation over α
and tracked by iLQR in MuJoCo (``engine.retarget.quadruped.tmr``); the output is the dynamic motion (qpos, qvel,
ctrl torques, PD targets) and the JSON adds the TMR figures to SMR's.

Every user error is one line naming the file and what was expected (CliError → exit 2); nothing is
written unless the whole command succeeded (files are written atomically at the end).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from studio.cli import CliError, check_ray_address


def register(sub: argparse._SubParsersAction) -> None:
    from engine.export import FORMATS as EXPORT_FORMATS
    from engine.retarget.contacts import CONTACT_SCHEDULES
    from engine.retarget.importers import FORMATS as IMPORT_FORMATS

    imp = sub.add_parser("import", help="import a source motion (dog mocap, animation, video keypoints) as keypoints (npz)")
    imp.add_argument("src", help="source file (format detected from its content)")
    imp.add_argument("--out", required=True, help="output keypoint motion, e.g. motions/source/NAME.npz")
    imp.add_argument("--format", default=None, choices=IMPORT_FORMATS, help="force the source format")

    ret = sub.add_parser("retarget", help="retarget a source motion onto a quadruped (UVM or SMR)")
    ret.add_argument("--source", required=True, help="any importable source or a motions/ keypoint npz")
    ret.add_argument("--robot", required=True, help="target quadruped: go1, go2, a1, b1, anymal_c")
    ret.add_argument("--method", default="smr", help="uvm | smr | stmr (SMR then TMR: re-timed, tracked in MuJoCo)")
    ret.add_argument("--baseless", action="store_true", help="remove the source's base trajectory and rebuild it (§VIII-E)")
    ret.add_argument("--contacts", choices=CONTACT_SCHEDULES, default="cleaned",
                     help="stance schedule SMR follows: the source's labels plus the stance measured from its foot "
                          "keypoints (cleaned, default), the measured stance alone, or the labels as they are")
    ret.add_argument("--terrain", action="append", default=[], metavar="box:x,y,w,d,h",
                     help="a box on the floor (metres; repeatable)")
    ret.add_argument("--no-touchdowns", action="store_true",
                     help="keep the source schedule even if a foot reaches the ground during a flight (Algorithm 1 lines 17-22 off)")
    ret.add_argument("--flight", choices=("schedule", "exit"), default="schedule",
                     help="flight arcs: land at the next scheduled contact (default; keeps the schedule, high arcs on "
                          "slowed-down clips) or leave with the fitted exit velocity (the paper's; lands early)")
    ret.add_argument("--format", default=None, choices=IMPORT_FORMATS, help="force the source format")
    ret.add_argument("--out", required=True, help="output robot motion (.npz)")
    ret.add_argument("--json", action="store_true", help="print the metrics as JSON")
    from studio.cli_tmr import add_tmr_options

    add_tmr_options(ret, prefix="stmr: ")

    exp = sub.add_parser("export", help="export a robot motion (studio retarget) or a walk run (studio walk --out)")
    exp.add_argument("motion", help="a robot motion or walk-run .npz")
    exp.add_argument("--format", required=True, choices=EXPORT_FORMATS)
    exp.add_argument("--out", required=True, help="output file")
    exp.add_argument("--amp-full", action="store_true", help="amp-json: AMP_for_hardware's 61-value frames")
    exp.add_argument("--amp-leg-order", choices=("pybullet", "isaac"), default="pybullet",
                     help="--amp-full legs: pybullet FR, FL, RR, RL (AMP_for_hardware's loader reorders them; default) "
                          "or isaac FL, FR, RL, RR (STMR_RL's loader, whose reorder is commented out)")
    exp.add_argument("--fps", type=float, default=None, help="resample to this rate (lerp, root slerp), e.g. 30 or 50")
    exp.add_argument("--take", choices=("simulated", "reference"), default="simulated",
                     help="walk runs: the simulated walk (default) or the reference it tracked")


def _load_source(path: str, fmt: str | None):
    from engine.retarget.importers import import_source
    from engine.retarget.motion import MotionFormatError

    try:
        return import_source(Path(path), fmt)
    except MotionFormatError as exc:
        raise CliError(str(exc)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise CliError(f"{Path(path).name}: cannot read ({exc.__class__.__name__})") from None


def _check_out(out: str, suffixes: tuple[str, ...]) -> Path:
    path = Path(out)
    if path.suffix.lower() not in suffixes:
        raise CliError(f"--out {out}: expected a {' or '.join(suffixes)} file")
    if path.is_dir():
        raise CliError(f"--out {out}: is a directory")
    return path


def _write(out: Path, save) -> None:
    try:
        save(out)
    except OSError as exc:
        raise CliError(f"--out {out}: cannot write ({exc.strerror or exc.__class__.__name__})") from None


def cmd_import(args: argparse.Namespace) -> int:
    out = _check_out(args.out, (".npz",))
    motion = _load_source(args.src, args.format)
    _write(out, motion.save)
    src = motion.source
    print(f"{Path(args.src).name} → {out}: {motion.frames} frames at {motion.fps:g} fps ({motion.duration_s:.2f} s), "
          f"format {src.get('format')}, contacts {src.get('contact_from', 'source')}"
          + (f", legs {src['leg_order']} ({src['leg_order_from']})" if "leg_order" in src else ""))
    return 0


def _target_robot(name: str) -> str:
    from engine.retarget.quadruped.pipeline import QUADRUPEDS
    from engine.robot.config import RobotConfigError, load_robot_config

    try:
        cfg = load_robot_config(name)
    except RobotConfigError as exc:
        raise CliError(f"--robot {name}: {exc}") from None
    if cfg.kind != "quadruped":
        raise CliError(f"--robot {name}: expected a quadruped ({', '.join(QUADRUPEDS)}), {name} is a {cfg.kind}")
    return name


def cmd_retarget(args: argparse.Namespace) -> int:
    from engine.retarget.heightmap import parse_terrain
    from engine.retarget.quadruped.pipeline import METHODS, RetargetOptions, retarget_detailed
    from engine.retarget.quadruped.smr import SmrOptions

    methods = (*METHODS, "stmr")
    if args.method not in methods:
        raise CliError(f"--method {args.method}: expected one of {', '.join(methods)}")
    out = _check_out(args.out, (".npz",))
    robot = _target_robot(args.robot)
    stmr = args.method == "stmr"
    if stmr:  # every TMR option is checked before minutes of work
        from studio import cli_tmr

        settings = cli_tmr._settings(args)
        check_ray_address(args.address)
    try:
        heightmap = parse_terrain(args.terrain)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    source = _load_source(args.source, args.format)
    if stmr:
        from engine.retarget.quadruped.tmr.deformation import DeformationError, check_segments

        try:
            check_segments(settings.segments, source.frames, source.fps)
        except DeformationError as exc:
            raise CliError(f"{Path(args.source).name}: keypoints: {exc}") from None
    options = RetargetOptions(baseless=args.baseless, contacts=args.contacts, heightmap=heightmap, smr=SmrOptions(touchdowns=not args.no_touchdowns, land_on_schedule=args.flight == "schedule"))
    result = retarget_detailed(source, robot, "smr" if stmr else args.method, options)
    figures = result.motion.metrics
    motion = result.motion
    if stmr:
        from studio import cli_tmr

        dynamic = cli_tmr.run_tmr(result.motion, settings, args.address, args.parallel)
        if dynamic is None:
            return 130
        motion = dynamic.motion
        figures = stmr_figures(figures, dynamic.summary)
        motion.metrics = figures
    _write(out, motion.save)
    if args.json:
        print(json.dumps(figures, indent=1))
    elif stmr:
        print(f"{Path(args.source).name} → {robot} (stmr{', baseless' if args.baseless else ''}): SMR foot slide "
              f"{_mm(figures['foot_slide_mm'])}, contact IoU {figures['contact_iou']:.3f}; TMR α = {figures['alpha']} "
              f"({figures['duration_s']['before']} s → {figures['duration_s']['after']} s, {figures['bo_evaluations']} "
              f"evaluations), replay {'FELL' if figures['replay_fell'] else 'stays up'}, tracking "
              f"{figures['tracking_error_mm']} mm, DTW keypoint L1 {figures['dtw_keypoint_l1_pct']} % → {out}")
    else:
        print(f"{Path(args.source).name} → {robot} ({args.method}{', baseless' if args.baseless else ''}): "
              f"{figures['frames']} frames, foot slide {_mm(figures['foot_slide_mm'])}, contact IoU "
              f"{figures['contact_iou']:.3f}, penetration {figures['penetration_mm']:.2f} mm, keypoint error "
              f"{figures['keypoint_error_mm']:.1f} mm, {figures['frames_per_s']:.0f} frames/s → {out}")
    return 0


def stmr_figures(smr: dict, tmr: dict) -> dict:
    """SMR's figures (foot slide, IoU, … of the kinematic stage) plus TMR's: α, duration before/after, BO
    evaluations, open-loop replay fell, DTW keypoint L1 (%) and tracking error (mm) of the dynamic motion."""
    renamed = {"contact_iou": "replay_contact_iou", "wall_time_s": "tmr_wall_time_s", "robot": None}
    out = {**smr, "method": "stmr", "smr_wall_time_s": smr.get("wall_time_s")}
    out.pop("wall_time_s", None)
    # SMR's kinematic DTW (its keypoints against the UVM target, no physics) is not the tracked figure: one
    # ``dtw_keypoint_l1_pct`` (the open-loop replay's, measured as UVM's and SMR's replays are) and no look-alike
    if "dtw_keypoint_l1_percent" in out:
        out["smr_kinematic_dtw_pct"] = out.pop("dtw_keypoint_l1_percent")
    for key, value in tmr.items():
        name = renamed.get(key, key)
        if name:
            out[name] = value
    out["wall_time_s"] = round(float(out.get("smr_wall_time_s") or 0.0) + float(tmr.get("wall_time_s", 0.0)), 2)
    return out


def _mm(value) -> str:
    return "n/a (no contact longer than 0.5 s)" if value is None else f"{value:.3f} mm"


def cmd_export(args: argparse.Namespace) -> int:
    from engine.export import SUFFIXES, export_motion
    from engine.export.resample import check_fps
    from engine.export.unitree_csv import missing_joints
    from engine.retarget.motion import MotionFormatError
    from engine.walk_recording import load_run_motion

    out = _check_out(args.out, SUFFIXES[args.format])
    if args.fps is not None:
        try:
            check_fps(args.fps)
        except ValueError as exc:
            raise CliError(str(exc)) from None
    try:
        motion = load_run_motion(args.motion, args.take)
    except MotionFormatError as exc:
        raise CliError(str(exc)) from None
    if args.amp_full and args.format != "amp-json":
        raise CliError("--amp-full: only with --format amp-json")
    if args.amp_leg_order != "pybullet" and not args.amp_full:
        raise CliError("--amp-leg-order: only with --amp-full")
    if args.amp_full:
        from engine.robot.config import RobotConfigError, load_robot_config

        try:
            kind = load_robot_config(motion.robot).kind
        except RobotConfigError as exc:
            raise CliError(f"{Path(args.motion).name}: robot: {exc}") from None
        if kind != "quadruped" or len(motion.joint_names) != 12:
            raise CliError(f"{Path(args.motion).name}: robot: --amp-full expects a 12-joint quadruped, got {motion.robot}")
    if args.format == "beyondmimic-npz":
        from engine.robot.config import RobotConfigError, load_robot_config

        try:
            load_robot_config(motion.robot)
        except RobotConfigError as exc:
            raise CliError(f"{Path(args.motion).name}: robot: {exc}") from None
    result: dict = {}
    _write(out, lambda path: result.setdefault("motion", export_motion(motion, args.format, path,
                                                                        amp_full=args.amp_full,
                                                                        amp_leg_order=args.amp_leg_order, fps=args.fps)))
    written = result["motion"]
    if args.format in ("unitree-csv", "beyondmimic-npz") and missing_joints(motion):
        print(f"studio: warning: {Path(args.motion).name}: joints {', '.join(missing_joints(motion))} of "
              f"Unitree's {motion.robot} order are not in the motion; written as 0", file=sys.stderr)
    print(f"{Path(args.motion).name} → {out} ({args.format}"
          f"{f', 61-value AMP frames, legs {args.amp_leg_order}' if args.amp_full else ''}, "
          f"{written.frames} frames at {written.fps:g} fps)")
    return 0
