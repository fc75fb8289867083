"""Rehearsal: walk the style through the sweep in physics, off screen, before the animator presses Test.

The edit-time check (:mod:`engine.gait.feasibility`) reads the reference and is cheap, but what it cannot see —
falls that begin in the closed loop (the CoM lagging the MPC's plan, the step adjustment running away) — only a
simulation shows. A rehearsal is that simulation: the same closed-loop walk as ``studio bench styles`` (the
``sweep`` command: stand, forward fast, back, strafe left/right, turn left/right, each with its ramps and pauses;
the same controller, :func:`engine.walk_runner.run_walk`), so its verdict is the benchmark's verdict for this
style. It costs what the walk costs (G1: about half a CPU-second per simulated second on a 2-core machine); the
studio runs it in a separate process at low priority and shows its progress.

When the walk falls, the recording says where in words an animator can act on: the sample the walk was
following (the largest blend weight), the command, the phase of that sample's cycle (from left liftoff, as the
edit-time check counts it), and how the fall began — the first moment in the last seconds where the body left
the MPC's plan by :data:`DRIFT_M` (behind, ahead or beside it) or a foot on the ground started sliding. When it
walks, the stance slip and the share of time the centre of pressure stays inside the feet (the benchmark's
"clean" bars) are reported too.

Several walks (``walks`` > 1): the first is the benchmark's, each other one is nudged once while the robot stands
(``PushSpec.nudge``: 0.01 N·s, physically nothing). Many random styles sit at a margin where that is enough to
turn a fall into a walk or a walk into a fall (README "Falls at a margin"), so one walk's verdict can be luck; the
verdict then says in how many of the walks the style fell, and describes the first fall.

``python -m engine.gait.rehearsal --robot g1 --style FILE [--duration S] [--walks K]`` prints one JSON object per
line: ``{"progress_s": t}`` as the walks go (t counts over all of them), ``{"walk": {...}}`` with the verdict so
far after each walk but the last, then ``{"result": {...}}``. A bad style file: one line on stderr, exit 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import asdict, dataclass, replace
from typing import Callable

import numpy as np

from engine.gait.style import SIDES, Style
from engine.gait.velocity_sampler import SAMPLE_NAMES
from engine.robot.model import RobotModel

SWEEP_DURATION_S = 60.0  # `studio bench styles`' default sweep length
CLEAN_SLIP_MM = 2.0  # issue 13's bars for a walk that is not only upright but clean
CLEAN_COP_INSIDE = 0.995
DRIFT_M = 0.03  # the body this far from the MPC's plan: the fall has begun
SLIDE_M = 0.01  # a foot on the ground this far from where it landed: sliding
LOOKBACK_S = 4.0  # how far before the fall to look for its beginning
PROGRESS_PERIOD_S = 0.5  # simulated seconds between progress reports
MAX_DURATION_S = 600.0  # the longest rehearsal the command line and the studio accept
MOVING_MPS = 0.05  # a command at least this fast: drift is told along / across the direction of travel
MAX_WALKS = 10
#: Both feet on the ground, at least one rolled on its heel or toe, and the body this far outside the support their
#: grounded corners span for at least EDGES_S: the style stands the robot where nothing under it can hold it.
#: (Walkers pass through such supports for a few hundredths of a second; stumbly, reachable-0-17, stood 0.33 s on
#: both toes with its body behind them before it fell backward.)
EDGES_S = 0.15
#: How a fall began (:func:`_onset`), for tables: the feet stood on their edges with the body outside them, a foot in
#: support slid, the body fell behind / ran ahead of its plan along the walk or drifted across it, or (standing or
#: turning in place) it drifted front to back / sideways.
ONSET_KINDS = ("edges", "slide", "behind", "ahead", "across", "front-back", "sideways")


@dataclass(frozen=True)
class RehearsalResult:
    fell: bool
    fall_time_s: float | None
    duration_s: float
    sample: str | None  # the sample the walk was following when it fell
    phase_pct: float | None  # of that sample's cycle, from left liftoff
    command: tuple[float, float, float] | None  # vx (m/s), vy (m/s), wz (rad/s) at the fall
    onset_time_s: float | None  # when the fall began (see the module docstring)
    max_stance_slip_mm: float
    cop_inside_fraction: float | None
    message: str  # what the animator reads
    walks: int = 1  # walks rehearsed (the first the benchmark's, the others nudged)
    falls: int = 0  # of them, how many fell (the fields above describe the first that fell, else the worst walk)
    recovery_time_s: float = 0.0  # how long the walk fell back toward the neutral gait to keep its balance
    recovery_mean_share: float = 0.0  # how far toward neutral, on average over that time
    onset_kind: str | None = None  # how the fall began: one of ONSET_KINDS (None: no fall, or not seen)

    @property
    def clean(self) -> bool:
        return (not self.fell and self.max_stance_slip_mm < CLEAN_SLIP_MM
                and self.cop_inside_fraction is not None and self.cop_inside_fraction >= CLEAN_COP_INSIDE)

    def to_dict(self) -> dict:
        return {**asdict(self), "clean": self.clean}


def rehearse(robot: RobotModel, style: Style, duration_s: float = SWEEP_DURATION_S,
             progress: Callable[[float], None] | None = None, walks: int = 1,
             on_walk: Callable[[RehearsalResult], None] | None = None) -> RehearsalResult:
    """Walk ``style`` through the sweep for ``duration_s`` in closed loop, ``walks`` times (the k-th nudged once
    while standing); ``progress(t_s)`` is called every :data:`PROGRESS_PERIOD_S` of simulated time, counted over all
    the walks (raise from it to stop the rehearsal); ``on_walk(verdict so far)`` after each walk but the last."""
    from engine.gait.command_schedule import parse_command
    from engine.walk_runner import PushSpec, run_walk

    problem = duration_problem(duration_s, "duration_s") or walks_problem(walks, "walks")
    if problem:
        raise ValueError(problem)
    schedule = parse_command("sweep", style.velocities)
    results: list[RehearsalResult] = []
    for k in range(walks):
        pushes = () if k == 0 else (PushSpec.nudge(k, walks),)
        offset = k * duration_s
        report = None if progress is None else (lambda t_s, offset=offset: progress(offset + t_s))
        summary, rec = run_walk(robot, style, schedule, duration_s, pushes, record=True, progress=report,
                                progress_period_s=PROGRESS_PERIOD_S)
        results.append(describe(summary, rec, duration_s))
        if on_walk is not None and k + 1 < walks:
            on_walk(combine(results))
    return combine(results)


def combine(results: list[RehearsalResult]) -> RehearsalResult:
    """One verdict for several walks of a style: the first fall if any walk fell (with how many did), else the first
    walk's."""
    fallen = [r for r in results if r.fell]
    first = fallen[0] if fallen else results[0]
    n = len(results)
    if n == 1:
        return replace(first, falls=int(first.fell))
    if fallen:
        message = (f"falls in {len(fallen)} of {n} walks (each after a nudge of nothing while standing)"
                   + (": the first " if len(fallen) > 1 else ": it ") + first.message)
        return replace(first, message=message, walks=n, falls=len(fallen))
    # None fell: the worst figures over the walks (one walk that slid is enough to say so).
    slip = max(r.max_stance_slip_mm for r in results)
    cops = [r.cop_inside_fraction for r in results if r.cop_inside_fraction is not None]
    cop = min(cops) if cops else None
    longest = max(results, key=lambda r: r.recovery_time_s)
    text = _walk_text(slip, cop, first.duration_s, longest.recovery_time_s, longest.recovery_mean_share)
    message = f"{text} (the worst of {n} walks, each after a nudge of nothing while standing)"
    return replace(first, max_stance_slip_mm=slip, cop_inside_fraction=cop, message=message, walks=n, falls=0,
                   recovery_time_s=longest.recovery_time_s, recovery_mean_share=longest.recovery_mean_share)


def _walk_text(slip_mm: float, cop: float | None, duration_s: float, recovery_s: float, recovery_share: float) -> str:
    """A walk that did not fall, in an animator's words: clean, or what was not."""
    problems = []
    if slip_mm >= CLEAN_SLIP_MM:
        problems.append(f"a foot on the ground slides up to {slip_mm:.1f} mm")
    if cop is not None and cop < CLEAN_COP_INSIDE:
        problems.append(f"the feet roll onto their edges {100 * (1 - cop):.1f} % of the time")
    text = f"walks the {duration_s:.0f} s sweep without falling"
    text += (": " + " and ".join(problems) + " (a real robot may slip or stumble)") if problems else ", cleanly"
    if recovery_s > 0.0:  # engine/control/recovery_blend.py: part of the walk was not the style as authored
        text += (f"; to keep its balance it fell back toward the neutral gait for {recovery_s:.1f} s "
                 f"({100 * recovery_share:.0f} % neutral on average)")
    return text


def walks_problem(walks: int, name: str = "--walks") -> str | None:
    """One line saying why ``walks`` cannot be rehearsed, or None."""
    if 1 <= walks <= MAX_WALKS:
        return None
    return f"{name}: expected 1 <= walks <= {MAX_WALKS}, got {walks}"


def duration_problem(duration_s: float, name: str = "--duration") -> str | None:
    """One line saying why ``duration_s`` cannot be rehearsed, or None."""
    if math.isfinite(duration_s) and 0 < duration_s <= MAX_DURATION_S:
        return None
    return f"{name}: expected 0 < seconds <= {MAX_DURATION_S:.0f}, got {duration_s}"


def describe(summary: dict, rec: dict[str, np.ndarray], duration_s: float) -> RehearsalResult:
    """The walk's verdict in an animator's words (``summary`` and ``rec`` as :func:`run_walk` returns them)."""
    slip = float(summary["max_stance_slip_mm"])
    cop = summary["cop_inside_fraction"]
    recovery_s = float(summary.get("recovery_time_s") or 0.0)
    recovery_share = float(summary.get("recovery_mean_share") or 0.0)
    if not summary["fell"]:
        return RehearsalResult(False, None, duration_s, None, None, None, None, slip, cop,
                               _walk_text(slip, cop, duration_s, recovery_s, recovery_share),
                               recovery_time_s=recovery_s, recovery_mean_share=recovery_share)
    fall_t = float(summary["fall_time_s"])
    t = np.asarray(rec["t"])
    if len(t) == 0:  # fell before the first recorded instant
        return RehearsalResult(True, fall_t, duration_s, None, None, None, None, slip, cop,
                               f"falls at {fall_t:.1f} s, at once: check the stance (pelvis height, width)")
    i = len(t) - 1
    weights = np.asarray(rec["sample_weights"])[i]
    sample = SAMPLE_NAMES[int(np.argmax(weights))]
    phase_pct = float(100.0 * (np.asarray(rec["gait_phase"])[i] % 1.0))
    vx, vy, wz = (float(x) for x in np.asarray(rec["command"])[i])
    command = (vx, vy, wz)
    onset, kind, how = _onset(rec, fall_t)
    text = (f"falls at {fall_t:.1f} s of the {duration_s:.0f} s sweep, walking **{sample}** "
            f"({_command_words(command)}), around {phase_pct:.0f} % of its cycle")
    if onset is not None:
        text += f"; it began at {onset:.1f} s: {how}"
    return RehearsalResult(True, fall_t, duration_s, sample, phase_pct, command, onset, slip, cop, text,
                           recovery_time_s=recovery_s, recovery_mean_share=recovery_share, onset_kind=kind)


def _onset(rec: dict[str, np.ndarray], fall_t: float) -> tuple[float | None, str | None, str]:
    """The first instant in the last :data:`LOOKBACK_S` before the fall where the feet stood on their edges with the
    body outside them, the body left the plan or a foot on the ground slid: (its time, its kind of
    :data:`ONSET_KINDS`, what happened in words)."""
    t = np.asarray(rec["t"])
    window = t >= fall_t - LOOKBACK_S
    com = np.asarray(rec["com"])[:, :2]
    com_ref = np.asarray(rec["com_ref"])
    drift = com - com_ref
    yaw = np.asarray(rec["pelvis_yaw_achieved"])
    # the drift in the robot's heading frame: + ahead / + left
    ahead = np.cos(yaw) * drift[:, 0] + np.sin(yaw) * drift[:, 1]
    left = -np.sin(yaw) * drift[:, 0] + np.cos(yaw) * drift[:, 1]
    far = window & (np.hypot(ahead, left) >= DRIFT_M) & np.all(np.isfinite(com_ref), axis=1)
    slide_t, slide_side = _first_slide(rec, window)
    drift_t = float(t[np.argmax(far)]) if far.any() else None
    edges_t, edges_text = _first_edges(rec, window)
    if edges_t is not None and all(other is None or edges_t <= other for other in (slide_t, drift_t)):
        return edges_t, "edges", edges_text
    if slide_t is not None and (drift_t is None or slide_t < drift_t):
        return slide_t, "slide", (f"the {slide_side} foot started sliding on the ground (less friction than the step "
                                  "needs)")
    if drift_t is None:
        return None, None, ""
    k = int(np.argmax(far))
    vx, vy = (float(v) for v in np.asarray(rec["command"])[k, :2])
    speed = math.hypot(vx, vy)
    if speed >= MOVING_MPS:  # walking: along or across the direction of travel
        along, across = (ahead[k] * vx + left[k] * vy) / speed, (left[k] * vx - ahead[k] * vy) / speed
        if abs(along) >= abs(across):
            if along < 0:
                return drift_t, "behind", (f"the body fell {100 * DRIFT_M:.0f} cm behind its plan along the walk "
                                           "(the steps could not carry it: a shorter stride or a longer cycle gives "
                                           "them time)")
            return drift_t, "ahead", (f"the body ran {100 * DRIFT_M:.0f} cm ahead of its plan along the walk "
                                      "(it overran its steps: a longer stride or a shorter cycle)")
        return drift_t, "across", (f"the body drifted {100 * DRIFT_M:.0f} cm sideways off its path (its sideways "
                                   "balance did not hold: a wider stance or less pelvis sway)")
    if abs(ahead[k]) >= abs(left[k]):
        where = "behind" if ahead[k] < 0 else "in front of"
        kind, advice = "front-back", "its balance front to back did not hold: a lower pelvis or shorter steps"
    else:
        where = "left of" if left[k] > 0 else "right of"
        kind, advice = "sideways", "its sideways balance did not hold: a wider stance or less pelvis sway"
    return drift_t, kind, f"the body drifted {100 * DRIFT_M:.0f} cm {where} where it should stand ({advice})"


def _first_edges(rec: dict[str, np.ndarray], window: np.ndarray) -> tuple[float | None, str]:
    """Start of the first stretch in ``window`` of at least :data:`EDGES_S` where both feet are on the ground, at
    least one rolled on its heel or toe, and the body :data:`DRIFT_M` outside the support of their grounded corners
    (engine/gait/support_edges.py, recorded as ``support_edge`` and ``com_outside_support_m``), and what it was."""
    from engine.gait.support_edges import EDGE_WORDS

    if "support_edge" not in rec or "com_outside_support_m" not in rec:
        return None, ""  # (a recording made before these were)
    t = np.asarray(rec["t"])
    edge = np.asarray(rec["support_edge"]).reshape(len(t), 2)
    outside = np.asarray(rec["com_outside_support_m"], dtype=float)
    both = np.asarray(rec["contact"]).reshape(len(t), 2).all(axis=1)
    hit = window & both & (edge > 0).any(axis=1) & (np.nan_to_num(outside, nan=0.0) >= DRIFT_M)
    idx = np.flatnonzero(hit)
    breaks = np.flatnonzero(np.diff(idx) > 1)
    stretches = zip(np.r_[idx[:1], idx[breaks + 1]].tolist(), np.r_[idx[breaks], idx[-1:]].tolist())
    start = next((a for a, b in stretches if t[b] - t[a] >= EDGES_S), None)
    if start is None:
        return None, ""
    codes = edge[start].tolist()
    words = [EDGE_WORDS.get(c) for c in codes]
    if words[0] is not None and words[0] == words[1]:
        feet = f"both feet stood on their {words[0]}s"
    else:
        i = 0 if words[0] is not None else 1
        other = words[1 - i]
        feet = (f"the {SIDES[i]} foot stood on its {words[i]} and the {SIDES[1 - i]} foot "
                + (f"on its {other}" if other else "flat"))
    return float(t[start]), (f"{feet} with the body {100 * DRIFT_M:.0f} cm outside them for {EDGES_S:g} s or more "
                             "(nothing under it could hold it: land and lift the feet flatter, with less heel or toe "
                             "pitch at touchdown and liftoff, or shorter heel/toe transitions)")


def _first_slide(rec: dict[str, np.ndarray], window: np.ndarray) -> tuple[float | None, str]:
    """First instant in ``window`` where a sole in stance has drifted :data:`SLIDE_M` from where its stance
    found it: the stance slip meter's drift (engine/stance_slip.py, recorded as ``stance_drift_m``: the plan holds
    the foot flat and the floor carries it). A foot rolling onto its toe to lift off, or still pitched from a heel
    strike, moves its sole centre without sliding: not counted."""
    t = np.asarray(rec["t"])
    drift = np.asarray(rec["stance_drift_m"]).reshape(len(t), 2)
    best: tuple[float | None, str] = (None, "")
    for side, name in enumerate(("left", "right")):
        hits = np.flatnonzero(window & (drift[:, side] >= SLIDE_M))
        if hits.size and (best[0] is None or t[hits[0]] < best[0]):
            best = (float(t[hits[0]]), name)
    return best


def _command_words(command: tuple[float, float, float]) -> str:
    vx, vy, wz = command
    parts = []
    if abs(vx) >= 0.02:
        parts.append(f"{abs(vx):.2f} m/s {'forward' if vx > 0 else 'backward'}")
    if abs(vy) >= 0.02:
        parts.append(f"{abs(vy):.2f} m/s to the {'left' if vy > 0 else 'right'}")
    if abs(wz) >= 0.02:
        parts.append(f"turning {'left' if wz > 0 else 'right'} {abs(wz):.2f} rad/s")
    return ", ".join(parts) if parts else "standing"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m engine.gait.rehearsal",
                                     description="walk a style through the sweep in physics (JSON lines out)")
    parser.add_argument("--robot", required=True)
    parser.add_argument("--style", required=True, help="style JSON file")
    parser.add_argument("--duration", type=float, default=SWEEP_DURATION_S, help="simulated seconds of the sweep")
    parser.add_argument("--walks", type=int, default=1,
                        help="walks of the sweep: the first the benchmark's, each other one nudged once while standing")
    parser.add_argument("--nice", type=int, default=0, help="raise this process's niceness by N (0-19) first")
    args = parser.parse_args(argv)
    if not 0 <= args.nice <= 19:
        print(f"--nice: expected 0 <= N <= 19, got {args.nice}", file=sys.stderr)
        return 2
    if args.nice:
        import os

        os.nice(args.nice)
    from engine.gait.style import StyleContext, StyleError, load_style
    from engine.robot.model import load_robot

    problem = duration_problem(args.duration) or walks_problem(args.walks)
    if problem:
        print(problem, file=sys.stderr)
        return 2
    try:
        robot = load_robot(args.robot)
        style = load_style(args.style, StyleContext.for_robot(robot.name), expected_robot=robot.name)
    except (StyleError, OSError, ValueError, KeyError) as exc:
        print(str(exc).splitlines()[0] if str(exc) else type(exc).__name__, file=sys.stderr)
        return 2

    def report(t_s: float) -> None:
        print(json.dumps({"progress_s": round(t_s, 2)}), flush=True)

    def walked(so_far: RehearsalResult) -> None:
        print(json.dumps({"walk": so_far.to_dict()}), flush=True)

    result = rehearse(robot, style, args.duration, progress=report, walks=args.walks, on_walk=walked)
    print(json.dumps({"result": result.to_dict()}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
