"""``studio`` command line: serve the studio, list robots, run benchmarks.

Errors a user can cause (unknown robot, malformed file) print one line and exit 2.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

EXIT_USAGE = 2


class CliError(Exception):
    """A user-facing error: printed as one line, exit status 2."""


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="studio", description="Motion Studio: author stylized walking gaits for robots.")
    sub = parser.add_subparsers(dest="command", required=True)

    serve = sub.add_parser("serve", help="serve the studio in the browser")
    serve.add_argument("--robot", default=None, help="robot to open (default: g1)")
    serve.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1: this machine only)")
    serve.add_argument("--port", type=int, default=8080)

    sub.add_parser("robots", help="list the robot library")

    bench = sub.add_parser("bench", help="measure performance figures side by side")
    bench.add_argument("sections", nargs="*", help="sections to run (default: all)")
    bench.add_argument("--json", action="store_true", help="print JSON instead of a table")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "serve":
            return cmd_serve(args)
        if args.command == "robots":
            return cmd_robots(args)
        if args.command == "bench":
            return cmd_bench(args)
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
    from studio.app import serve

    serve(robot, args.host, args.port)
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


def cmd_bench(args: argparse.Namespace) -> int:
    from engine.bench import SECTIONS

    sections = args.sections or list(SECTIONS)
    unknown = [s for s in sections if s not in SECTIONS]
    if unknown:
        raise CliError(f"unknown bench section {unknown[0]!r}; sections: {', '.join(SECTIONS)}")
    rows: list[dict] = []
    for section in sections:
        rows.extend(SECTIONS[section]())
    if args.json:
        print(json.dumps({"rows": rows, "cpu_count": os.cpu_count()}, indent=1))
        return 0
    by_section: dict[str, list[dict]] = {}
    for row in rows:
        by_section.setdefault(row["section"], []).append(row)
    for section, srows in by_section.items():
        keys = [k for k in srows[0] if k != "section"]
        print(f"[{section}]")
        cells = [[str(r.get(k, "")) for k in keys] for r in srows]
        widths = [max(len(k), *(len(c[i]) for c in cells)) for i, k in enumerate(keys)]
        print("  ".join(k.rjust(w) for k, w in zip(keys, widths)))
        for c in cells:
            print("  ".join(v.rjust(w) for v, w in zip(c, widths)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
