"""The motion library on disk (motions/): where files live, and paths that cannot leave it.

Layout: ``motions/source/NAME.npz`` keypoint motions (imported sources), ``motions/<robot>/NAME.npz`` robot
motions (retargeting results), ``motions/exports/`` exported files. Every path a user (or the studio) names is a
path *relative to a root*; :func:`confined` refuses absolute paths, ``..``, and symlinks that lead out.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[1]
SOURCE_DIR = "source"
EXPORTS_DIR = "exports"
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,79}$")


class OutsideLibrary(ValueError):
    """A path that would leave its root (absolute, ``..``, a symlink out) or is not a plain name."""


def motions_root() -> Path:
    """motions/ of the repository (``MOTION_STUDIO_MOTIONS`` overrides it: tests use a temporary folder)."""
    return Path(os.environ.get("MOTION_STUDIO_MOTIONS") or REPO_ROOT / "motions")


def shared_root() -> Path | None:
    """The shared (read-only) data folder: MOTION_STUDIO_SHARED, else ../shared, else /work/shared."""
    env = os.environ.get("MOTION_STUDIO_SHARED")
    for candidate in ([Path(env)] if env else []) + [REPO_ROOT.parent / "shared", Path("/work/shared")]:
        if candidate.is_dir():
            return candidate
    return None


def confined(root: str | os.PathLike, relative: str) -> Path:
    """``root/relative`` resolved, or OutsideLibrary when it would leave ``root``."""
    text = str(relative).strip()
    if not text:
        raise OutsideLibrary("expected a file name inside the library, got nothing")
    rel = Path(text)
    if rel.is_absolute() or text.startswith(("/", "\\", "~")) or re.match(r"^[A-Za-z]:", text):
        raise OutsideLibrary(f"{text}: expected a path relative to {Path(root).name}/, not an absolute path")
    if any(part == ".." for part in rel.parts):
        raise OutsideLibrary(f"{text}: '..' is not allowed (the picker stays inside {Path(root).name}/)")
    root_resolved = Path(root).resolve()
    path = (root_resolved / rel).resolve()  # follows symlinks
    try:
        path.relative_to(root_resolved)
    except ValueError:
        raise OutsideLibrary(f"{text}: leads outside {Path(root).name}/ (a symbolic link?)") from None
    return path


def check_name(name: str) -> str:
    """A plain file stem (letters, digits, _ . -), for files the studio creates."""
    if not NAME_PATTERN.match(name or "") or ".." in name:
        raise OutsideLibrary(f"name {name!r}: expected letters, digits, '_', '-' or '.' (at most 80)")
    return name


def list_files(root: str | os.PathLike, sub: str = "", suffixes: tuple[str, ...] = (".npz",)) -> list[str]:
    """Files under ``root/sub`` (recursively) as paths relative to ``root``, sorted; symlinks out are skipped."""
    root = Path(root)
    if not root.is_dir():
        return []
    base = confined(root, sub) if sub else root.resolve()
    if not base.is_dir():
        return []
    out = []
    for path in sorted(base.rglob("*")):
        if path.name.startswith(".") or path.suffix.lower() not in suffixes or not path.is_file():
            continue
        rel = str(path.relative_to(root.resolve()))
        try:
            confined(root, rel)
        except OutsideLibrary:
            continue
        out.append(rel)
    return out


MOTION_KINDS = ("keypoint-motion/1", "robot-motion/1")


def motion_kind(path: str | os.PathLike) -> str:
    """'keypoint-motion/1', 'robot-motion/1' or '' (reads only the npz's ``format`` entry, through
    engine/safe_io.py: a zip bomb or a huge declared array elsewhere in the file is never inflated)."""
    from engine.safe_io import ReadError, read_npz

    try:
        fmt = read_npz(path, only=("format",)).get("format")
    except ReadError:  # anything unreadable is simply not a motion (the loaders name what is wrong)
        return ""
    if fmt is None or fmt.ndim != 0 or fmt.dtype.kind != "U" or str(fmt) not in MOTION_KINDS:
        return ""
    return str(fmt)
