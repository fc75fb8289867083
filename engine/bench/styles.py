"""``studio bench styles``: does the controller hold the validated style space? (issue 13)

Draws ``n`` random styles that pass validation (engine/gait/style_space.py, seeded), runs the
edit-time feasibility check on each (engine/gait/feasibility.py), walks each through the
``sweep`` command in closed loop on Ray (local by default, ``--address`` for a cluster), and
prints per style: fell / fall time, stance slip, CoP inside, the tracking errors of pelvis
height, pelvis yaw and an elbow (RMS), and whether the check flagged it; then the totals:
walked, slip < 2 mm and CoP inside ≥ 99.5 % among those that walked, falls that were not
flagged ("silent falls") and flagged styles that walked ("false alarms"); only findings in the
samples the sweep reaches within ``duration`` count (column ``unreached``: samples with findings
the walk never blended in). Findings of severity
"rating" (a joint faster than its rated speed: the simulation has no velocity limit and walks them)
are counted apart (``over_rating``), not as flags.
Results are keyed by the style's hash in the output folder: a second call resumes.

``--repeat K`` walks each style K times: the first walk as above, the k-th after a nudge while the robot stands
(:func:`nudge_push`, ``PushSpec.nudge``: 1 N for 10 ms at 0.5 s, 0.01 N·s, a direction per k; the robot's velocity
changes by 0.3 mm/s). Physically nothing, it is enough to send the closed loop down another path: at the margin where these
styles sit, a fall and a walk are that close (README "Falls at a margin"). Per style the column ``falls`` says how
many of its walks fell; the totals how many styles walked every time, never, or sometimes.

Each fall's anatomy (the rehearsal's own analysis): ``fell_in``, the sample and phase it fell in; ``onset`` and
``onset_s``, how and when it began — both feet on their heel or toe edges with the body outside them, a sole in
stance sliding, the body behind or ahead of its plan along the walk or across it, or drifting while standing
(engine/gait/rehearsal.py ``ONSET_KINDS``; "unseen": none of these before the fall); ``onset_runs`` per walk with
``--repeat``. The totals count the kinds over all the falls.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from engine.bench.options import STYLE_SPACES
from engine.walk_batch import job_key, print_progress, run_batch


KINEMATIC_KINDS = frozenset({"reach", "clearance"})  # the check's findings no leg posture can follow


def nudge_push(k: int, repeat: int) -> list[float]:
    """The ``pushes`` entry [t, fx, fy, fz, duration] of the k-th walk (k ≥ 1) of ``repeat`` (engine/walk_runner.py
    ``PushSpec.nudge``)."""
    from engine.walk_runner import PushSpec

    p = PushSpec.nudge(k, repeat)
    return [p.t_s, *p.force_n, p.duration_s]


def repeated_jobs(job: dict[str, Any], repeat: int) -> list[dict[str, Any]]:
    """``job`` itself, then ``repeat`` − 1 copies each nudged once while standing."""
    return [job] + [{**job, "pushes": [*job.get("pushes", []), nudge_push(k, repeat)]} for k in range(1, repeat)]


def style_jobs(robot: str, n: int, seed: int, duration_s: float, extent: float = 1.0,
               space: str = "validated", progress: Callable[[str], None] | None = None) -> list[tuple[Any, dict[str, Any]]]:
    """[(style, job)] for ``n`` random styles of ``robot`` drawn with ``seed``: over the validated space, or
    (``space="reachable"``) over its part the legs reach (each sample drawn again while the feasibility check
    finds its feet out of every leg posture's reach, or in the floor)."""
    from engine.gait.style import StyleContext, load_style, style_to_json_dict, styles_dir
    from engine.gait.style_space import random_reachable_style, random_style

    if space not in STYLE_SPACES:
        raise ValueError(f"space: expected one of {', '.join(STYLE_SPACES)}, got {space!r}")
    ctx = StyleContext.for_robot(robot)
    neutral = load_style(styles_dir(robot) / "neutral.json", ctx)
    rng = np.random.default_rng(seed)
    unreachable = None
    if space == "reachable":
        from engine.gait.feasibility import FeasibilityChecker
        from engine.robot.model import load_robot

        checker = FeasibilityChecker(load_robot(robot), ctx)

        def unreachable(style: Any, sample: str) -> bool:
            return any(f.kind in KINEMATIC_KINDS for f in checker.check_sample(style, sample, balance=False))

    out = []
    for i in range(n):
        name = f"random-{seed}-{i}" if space == "validated" else f"reachable-{seed}-{i}"
        if unreachable is None:
            style = random_style(rng, ctx, neutral, extent, name=name)
        else:
            style, draws = random_reachable_style(rng, ctx, neutral, unreachable, extent, name=name)
            if progress is not None:
                progress(f"  drew {name}: {draws} samples checked for {len(style.samples)} reachable")
        job = {"robot": robot, "style": style_to_json_dict(style), "command": "sweep", "duration_s": float(duration_s)}
        out.append((style, job))
    return out


def bench_styles(robot: str = "g1", n: int = 40, seed: int = 0, duration_s: float = 60.0,
                 out_dir: str | None = None, address: str | None = None, extent: float = 1.0,
                 space: str = "validated", repeat: int = 1) -> list[dict]:
    from engine.gait.feasibility import check_style
    from engine.robot.model import load_robot

    model = load_robot(robot)
    if space == "reachable":
        print(f"drawing {n} reachable styles (the feasibility check on every draw) ...", flush=True)
    pairs = style_jobs(robot, n, seed, duration_s, extent, space, progress=lambda line: print(line, flush=True))
    out = Path(out_dir) if out_dir else Path.home() / ".cache" / "motion-studio" / "bench-styles" / robot
    runs = {job_key(job): repeated_jobs(job, repeat) for _, job in pairs}
    results = run_batch([j for jobs in runs.values() for j in jobs], out, address=address, progress=print_progress)
    rows: list[dict] = []
    for i, (style, job) in enumerate(pairs):
        key = job_key(job)
        r = results.get(key, {"error": "missing"})
        repeats = [results.get(job_key(j), {"error": "missing"}) for j in runs[key]]
        reached = reached_samples(style, job["command"], duration_s)
        everything = check_style(model, style)
        findings = [f for f in everything if f.severity == "fall" and f.sample in reached]
        unreached = [f for f in everything if f.severity == "fall" and f.sample not in reached]
        rating = [f for f in everything if f.severity != "fall"]
        first = findings[0] if findings else None
        row = {"section": "styles", "robot": robot, "seed": seed, "i": i, "key": key}
        if "error" in r:
            rows.append({**row, "fell": "error", "note": r["error"][:60]})
            continue
        row.update({
            "fell": r["fell"], "fall_s": r["fall_time_s"], "slip_mm": r["max_stance_slip_mm"],
            "cop_in": r["cop_inside_fraction"],
            "pelvis_z_rms_mm": _mm(r.get("pelvis_height_rms")), "pelvis_yaw_rms_rad": _r3(r.get("pelvis_yaw_rms")),
            "elbow_rms_rad": _r3(r.get("elbow_rms")),
            # balance recovery: the neutral gait's mean share in the blend over the walk (0: the style throughout)
            "recovery_share": r.get("recovery_mean_share", 0.0),
            "flagged": bool(findings),
            "over_rating": bool(rating),
            "unreached": ",".join(sorted({f.sample for f in unreached})),
            "finding": f"{first.sample} {first.phase_pct:.0f}%: {first.message}"[:90] if first else "",
            **fall_anatomy(r),
        })
        if repeat > 1:
            done = [x for x in repeats if "error" not in x]
            row["falls"] = f"{sum(bool(x['fell']) for x in done)}/{len(done)}"
            row["fall_s_runs"] = ",".join("-" if not x["fell"] else f"{x['fall_time_s']:.1f}" for x in done)
            row["onset_runs"] = ",".join(fall_anatomy(x)["onset"] or ("-" if not x["fell"] else "?") for x in done)
        rows.append(row)
    rows.append(totals(rows, robot, seed))
    return rows


def reached_samples(style: Any, command: str, duration_s: float, min_weight: float = 0.05) -> set[str]:
    """The samples the command blends in with at least ``min_weight`` at some time of the walk: a
    finding in another sample (the sweep walks backward at ``x_slow``: ``reverse_fast`` never) says
    nothing about this walk, so it is neither a flag nor a false alarm here."""
    from engine.gait.command_schedule import parse_command
    from engine.gait.velocity_sampler import SAMPLE_NAMES, sample_weights

    schedule = parse_command(command, style.velocities)
    peak = np.zeros(len(SAMPLE_NAMES))
    for t in np.arange(0.0, duration_s + 1e-9, 0.05):
        peak = np.maximum(peak, sample_weights(schedule(float(t)), style.velocities, style.blend_eta))
    return {name for name, w in zip(SAMPLE_NAMES, peak) if w >= min_weight}


def fall_anatomy(result: dict) -> dict[str, Any]:
    """Where and how a walk's fall began, as table columns: ``fell_in`` (the sample and phase it fell in),
    ``onset`` (engine/gait/rehearsal.py ``ONSET_KINDS``, or "unseen") and ``onset_s``; empty for a walk, or for a
    result stored before these fields."""
    if not result.get("fell") or "fall_onset" not in result:
        return {"fell_in": "", "onset": "", "onset_s": None}
    sample = result.get("fall_sample")
    onset_s = result.get("fall_onset_s")
    return {"fell_in": f"{sample} {result['fall_phase_pct']:.0f}%" if sample else "at once",
            "onset": result["fall_onset"] or "unseen", "onset_s": None if onset_s is None else round(onset_s, 1)}


def onset_counts(kinds: list[str]) -> str:
    """``slide 11, behind 4`` over the falls' onset kinds, most frequent first."""
    counts: dict[str, int] = {}
    for kind in kinds:
        counts[kind] = counts.get(kind, 0) + 1
    return ", ".join(f"{k} {n}" for k, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def totals(rows: list[dict], robot: str, seed: int) -> dict:
    done = [r for r in rows if r.get("fell") in (True, False)]
    walked = [r for r in done if not r["fell"]]
    good = [r for r in walked if (r["slip_mm"] or 0) < 2.0 and (r["cop_in"] or 0) >= 0.995]
    fell = [r for r in done if r["fell"]]
    silent = [r for r in fell if not r["flagged"]]
    alarms = [r for r in walked if r["flagged"]]
    rated = [r for r in walked if r.get("over_rating")]
    repeats = [tuple(int(x) for x in r["falls"].split("/")) for r in done if "falls" in r]
    recovered = [r for r in walked if (r.get("recovery_share") or 0.0) > 0.0]
    mean_share = float(np.mean([r.get("recovery_share") or 0.0 for r in walked])) if walked else 0.0
    # how the falls began: every fallen walk's onset kind (with --repeat, over all the walks)
    kinds = ([k for r in done for k in r.get("onset_runs", "").split(",") if k not in ("", "-", "?")]
             if any("onset_runs" in r for r in done) else [r["onset"] for r in fell if r.get("onset")])
    return {"section": "styles", "robot": robot, "seed": seed, "i": "total", "key": f"{len(done)} run",
            "fell": f"walked {len(walked)}/{len(done)}", "fall_s": "",
            "slip_mm": f"<2mm&CoP≥99.5%: {len(good)}/{len(walked)}", "cop_in": "",
            "flagged": f"silent falls {len(silent)}/{len(fell)}, false alarms {len(alarms)}/{len(walked)}",
            "over_rating": f"walked above a rated joint speed {len(rated)}/{len(walked)}",
            "recovery_share": f"recovered toward neutral {len(recovered)}/{len(walked)}, mean share {mean_share:.3f}",
            "onset": f"falls began: {onset_counts(kinds)}" if kinds else "",
            **({"falls": f"walks: {sum(k - f for f, k in repeats)}/{sum(k for _, k in repeats)}; styles that walk every "
                         f"time {sum(f == 0 for f, _ in repeats)}, never {sum(f == k for f, k in repeats)}, sometimes "
                         f"{sum(0 < f < k for f, k in repeats)}"} if repeats else {})}


def _mm(x: float | None) -> float | None:
    return None if x is None else round(1000.0 * x, 1)


def _r3(x: float | None) -> float | None:
    return None if x is None else round(x, 3)
