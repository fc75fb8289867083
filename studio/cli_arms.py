"""`studio train-arms`, `studio puppet`, `studio stream-bvh`: human mocap → humanoid upper body (LWL2).

Bodies of the subcommands registered in studio/cli.py. User errors raise CliError (one line, exit 2,
nothing written).
"""

from __future__ import annotations

import argparse
import json
import socket
import sys
import time
from pathlib import Path
from urllib.parse import urlparse

import numpy as np

from studio.cli import CliError

ARM_ROBOTS = ("g1", "talos")


def register(sub) -> None:  # noqa: ANN001 - argparse's private subparsers type
    train = sub.add_parser("train-arms", help="train LWL2 (mocap → upper body) for a humanoid")
    train.add_argument("--robot", choices=ARM_ROBOTS, required=True)
    train.add_argument("--quick", action="store_true", help="tiny datasets and networks (a smoke run, < 1 min)")
    train.add_argument("--out", default=None, help="weights path without suffix (default: the shipped weights folder)")
    train.add_argument("--seed", type=int, default=0)
    train.add_argument("--resume", action="store_true",
                       help="continue an interrupted run from its checkpoint (same options; default: start afresh)")
    train.add_argument("--checkpoint-dir", default=None,
                       help="where the resumable state lives (default: ~/.cache/motion-studio/train-arms/<out>-<hash>)")

    puppet = sub.add_parser("puppet", help="retarget a BVH clip onto a humanoid's arms and torso (LWL2)")
    puppet.add_argument("--robot", choices=ARM_ROBOTS, required=True)
    puppet.add_argument("--bvh", required=True, help="BVH clip (CMU or Bandai Namco naming)")
    puppet.add_argument("--out", required=True, help="output .npz (e.g. motions/g1/wave.npz)")
    puppet.add_argument("--weights", default=None, help="trained weights (default: the shipped ones for --robot)")
    puppet.add_argument("--fps", type=float, default=30.0, help="output rate: the clip is decimated to at most this")
    puppet.add_argument("--json", action="store_true", help="print the summary as JSON")
    puppet.add_argument("--refine-iters", type=int, default=None,
                        help="refinement steps after LWR (default 3; 0: the paper's LWL2 alone)")

    stream = sub.add_parser("stream-bvh", help="replay a BVH clip in real time as live mocap datagrams (UDP JSON)")
    stream.add_argument("bvh", help="BVH clip")
    stream.add_argument("--to", required=True, help="udp://HOST:PORT")
    stream.add_argument("--fps", type=float, default=60.0, help="datagram rate: the clip is decimated to at most this")
    stream.add_argument("--loop", action="store_true", help="replay forever")
    stream.add_argument("--max-frames", type=int, default=0, help="stop after this many datagrams (0: the whole clip)")


def dispatch(args: argparse.Namespace) -> int | None:
    if args.subcommand == "train-arms":
        return cmd_train_arms(args)
    if args.subcommand == "puppet":
        return cmd_puppet(args)
    if args.subcommand == "stream-bvh":
        return cmd_stream_bvh(args)
    return None


class _ProgressBar:
    def __init__(self, stream=sys.stderr):
        self.stream, self.last = stream, 0.0

    def __call__(self, stage: str, i: int, n: int, extra: str = "") -> None:
        now = time.monotonic()
        if i < n and now - self.last < 0.2:
            return
        self.last = now
        width = 30
        fill = int(width * i / max(n, 1))
        self.stream.write(f"\r{stage:>18} [{'#' * fill}{'.' * (width - fill)}] {i}/{n} {extra}"[:150].ljust(150))
        if i >= n:
            self.stream.write("\n")
        self.stream.flush()


def cmd_train_arms(args: argparse.Namespace) -> int:
    from engine.retarget.humanoid_arm.training import ArmTrainingPlan, train_arms

    plan = ArmTrainingPlan.quick() if args.quick else ArmTrainingPlan.full(args.robot)
    if args.seed != 0:
        from dataclasses import replace

        plan = replace(plan, train=replace(plan.train, seed=args.seed))
    out = Path(args.out) if args.out else None
    if out is not None and out.suffix in (".json", ".safetensors"):
        out = out.with_suffix("")
    from engine.retarget.humanoid_arm.metadata import weights_path
    from engine.retarget.humanoid_arm.training import default_checkpoint_dir

    ckpt_dir = Path(args.checkpoint_dir) if args.checkpoint_dir else default_checkpoint_dir(out or weights_path(args.robot))
    try:
        summary = train_arms(args.robot, plan, out, _ProgressBar(), checkpoint_dir=ckpt_dir, resume=args.resume)
    except KeyboardInterrupt:
        print(f"\nstudio: train-arms cancelled; no weights written; continue with --resume (state in {ckpt_dir})",
              file=sys.stderr)
        return 130
    except ValueError as exc:
        raise CliError(str(exc)) from None
    print(json.dumps(summary, indent=1))
    return 0


def _load_clip(path_spec: str):
    """The clip and its key points; CliError (one line naming the file) for anything unusable, including a
    skeleton whose arm joints coincide (its poses would be zero vectors)."""
    import numpy as np

    from engine.retarget.humanoid_arm.pose15 import bvh_points, degenerate_frame
    from engine.retarget.importers.bvh import BvhError, load_bvh

    path = Path(path_spec)
    if not path.is_file():
        raise CliError(f"{path_spec}: no such BVH file")
    try:
        motion = load_bvh(path)
        with np.errstate(all="ignore"):  # overflowing coordinates become NaN, refused below
            points = bvh_points(motion)
            bad = degenerate_frame(points.pose15())
    except BvhError as exc:
        raise CliError(str(exc)) from None
    if bad is not None:
        raise CliError(f"{path.name}: MOTION: frame {bad}: expected a skeleton, got coincident arm joints (degenerate)")
    return motion, points


def cmd_puppet(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.suffix != ".npz":
        raise CliError(f"--out: expected a .npz file, got {args.out!r}")
    if not (0 < args.fps <= 1000):
        raise CliError(f"--fps: expected 0 < fps ≤ 1000, got {args.fps}")
    motion, points = _load_clip(args.bvh)
    poses = points.pose15()
    stride = max(1, int(round(points.fps / args.fps)))
    poses = poses[::stride]
    from engine.retarget.humanoid_arm.metadata import weights_path

    weights = Path(args.weights) if args.weights else weights_path(args.robot)
    try:
        _check_metadata(weights, args.robot)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    from engine.retarget.humanoid_arm.ik import arm_errors_m
    from engine.retarget.humanoid_arm.puppeteer import ArmRetargeter

    try:
        from engine.retarget.humanoid_arm.puppeteer import REFINE_ITERS

        refine = REFINE_ITERS if args.refine_iters is None else args.refine_iters
        if not 0 <= refine <= 100:
            raise CliError(f"--refine-iters: expected 0..100, got {refine}")
        arms = ArmRetargeter.load(args.robot, Path(args.weights) if args.weights else None, refine_iters=refine)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    n = len(poses)
    q = np.empty((n, arms.ub.n))
    ks = np.empty(n, dtype=np.int8)
    transitions = np.empty(n, dtype="U6")
    times = np.empty(n)
    hand = np.empty(n)
    elbow = np.empty(n)
    free = np.empty(n, dtype=bool)
    for i, p in enumerate(poses):
        step = arms.retarget(p)
        q[i], ks[i], transitions[i], times[i] = step.x, step.k, step.transition, step.inference_s
        hand[i], elbow[i] = arm_errors_m(arms.ub, step.x, p)
        free[i] = arms.capsules.is_free(step.x)
    fps = points.fps / stride
    from studio.cli import _save_npz

    _save_npz(out, {"t": np.arange(n) / fps, "fps": np.array(fps), "robot": np.array(args.robot),
                    "joint_names": np.array(arms.joint_names), "q": q, "pose15": poses, "k": ks,
                    "transition": transitions, "collision_free": free, "hand_error_m": hand, "elbow_error_m": elbow,
                    "source": np.array(Path(args.bvh).name), "skeleton": np.array(points.skeleton)})
    summary = {
        "out": str(out), "robot": args.robot, "source": Path(args.bvh).name, "skeleton": points.skeleton,
        "frames": n, "fps": round(fps, 3), "collision_free_fraction": round(float(free.mean()), 4),
        "hand_error_mm": round(float(hand.mean() * 1000), 1), "elbow_error_mm": round(float(elbow.mean() * 1000), 1),
        "inference_us": {"median": round(float(np.median(times) * 1e6), 1), "p99": round(float(np.percentile(times, 99) * 1e6), 1)},
        "graph_fallbacks": arms.graph_fallbacks, "holds": arms.holds, "refine_iters": arms.refine_iters,
        "k_counts": {str(k): int((ks == k).sum()) for k in (1, 2, 3)},
    }
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(f"{out}: {n} frames at {fps:g} fps on {args.robot}; collision-free {summary['collision_free_fraction']:.1%}; "
              f"hand error {summary['hand_error_mm']} mm, elbow {summary['elbow_error_mm']} mm; inference median "
              f"{summary['inference_us']['median']} µs, p99 {summary['inference_us']['p99']} µs; "
              f"{arms.graph_fallbacks} graph steps, {arms.holds} holds")
    return 0


def _check_metadata(path: Path, robot: str) -> None:
    """The weights' robot, checked from the JSON alone (no torch import for a wrong file)."""
    from engine.retarget.humanoid_arm.metadata import check_metadata

    check_metadata(path.with_suffix("") if path.suffix in (".json", ".safetensors") else path, robot)


def _udp_target(spec: str) -> tuple[str, int]:
    url = urlparse(spec)
    if url.scheme != "udp" or not url.hostname or url.port is None:
        raise CliError(f"--to: expected udp://HOST:PORT, got {spec!r}")
    if not 0 < url.port < 65536:
        raise CliError(f"--to: expected a port 1..65535, got {url.port}")
    return url.hostname, url.port


def cmd_stream_bvh(args: argparse.Namespace) -> int:
    from engine.retarget.humanoid_arm.live import datagrams_from_points

    target = _udp_target(args.to)
    if not (0 < args.fps <= 1000):
        raise CliError(f"--fps: expected 0 < fps ≤ 1000, got {args.fps}")
    _, points = _load_clip(args.bvh)
    stride = max(1, int(round(points.fps / args.fps)))
    sent = 0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        try:
            while True:
                t0 = time.perf_counter()
                for t_s, payload in datagrams_from_points(points, stride=stride):
                    delay = t0 + t_s - time.perf_counter()
                    if delay > 0:
                        time.sleep(delay)  # real-time pacing of the replay
                    sock.sendto(payload, target)
                    sent += 1
                    if args.max_frames and sent >= args.max_frames:
                        break
                if not args.loop or (args.max_frames and sent >= args.max_frames):
                    break
        except OSError as exc:
            raise CliError(f"--to {args.to}: {exc.strerror or exc}") from None
    print(f"{Path(args.bvh).name}: {sent} datagrams to {args.to} at {points.fps / stride:g} Hz", file=sys.stderr)
    return 0
