"""Command-line options of the bench sections that run batches of closed-loop runs (``styles``, ``push`` on Ray;
``retarget``'s and ``tmr-clips``' tracking): kept here so ``studio/cli.py`` only registers them."""

from __future__ import annotations

import argparse
import inspect
import math
from collections.abc import Callable


STYLE_SPACES = ("validated", "reachable")  # what the styles section draws from (engine/bench/styles.py style_jobs)


def add_random_style_options(parser: argparse.ArgumentParser, n: int = 40, seed: int = 0, extent: float = 0.3,
                             duration_s: float = 60.0) -> None:
    """Which of ``studio bench styles``' random styles a tool walks again: the bench's robot, ``--n``, ``--seed``,
    ``--extent`` and ``--duration`` (style i is the same style as in the bench run with those options)."""
    parser.add_argument("--robot", default="g1")
    parser.add_argument("--n", type=int, default=n, help="as the bench's --n")
    parser.add_argument("--seed", type=int, default=seed, help="as the bench's --seed")
    parser.add_argument("--extent", type=float, default=extent, help="as the bench's --extent")
    parser.add_argument("--space", choices=STYLE_SPACES, default=STYLE_SPACES[0], help="as the bench's --space")
    parser.add_argument("--duration", type=float, default=duration_s, help="seconds of the sweep")


def check_style_options(n: int, extent: float, duration_s: float, phases: int, n_per_kg: float,
                        repeat: int = 1) -> str | None:
    """The one-line complaint about the styles / push sections' ``--n``, ``--extent``, ``--duration`` (puppet's too),
    ``--phases``, ``--n-per-kg`` or ``--repeat``, or None."""
    if not 1 <= repeat <= 20:
        return f"--repeat: expected 1 ≤ walks per style ≤ 20, got {repeat}"
    if not 1 <= n <= 10_000:
        return f"--n: expected 1 ≤ styles ≤ 10000, got {n}"
    if not (math.isfinite(extent) and 0.0 < extent <= 1.0):
        return f"--extent: expected a share 0 < E ≤ 1 of each validated range, got {extent}"
    if not (math.isfinite(duration_s) and 0.0 < duration_s <= 600.0):
        return f"--duration: expected 0 < seconds ≤ 600, got {duration_s}"
    if not 1 <= phases <= 64:
        return f"--phases: expected 1 ≤ phases ≤ 64, got {phases}"
    if not (math.isfinite(n_per_kg) and 0.0 <= n_per_kg <= 20.0):
        return f"--n-per-kg: expected 0 ≤ N/kg ≤ 20, got {n_per_kg}"
    return None


def add_bench_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--robot", default="g1", help="robot of the styles/push sections")
    parser.add_argument("--style", default=None, help="style file of the push section (default: the robot's neutral)")
    parser.add_argument("--n", type=int, default=40, help="styles: how many random styles")
    parser.add_argument("--seed", type=int, default=0, help="styles: random seed")
    parser.add_argument("--duration", type=float, default=60.0, help="styles: seconds of the sweep per style")
    parser.add_argument("--extent", type=float, default=1.0,
                        help="styles: share of each validated range drawn around neutral (1: the whole range)")
    parser.add_argument("--space", choices=STYLE_SPACES, default=STYLE_SPACES[0],
                        help="styles: draw over the validated space, or over its part the legs reach (each sample "
                             "drawn again while the feasibility check finds a foot out of reach or in the floor)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="styles: walk each style this many times, the k-th after a nudge of 0.01 N·s while it "
                             "stands (1 N for 10 ms at 0.5 s, a direction per k): how many of a style's walks fall")
    parser.add_argument("--phases", type=int, default=16, help="push: gait phases per direction")
    parser.add_argument("--n-per-kg", type=float, default=1.5, help="push: force per kg of robot mass")
    parser.add_argument("--address", default=None, help="Ray cluster address (default: a local Ray)")
    parser.add_argument("--out-dir", default=None, help="results folder (resumable; default under ~/.cache/motion-studio)")
    parser.add_argument("--clips", default=None, help="retarget, tmr-clips: comma-separated clips (default: all six)")
    parser.add_argument("--robots", default=None,
                        help="retarget, tmr-clips: comma-separated quadrupeds (default: go1,a1,go2,b1,anymal_c for the "
                             "kinematic tables, go1,a1,anymal_c for UVM / SMR / STMR)")
    parser.add_argument("--budget", type=int, default=None,
                        help="retarget, tmr-clips: TMR's BO evaluations per clip (default 6)")
    parser.add_argument("--weights-dir", default=None,
                        help="arms: a folder of trained <robot>_lwl2.* weights (default: the shipped ones)")
    parser.add_argument("--kinematic", action="store_true",
                        help="retarget: the kinematic UVM / SMR tables only (no tracking in MuJoCo, no STMR)")


def call_with_known(function: Callable[..., list[dict]], options: dict) -> list[dict]:
    """Call ``function`` with the options it declares as keyword parameters (all of them if it takes
    ``**options``)."""
    params = inspect.signature(function).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return function(**options)
    return function(**{k: v for k, v in options.items() if k in params})


def run_section(section: Callable[..., list[dict]], args: argparse.Namespace) -> list[dict]:
    """Call a section with the command-line options it declares as keyword parameters."""
    mapping = {"minutes": args.minutes, "clients": args.clients, "tabs": getattr(args, "tabs", 2), "tab_nice": getattr(args, "tab_nice", 0),
               "robot": args.robot,
               "style": args.style, "n": args.n, "seed": args.seed, "duration_s": args.duration, "phases": args.phases, "extent": args.extent,
               "space": getattr(args, "space", "validated"), "repeat": getattr(args, "repeat", 1),
               "n_per_kg": args.n_per_kg, "address": args.address, "out_dir": args.out_dir,
               "clip_names": getattr(args, "clips", None), "bo_budget": getattr(args, "budget", None),
               "robot_names": getattr(args, "robots", None), "weights_dir": getattr(args, "weights_dir", None),
               # retarget's UVM / SMR / STMR comparison (minutes per clip) when the section is named, not in the
               # default run of every section
               "tracked": bool(getattr(args, "sections", None)) and not getattr(args, "kinematic", False)}
    return call_with_known(section, mapping)
