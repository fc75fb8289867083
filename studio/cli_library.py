"""``studio library``: a gait library over a velocity grid, one closed-loop walk per cell, on Ray.

The body lives in :mod:`engine.gait_library`; this module checks the arguments (one line, exit 2,
nothing written on bad input) and prints the progress bar and the result.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_parser(sub) -> None:  # noqa: ANN001 - argparse's subparsers action
    lib = sub.add_parser("library", help="run a gait library: one closed-loop walk per grid velocity (on Ray)")
    lib.add_argument("--robot", default="g1")
    lib.add_argument("--style", default="neutral", help="a style name of the robot or a path to a style file")
    lib.add_argument("--grid", required=True, metavar="vx=LO:HI:N,vy=LO:HI:N,wz=LO:HI:N",
                     help="velocity grid; an axis may be one value (wz=0) or left out (0)")
    lib.add_argument("--duration", type=float, default=10.0, help="seconds of simulated walking per cell")
    lib.add_argument("--out", required=True, help="library folder (created; a second run resumes it)")
    lib.add_argument("--address", default=None, help="Ray cluster address (default: a local Ray)")
    lib.add_argument("--workers", type=int, default=None, help="cells run at once (default: every CPU Ray has)")
    lib.add_argument("--export", default="", metavar="FMT[,FMT]",
                     help="also export every cell (simulated and reference) as unitree-csv, beyondmimic-npz, amp-json")
    lib.add_argument("--fps", type=float, default=None, help="--export: resample to this rate (e.g. 30 or 50)")
    lib.add_argument("--json", action="store_true", help="print the index as JSON at the end")


def cmd_library(args: argparse.Namespace) -> int:
    from engine.gait.style import style_to_json_dict
    from engine.gait_library import GridError, LibraryError, LibraryRun, parse_grid, run_library, text_progress
    from studio.cli import CliError, _walk_inputs, check_ray_address

    try:
        grid = parse_grid(args.grid)
    except GridError as exc:
        raise CliError(str(exc)) from None
    formats = [f.strip() for f in args.export.split(",") if f.strip()]
    from engine.export import FORMATS

    for fmt in formats:
        if fmt not in FORMATS:
            raise CliError(f"--export: {fmt}: expected formats among {', '.join(FORMATS)}")
    if args.fps is not None:
        from engine.export.resample import check_fps

        try:
            check_fps(args.fps)
        except ValueError as exc:
            raise CliError(str(exc)) from None
        if not formats:
            raise CliError("--fps: only with --export")
    if args.workers is not None and args.workers < 1:
        raise CliError(f"--workers: expected at least 1, got {args.workers}")
    args.command = "stand"  # each cell makes its own command; _walk_inputs checks robot, duration, style
    style, _ = _walk_inputs(args, "the walking controller walks bipeds")
    v = style.velocities
    limits = {"vx": v.x_max_mps, "vy": v.y_max_mps, "wz": v.yaw_max_radps}
    for axis in grid.axes:
        if max(abs(axis.low), abs(axis.high)) > limits[axis.name] + 1e-9:
            print(f"studio: warning: --grid: {axis.name} beyond the style's limit ±{limits[axis.name]:g}; "
                  "those cells walk clamped commands", file=sys.stderr)
    check_ray_address(args.address)
    run = LibraryRun(args.robot, style.name, style_to_json_dict(style), grid, float(args.duration), Path(args.out))
    try:
        run.check_folder()
        index = run_library(run, address=args.address, workers=args.workers, progress=text_progress(),
                            export_formats=formats, export_fps=args.fps)
    except LibraryError as exc:
        raise CliError(str(exc)) from None
    if args.json:
        print(json.dumps({k: v for k, v in index.items() if k != "cells"} | {"cells": index["cells"]}, indent=1))
    else:
        fell = sum(c["fell"] for c in index["cells"])
        print(f"{args.out}: {index['cells_done']}/{index['cells_total']} cells ({index['ran']} run, "
              f"{index['skipped']} already done) in {index['wall_time_s']:.1f} s; {fell} fell; "
              f"index.json and summary.png written"
              + (f"; {index['exported']} exported files written, {index['exports_kept']} kept, in {args.out}/exports"
                 if formats else ""))
    return 0
