"""A few styles of ``studio bench styles`` (by index) and the shipped styles, walked in this process (issue 13).

For trying a robot-level change (``robots/<robot>.toml``) on a chosen group of random styles without the whole
``--n 40`` bench: index i is the same style as in ``studio bench styles --robot R --n N --seed S --extent E``
(engine/bench/styles.py's ``style_jobs``), walked through ``engine.walk_batch.run_job`` (the bench's own job)
one after the other. Prints one JSON line per walk (walked, fall time, stance slip, CoP inside) and a summary.

Usage: ``python tools/style_trial.py --robot g1 --n 40 --seed 0 --extent 0.3 --duration 60 8 9 13 --shipped
--shipped-duration 20`` (``--shipped``: every styles/<robot>/*.json through a ``--shipped-duration`` sweep).
"""

from __future__ import annotations

import argparse
import json
import sys

from engine.bench.options import add_random_style_options
from engine.bench.styles import style_jobs
from engine.walk_batch import run_job


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("indices", type=int, nargs="*")
    add_random_style_options(ap)
    ap.add_argument("--shipped", action="store_true")
    ap.add_argument("--shipped-duration", type=float, default=20.0)
    ap.add_argument("--json", help="write the rows here")
    a = ap.parse_args(argv)
    jobs: list[tuple[str, dict]] = []
    if a.indices:
        pairs = style_jobs(a.robot, a.n, a.seed, a.duration, a.extent, a.space)
        for i in a.indices:
            if not 0 <= i < len(pairs):
                print(f"index {i}: expected 0..{len(pairs) - 1}", file=sys.stderr)
                return 2
            jobs.append((str(i), pairs[i][1]))
    if a.shipped:
        from engine.gait.style import StyleContext, load_style, style_to_json_dict, styles_dir

        ctx = StyleContext.for_robot(a.robot)
        for path in sorted(styles_dir(a.robot).glob("*.json")):
            style = load_style(path, ctx)
            jobs.append((path.stem, {"robot": a.robot, "style": style_to_json_dict(style), "command": "sweep",
                                     "duration_s": a.shipped_duration}))
    rows = []
    for name, job in jobs:
        r = run_job(job)
        row = {"style": name, "fell": r.get("fell"), "fall_s": r.get("fall_time_s"),
               "slip_mm": r.get("max_stance_slip_mm"), "cop": r.get("cop_inside_fraction"), "error": r.get("error")}
        rows.append(row)
        print(json.dumps(row), flush=True)
        if a.json:
            with open(a.json, "w") as f:
                json.dump(rows, f, indent=1)
    walked = sum(1 for r in rows if r["fell"] is False)
    print(f"walked {walked}/{len(rows)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
