"""Stance slip by the load-anchored metric and by the old reference-anchored one, from the same walks.

    PYTHONPATH=. .venv/bin/python tools/compare_stance_slip.py --robot g1 --seeds 2,3,4,5 --n 8 \
        --duration 20 --extent 0.15 [--shipped] [--out-dir DIR]

Walks each style (random styles of ``studio bench styles`` and/or the shipped ``styles/<robot>/``)
through the ``sweep`` in this process, one after the other, and prints per style: fell, the new
slip (engine/stance_slip.py: the plan holds the sole flat *and* the floor carries it), the old slip
(the plan holds it flat, whether or not the foot is down), CoP inside and clean by either. With
``--out-dir`` it writes each walk's recording plus per-tick foot loads and both drifts (every 4th
tick) to DIR/<style>.npz for diagnosis.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import engine.walk_runner as walk_runner
from engine.bench.options import STYLE_SPACES
from engine.stance_slip import StanceSlipMeter

CLEAN_SLIP_MM, CLEAN_COP = 2.0, 0.995


class _BothMeters(StanceSlipMeter):
    """The new meter; beside it the old one (no load condition) and a per-tick log."""

    last: "_BothMeters | None" = None

    def __init__(self, dt_s: float, body_weight_n: float) -> None:
        super().__init__(dt_s, body_weight_n)
        self.old = StanceSlipMeter(self.dt_s, self.body_weight_n, load_fraction=-np.inf)
        self.log: dict[str, list] = {"load_n": [], "drift_new_m": [], "drift_old_m": [], "flat": []}
        self._tick = 0
        _BothMeters.last = self

    def update(self, planned_flat: np.ndarray, sole_xy_m: np.ndarray, load_n: np.ndarray) -> np.ndarray:
        new = super().update(planned_flat, sole_xy_m, load_n)
        old = self.old.update(planned_flat, sole_xy_m, load_n)
        if self._tick % 4 == 0:
            self.log["load_n"].append(np.array(load_n, dtype=float))
            self.log["drift_new_m"].append(new)
            self.log["drift_old_m"].append(old)
            self.log["flat"].append(np.array(planned_flat, dtype=bool))
        self._tick += 1
        return new


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--robot", default="g1")
    ap.add_argument("--seeds", default="")
    ap.add_argument("--n", type=int, default=8)
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--extent", type=float, default=0.15)
    ap.add_argument("--space", choices=STYLE_SPACES, default=STYLE_SPACES[0])
    ap.add_argument("--shipped", action="store_true")
    ap.add_argument("--only", default="", help="comma-separated style names to run (default all)")
    ap.add_argument("--out-dir", default="")
    ap.add_argument("--walking", action="append", default=[], metavar="KEY=VALUE",
                    help="override a [control.walking] parameter for these walks (e.g. landing_height_m=0.01)")
    args = ap.parse_args()

    from engine.bench.styles import style_jobs
    from engine.gait.command_schedule import parse_command
    from engine.gait.style import StyleContext, load_style, styles_dir
    from engine.robot.model import load_robot

    robot = load_robot(args.robot)
    styles = []
    if args.shipped:
        ctx = StyleContext.for_robot(args.robot)
        styles += [load_style(p, ctx) for p in sorted(styles_dir(args.robot).glob("*.json"))]
    for seed in (int(s) for s in args.seeds.split(",") if s):
        styles += [s for s, _ in style_jobs(args.robot, args.n, seed, args.duration, args.extent, args.space)]
    if args.only:
        keep = set(args.only.split(","))
        styles = [s for s in styles if s.name in keep]
    walk_runner.StanceSlipMeter = _BothMeters  # type: ignore[misc]
    if args.walking:
        import dataclasses

        from engine.control.walking_parameters import WalkingParameters

        changes = {k: float(v) for k, v in (item.split("=", 1) for item in args.walking)}
        base = WalkingParameters.for_robot

        def for_robot(name: str) -> WalkingParameters:
            return dataclasses.replace(base(name), **changes)  # type: ignore[arg-type]

        WalkingParameters.for_robot = staticmethod(for_robot)  # type: ignore[method-assign]
    out = Path(args.out_dir) if args.out_dir else None
    if out:
        out.mkdir(parents=True, exist_ok=True)
    n_walk = n_clean_new = n_clean_old = 0
    for style in styles:
        summary, rec = walk_runner.run_walk(robot, style, parse_command("sweep", style.velocities), args.duration,
                                            record=out is not None)
        meters = _BothMeters.last
        assert meters is not None
        new_mm, old_mm = 1000 * meters.max_slip_m, 1000 * meters.old.max_slip_m
        cop = summary["cop_inside_fraction"] or 0.0
        fell = summary["fell"]
        clean_new = not fell and new_mm < CLEAN_SLIP_MM and cop >= CLEAN_COP
        clean_old = not fell and old_mm < CLEAN_SLIP_MM and cop >= CLEAN_COP
        n_walk += not fell
        n_clean_new += clean_new
        n_clean_old += clean_old
        print(json.dumps({"style": style.name, "fell": fell, "fall_s": summary["fall_time_s"],
                          "slip_new_mm": round(new_mm, 2), "slip_old_mm": round(old_mm, 2),
                          "cop_in": cop, "clean_new": clean_new, "clean_old": clean_old}), flush=True)
        if out is not None:
            arrays = {k: v for k, v in rec.items() if isinstance(v, np.ndarray) and v.dtype != object}
            arrays.update({k: np.asarray(v) for k, v in meters.log.items()})
            np.savez_compressed(out / f"{style.name}.npz", **arrays)
        del rec
    print(json.dumps({"styles": len(styles), "walked": n_walk, "clean_new": n_clean_new, "clean_old": n_clean_old}))


if __name__ == "__main__":
    main()
