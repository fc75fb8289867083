"""Two runs of ``studio bench tmr-clips --json`` side by side: STMR before → after, per clip and robot (markdown).

    studio bench tmr-clips --robots go1 --clips hopturn,sidesteps --json > before.json   # the old code
    studio bench tmr-clips --robots go1 --clips hopturn,sidesteps --json > after.json    # the new code
    python tools/tmr_clips_table.py before.json after.json

Per row: SMR's replay (fell / DTW % — the same motion and solve in both runs, printed from the second), then for
each run STMR's α, duration after (s), replay fell (at s) / DTW % / mm, STMR vs SMR DTW, BO evaluations, TMR wall
and CPU s, and BO's evaluations in order (α, ✓ stood / ↓ fell at s, wall s of that evaluation).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _rows(path: Path) -> dict[tuple[str, str], dict]:
    text = path.read_text()
    data = json.loads(text[text.index("{"):])  # tolerate a line of noise before the JSON
    return {(r["clip"], r["robot"]): r for r in data["rows"]
            if r.get("section") == "retarget-methods" and "clip" in r}


def _stmr(r: dict | None) -> str:
    if r is None:
        return "– | – | – | – | – | – |"
    fell = f"**yes** (at {r['stmr_fell_at_s']:g} s)" if r["stmr_fell"] else "no"
    change = r.get("stmr_vs_smr_dtw_pct")
    return (f"{r['stmr_alpha']} | {r['stmr_duration_s']:g} | {fell} / {r['stmr_dtw_pct']} / {r['stmr_track_mm']} "
            f"| {'–' if change is None else f'{change:+.0f} %'} | {r['evals']}: {r['tmr_s']:g} / {r['tmr_cpu_s']:g} "
            f"| {r['bo_trace']} |")


def table(before: dict[tuple[str, str], dict], after: dict[tuple[str, str], dict]) -> str:
    head = ("| clip | robot | SMR replay: fell / DTW % | before: STMR α | after s | replay: fell / DTW % / mm | vs SMR "
            "| evals: TMR wall / CPU s | BO trace | after: STMR α | after s | replay: fell / DTW % / mm | vs SMR "
            "| evals: TMR wall / CPU s | BO trace |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for key in [*before, *(k for k in after if k not in before)]:
        b, a = before.get(key), after.get(key)
        ref = a or b
        assert ref is not None
        smr = f"{'**yes**' if ref['smr_fell'] else 'no'} / {ref['smr_dtw_pct']}"
        lines.append(f"| {key[0]} | {key[1]} | {smr} | {_stmr(b)} {_stmr(a)}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    args = parser.parse_args(argv)
    try:
        before, after = _rows(args.before), _rows(args.after)
    except (OSError, ValueError, KeyError) as exc:
        print(f"tmr_clips_table: {exc}", file=sys.stderr)
        return 2
    print(table(before, after))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
