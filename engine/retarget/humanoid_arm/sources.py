"""Where the mocap clips live and how they split: training (licence allows shipping models) vs held-out.

The shared data folder (read-only, never copied into the repo) is ``$MOTION_STUDIO_SHARED``, else the first
existing of ``<repo>/../shared`` and ``/work/shared``. Clips are split by file:

- CMU ``131_01`` (3dsMax naming, "start walk stop"): training (mocap domain + glue set);
- CMU ``141_16`` (MotionBuilder naming, "wave hello"): held out for evaluation;
- Bandai Namco dataset 1 (CC BY-NC 4.0): evaluation only, never trained on.
"""

from __future__ import annotations

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
TRAIN_CLIPS = ("mocap-src/cmu/131_01.bvh",)
HELD_OUT_CLIPS = ("mocap-src/cmu/141_16.bvh",)
EVAL_ONLY_DIRS = ("mocap-src/bandai_namco_dataset1",)
TRAINING_LICENCE = ("CMU Graphics Lab Motion Capture Database (mocap.cs.cmu.edu, free for research and commercial use, "
                    "no resale of the data; cgspeed BVH conversion, no added restrictions) + synthetic poses of "
                    "example-robot-data's human model (BSD-3-Clause)")


def shared_dir() -> Path | None:
    env = os.environ.get("MOTION_STUDIO_SHARED")
    candidates = [Path(env)] if env else [REPO.parent / "shared", Path("/work/shared")]
    for c in candidates:
        if c.is_dir():
            return c
    return None


def train_clips() -> list[Path]:
    root = shared_dir()
    return [root / c for c in TRAIN_CLIPS if (root / c).is_file()] if root else []


def evaluation_clips() -> list[Path]:
    """Held-out CMU clips and every Bandai Namco clip (evaluation only)."""
    root = shared_dir()
    if root is None:
        return []
    out = [root / c for c in HELD_OUT_CLIPS if (root / c).is_file()]
    for d in EVAL_ONLY_DIRS:
        out += sorted((root / d).glob("*.bvh"))
    return out
