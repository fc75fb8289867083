"""``studio`` command line: serve the studio, list robots, run benchmarks.

Errors a user can cause (unknown robot, malformed file) print one line and exit 2.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Callable, NoReturn
from pathlib import Path

EXIT_USAGE = 2


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def check_ray_address(address: str | None) -> None:
    """``--address``: a Ray head that does not answer is one line (exit 2) within seconds, before any work."""
    if address is None:
        return
    from engine.ray_cluster import RayClusterError, check_address

    try:
        check_address(address)
    except RayClusterError as exc:
        raise CliError(str(exc)) from None


class _Parser(argparse.ArgumentParser):
    """Usage errors as ONE line (``studio walk: error: ...``), exit 2, like every other user error."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="studio", description="Motion Studio: author stylized walking gaits for robots.")
    sub = parser.add_subparsers(dest="subcommand", required=True)

    serve = sub.add_parser("serve", help="serve the studio in the browser")
    serve.add_argument("--robot", default=None, help="robot to open (default: g1)")
    serve.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    serve.add_argument("--port", type=int, default=8080)
    serve.add_argument("--shadows", action="store_true",
                       help="draw shadows (needs a GPU: with software WebGL the page draws 1.7-5x fewer frames: studio bench render)")
    serve.add_argument("--token", default=None, help="require this access token from browsers (env MOTION_STUDIO_TOKEN)")
    serve.add_argument("--no-rehearse-after-edits", dest="rehearse_after_edits", action="store_false",
                       help="do not walk the style through the sweep off screen after each edit (the Rehearsal "
                            "panel's checkbox; on by default: it uses a second CPU core at low priority)")

    sub.add_parser("robots", help="list the robot library")

    check = sub.add_parser("check", help="validate style files")
    check.add_argument("files", nargs="+", help="style files (JSON)")
    check.add_argument("--rehearse", action="store_true",
                       help="also walk each style through the sweep in physics (as `studio bench styles` does) and say "
                            "whether, when and where it falls (exit 1 when one falls)")
    check.add_argument("--duration", type=float, default=60.0, help="--rehearse: seconds of the sweep")

    plan = sub.add_parser("plan", help="run the gait planner headless and record the reference (npz)")
    plan.add_argument("--robot", default="g1")
    plan.add_argument("--style", default="neutral", help="a style name of the robot or a path to a style file")
    plan.add_argument("--command", default="forward", help="vx,vy,wz | stand | forward | sweep | keyframes.json")
    plan.add_argument("--duration", type=float, default=10.0, help="seconds to plan")
    plan.add_argument("--out", required=True, help="output .npz")

    walk = sub.add_parser("walk", help="walk a style headless in closed loop (MuJoCo + the full control stack)")
    walk.add_argument("--robot", default="g1")
    walk.add_argument("--style", default="neutral", help="a style name of the robot or a path to a style file")
    walk.add_argument("--command", default="forward", help="vx,vy,wz | stand | forward | sweep | keyframes.json")
    walk.add_argument("--duration", type=float, default=10.0, help="seconds of simulated time")
    walk.add_argument("--push", action="append", default=[], metavar="t,fx,fy,fz,dur",
                      help="push the pelvis at t for dur seconds with (fx, fy, fz) N, world frame; repeatable")
    walk.add_argument("--wbc", choices=("paper", "placo"), default="paper", help="whole-body controller")
    walk.add_argument("--state", choices=("truth", "estimated"), default="truth", help="state feedback source")
    walk.add_argument("--no-feedback", action="store_true", help="disable gait feedback (for comparison)")
    walk.add_argument("--out", default=None, help="write the recorded run (.npz): a robot motion with its reference "
                      "(studio export reads it)")
    walk.add_argument("--json", action="store_true", help="print the summary as JSON")

    from studio.cli_retarget import register as register_retarget

    register_retarget(sub)
    from studio.cli_library import add_parser as add_library_parser

    add_library_parser(sub)

    bench = sub.add_parser("bench", help="measure performance figures side by side")
    bench.add_argument("sections", nargs="*", help="sections to run (default: all)")
    bench.add_argument("--json", action="store_true", help="print JSON instead of a table")
    bench.add_argument("--minutes", type=float, default=1.0, help="soak: how long to drive the studio")
    bench.add_argument("--clients", type=int, default=4, help="soak: headless WebSocket clients")
    bench.add_argument("--tabs", type=int, default=2, help="soak: headless Chromium tabs rendering the studio")
    bench.add_argument("--tab-nice", type=int, default=0, help="soak: run the Chromium tabs at this niceness "
                       "(0-19; a user can lower their browser's priority without privileges)")

    from studio import cli_tmr

    cli_tmr.register(sub)

    from studio import cli_arms

    cli_arms.register(sub)

    from engine.bench.options import add_bench_options

    add_bench_options(bench)  # options of the closed-loop batch sections (styles, push)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.subcommand == "serve":
            return cmd_serve(args)
        if args.subcommand == "robots":
            return cmd_robots(args)
        if args.subcommand == "bench":
            return cmd_bench(args)
        if args.subcommand == "check":
            return cmd_check(args)
        if args.subcommand == "plan":
            return cmd_plan(args)
        if args.subcommand == "walk":
            return cmd_walk(args)
        if args.subcommand in ("import", "retarget", "export"):
            from studio import cli_retarget

            return getattr(cli_retarget, f"cmd_{args.subcommand}")(args)
        if args.subcommand in ("tmr", "retarget-batch"):
            from studio import cli_tmr

            return cli_tmr.cmd_tmr(args) if args.subcommand == "tmr" else cli_tmr.cmd_retarget_batch(args)
        if args.subcommand in ("train-arms", "puppet", "stream-bvh"):
            from studio import cli_arms

            return cli_arms.dispatch(args) or 0
        if args.subcommand == "library":
            from studio.cli_library import cmd_library

            return cmd_library(args)
    except CliError as exc:
        print(f"studio: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130
    return 0


def _config_error(exc: Exception) -> CliError:
    return CliError(str(exc))


def cmd_serve(args: argparse.Namespace) -> int:
    from engine.robot.config import DEFAULT_ROBOT, RobotConfigError, load_robot_config

    robot = args.robot or DEFAULT_ROBOT
    try:
        load_robot_config(robot)
        from engine.robot.model import load_robot

        load_robot(robot)  # builds the cache once, before the engine process needs it
    except RobotConfigError as exc:
        raise _config_error(exc) from None
    if not 0 < args.port < 65536:
        raise CliError(f"--port: expected 1..65535, got {args.port}")
    import socket

    with socket.socket() as probe:  # viser would silently take the next free port
        try:
            probe.bind((args.host, args.port))
        except OSError as exc:
            raise CliError(f"--port: {args.host}:{args.port} is not free ({exc.strerror}); "
                           "stop what uses it or pick another with --port") from None
    from studio.access import is_loopback, token_from_env
    from studio.app import serve

    token = args.token or token_from_env()
    if token is not None and not token.strip():
        raise CliError("--token: expected a non-empty token")
    if not is_loopback(args.host) and not token:
        print(f"studio: warning: --host {args.host}: anyone on the network can read and write styles and motions; "
              "pass --token TOKEN (or set MOTION_STUDIO_TOKEN) to require an access token", file=sys.stderr)
    serve(robot, args.host, args.port, token=token, shadows=args.shadows, rehearse_after_edits=args.rehearse_after_edits)
    return 0


def cmd_robots(args: argparse.Namespace) -> int:
    from engine.robot.config import RobotConfigError, robot_names, robots_dir
    from engine.robot.model import load_robot

    rows, errors = [], []
    for name in robot_names(robots_dir()):
        try:
            robot = load_robot(name)
        except RobotConfigError as exc:
            errors.append(str(exc))
            continue
        rows.append((name, robot.kind, str(robot.n_joints) if robot.config.simulated else "-", f"{robot.mass_kg:.2f}", f"{robot.height_m:.2f}",
                     robot.config.display_name))
    header = ("name", "kind", "actuated joints", "mass (kg)", "height (m)", "model")
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    for row in [header, *rows]:
        print("  ".join(cell.ljust(w) if i in (0, 1, 5) else cell.rjust(w) for i, (cell, w) in enumerate(zip(row, widths))).rstrip())
    for err in errors:
        print(f"studio: error: {err}", file=sys.stderr)
    return EXIT_USAGE if errors else 0


def cmd_check(args: argparse.Namespace) -> int:
    from engine.gait.style import StyleError, load_style

    if args.rehearse:
        from engine.gait.rehearsal import duration_problem

        problem = duration_problem(args.duration)
        if problem:
            raise CliError(problem)
    status = 0
    for f in args.files:
        try:
            style = load_style(f)
            print(f"{f}: ok", flush=True)
        except StyleError as exc:
            print(f"studio: error: {exc}", file=sys.stderr)
            status = EXIT_USAGE
            continue
        if args.rehearse:
            from engine.gait.rehearsal import rehearse
            from engine.robot.model import load_robot

            result = rehearse(load_robot(style.robot), style, args.duration)
            print(f"{f}: rehearsal: {result.message.replace('**', '')}", flush=True)
            if result.fell and status == 0:
                status = 1
    return status


def resolve_style(robot: str, style: str):
    """Load ``style`` (a name in styles/<robot>/ or a file path) for ``robot``; one-line errors."""
    from engine.gait.style import StyleError, load_style, styles_dir

    path = Path(style)
    if path.suffix != ".json":
        folder = styles_dir(robot)
        path = folder / f"{style}.json"
        if not path.is_file():
            known = sorted(p.stem for p in folder.glob("*.json"))
            raise CliError(f"unknown style {style!r} for {robot}; styles: {', '.join(known) or 'none'}")
    try:
        return load_style(path, expected_robot=robot)
    except StyleError as exc:
        raise CliError(str(exc)) from None


def _walk_inputs(args: argparse.Namespace, why_biped: str):  # noqa: ANN202 - (Style, CommandSchedule)
    """--robot (a biped), --duration, --style and --command of `studio plan` and `studio walk`."""
    from engine.gait.command_schedule import CommandError, parse_command
    from engine.robot.config import RobotConfigError, load_robot_config

    try:
        cfg = load_robot_config(args.robot)
    except RobotConfigError as exc:
        raise CliError(str(exc)) from None
    if cfg.kind != "biped":
        raise CliError(f"--robot: expected a biped ({why_biped}), {args.robot} is a {cfg.kind}")
    if not (args.duration > 0 and args.duration <= 3600):
        raise CliError(f"--duration: expected 0 < T ≤ 3600 s, got {args.duration}")
    style = resolve_style(args.robot, args.style)
    try:
        schedule = parse_command(args.command, style.velocities)
    except CommandError as exc:
        raise CliError(str(exc)) from None
    return style, schedule


def _npz_path(spec: str) -> Path:
    out = Path(spec)
    if out.suffix != ".npz":
        raise CliError(f"--out: expected a .npz file, got {spec!r}")
    folder = out.parent if str(out.parent) else Path(".")
    if not folder.is_dir() or not os.access(folder, os.W_OK) or out.is_dir():
        raise CliError(f"--out: expected a writable file in an existing folder, got {spec!r}")  # before the run
    return out


def _save_npz(out: Path, arrays: dict) -> None:
    """Compressed npz, written atomically (a recording is never left half-written)."""
    import io

    import numpy as np

    from engine.atomic_io import atomic_write_bytes

    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    try:
        atomic_write_bytes(out, buf.getvalue())
    except OSError as exc:  # full disk, folder removed meanwhile: nothing half-written (atomic), one line
        raise CliError(f"--out: could not write {out}: {exc.strerror or exc}") from None


def cmd_plan(args: argparse.Namespace) -> int:
    import numpy as np

    from engine.gait.offline_plan import run_plan
    from engine.robot.model import load_robot

    style, schedule = _walk_inputs(args, "the gait planner walks bipeds")
    out = _npz_path(args.out)
    arrays = run_plan(load_robot(args.robot), style, schedule, args.duration)
    _save_npz(out, arrays)
    n = len(arrays["t"])
    clamped = int(np.any(np.abs(arrays["command"] - arrays["command_requested"]) > 1e-9, axis=1).sum())
    print(f"{out}: {n} samples at 125 Hz, {args.duration:g} s, style {style.name} on {args.robot}"
          + (f"; command clamped to the style's limits in {clamped} samples" if clamped else ""))
    return 0


def cmd_walk(args: argparse.Namespace) -> int:
    import numpy as np

    from engine.robot.model import load_robot
    from engine.walk_runner import PushSpec, run_walk

    style, schedule = _walk_inputs(args, "the walking controller walks bipeds")
    try:
        pushes = [PushSpec.parse(p) for p in args.push]
    except ValueError as exc:
        raise CliError(str(exc)) from None
    out = _npz_path(args.out) if args.out else None
    v = style.velocities
    requested = np.abs(schedule.values).max(axis=0)
    limits = np.array([v.x_max_mps, v.y_max_mps, v.yaw_max_radps])
    clamped = bool(np.any(requested > limits + 1e-9))
    if clamped:
        print(f"studio: warning: the command exceeds the style's limits (vx {v.x_max_mps}, vy {v.y_max_mps} m/s, "
              f"wz {v.yaw_max_radps} rad/s); it is clamped", file=sys.stderr)
    summary, arrays = run_walk(load_robot(args.robot), style, schedule, args.duration, pushes, wbc=args.wbc,
                               state_source=args.state, feedback=not args.no_feedback, record=out is not None,
                               record_reference=out is not None, command_text=args.command)
    if out is not None:
        _save_npz(out, arrays)
    summary["command_clamped"] = clamped
    summary["command_limits"] = limits.tolist()
    if len(np.unique(schedule.values, axis=0)) == 1:  # a constant command: what was asked, what was walked
        summary["command_requested"] = schedule.values[0].tolist()
        summary["command_applied"] = np.clip(schedule.values[0], -limits, limits).tolist()
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        state = f"FELL at {summary['fall_time_s']:.2f} s" if summary["fell"] else "walked"
        print(f"{args.robot}/{style.name} ({args.wbc}, {args.state} state): {state}; {summary['sim_time_s']:.1f} s "
              f"simulated in {summary['wall_time_s']:.1f} s ({summary['real_time_factor']}x real time), "
              f"{summary['distance_m']:.2f} m; velocity RMSE {summary['velocity_rmse']}; stance slip "
              f"{summary['max_stance_slip_mm']} mm; CoP inside {summary['cop_inside_fraction']}")
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from engine.bench import BATCH_SECTIONS
    from engine.bench import SECTIONS as ENGINE_SECTIONS
    from engine.bench.options import run_section
    from studio.bench_edit import bench_edit_latency
    from studio.bench_engine import bench_engine
    from studio.bench_render import bench_render
    from studio.bench_soak import bench_soak

    SECTIONS: dict[str, Callable[..., list[dict]]] = {**ENGINE_SECTIONS, "edit": bench_edit_latency, "engine": bench_engine, "soak": bench_soak, "render": bench_render}  # noqa: N806 - the studio's on top
    sections = args.sections or [s for s in SECTIONS if s not in ("soak", "render") and s not in BATCH_SECTIONS]
    unknown = [s for s in sections if s not in SECTIONS]
    if unknown:
        raise CliError(f"unknown bench section {unknown[0]!r}; sections: {', '.join(SECTIONS)}")
    if not (0 < args.minutes <= 24 * 60) or not (0 <= args.clients <= 64) or not (0 <= args.tabs <= 8):
        raise CliError(f"--minutes/--clients/--tabs: expected 0 < M ≤ 1440, 0 ≤ C ≤ 64 and 0 ≤ T ≤ 8, "
                       f"got {args.minutes}, {args.clients}, {args.tabs}")
    if not 0 <= args.tab_nice <= 19:
        raise CliError(f"--tab-nice: expected a niceness 0 ≤ N ≤ 19, got {args.tab_nice}")
    weights_dir = getattr(args, "weights_dir", None)
    if weights_dir is not None and (not weights_dir.strip() or not Path(weights_dir).is_dir()):
        raise CliError(f"--weights-dir: expected the folder train-arms --out DIR/<robot>_lwl2 wrote into, "
                       f"got {weights_dir!r} (no such folder)")
    from engine.robot.config import RobotConfigError, load_robot_config

    try:  # (--robot: the robot of the styles, push and puppet sections)
        robot_kind = load_robot_config(args.robot).kind
    except RobotConfigError as exc:
        raise CliError(f"--robot: {exc}") from None
    bipeds_only = sorted({"styles", "push"} & set(sections))
    if bipeds_only and robot_kind != "biped":
        raise CliError(f"--robot: expected a biped for {' and '.join(bipeds_only)}, {args.robot} is a {robot_kind}")
    from engine.bench.options import check_style_options
    from engine.bench.retarget import check_clip_options

    problem = (check_style_options(args.n, args.extent, args.duration, args.phases, args.n_per_kg,
                                   getattr(args, "repeat", 1))
               or check_clip_options(args.clips, args.budget, args.robots))
    if problem:
        raise CliError(problem)
    check_ray_address(args.address)
    from engine.ray_cluster import RayClusterError

    rows: list[dict] = []
    for section in sections:
        try:
            rows.extend(run_section(SECTIONS[section], args))
        except RayClusterError as exc:  # a cluster that answers but cannot be joined (e.g. its token)
            raise CliError(str(exc)) from None
    if args.json:
        print(json.dumps({"rows": rows, "cpu_count": os.cpu_count()}, indent=1))
        return 0
    by_section: dict[str, list[dict]] = {}
    for row in rows:
        by_section.setdefault(row["section"], []).append(row)
    from engine.bench import TEXT_TABLES

    for section, srows in by_section.items():
        keys = [k for k in srows[0] if k != "section"]
        print(f"[{section}]")
        if section in TEXT_TABLES:
            print(TEXT_TABLES[section](srows))
            continue
        cells = [[str(r.get(k, "")) for k in keys] for r in srows]
        widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]
        print("  ".join(k.rjust(w) for k, w in zip(keys, widths)))
        for c in cells:
            print("  ".join(v.rjust(w) for v, w in zip(c, widths)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
