"""Where the shared (read-only, non-commercial) source data lives, or a skip."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def shared_dir() -> Path | None:
    env = os.environ.get("MOTION_STUDIO_SHARED")
    for cand in ([Path(env)] if env else []) + [REPO.parent / "shared", Path("/work/shared")]:
        if (cand / "motions-src").is_dir():
            return cand
    return None


def shared_file(*parts: str) -> Path:
    root = shared_dir()
    if root is None:
        pytest.skip("shared data folder absent (set MOTION_STUDIO_SHARED)")
    path = root.joinpath("motions-src", *parts)
    if not path.exists():
        pytest.skip(f"{path} absent")
    return path


def stmr_clip(clip: str) -> Path:
    return shared_file("stmr_rl", "datasets", clip, f"{clip}_keypoints.npz")
