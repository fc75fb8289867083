"""Where trained LWL2 weights live and their JSON metadata check (no torch, no robot model: fails fast)."""

from __future__ import annotations

from pathlib import Path

WEIGHTS_DIR = Path(__file__).resolve().parent / "weights"


def weights_path(robot: str, folder: Path | None = None) -> Path:
    """``<folder>/<robot>_lwl2`` (+ ``.safetensors``, ``.json``, ``_ff.safetensors``)."""
    return (folder or WEIGHTS_DIR) / f"{robot}_lwl2"


def check_metadata(path: Path, robot: str) -> dict:
    """The weights' JSON metadata, checked to be for ``robot``; ValueError (one line) otherwise."""
    import json

    meta_path = Path(path).with_suffix(".json")
    if not meta_path.is_file():
        raise ValueError(f"{meta_path}: no trained weights there (train with `studio train-arms --robot {robot}`)")
    try:
        meta = json.loads(meta_path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{meta_path}: expected JSON metadata ({exc.__class__.__name__})") from None
    if not isinstance(meta, dict) or meta.get("robot") != robot:
        got = meta.get("robot") if isinstance(meta, dict) else None
        raise ValueError(f"{meta_path}: robot: expected weights for {robot}, these are for {got!r}")
    return meta
