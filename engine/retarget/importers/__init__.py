"""Importers: one module per source format, each returning a KeypointMotion (legs FL, FR, RL, RR; w,x,y,z).

``import_source(path)`` detects the format from the file's content (``fmt`` forces one). Every failure is
an ``ImportFormatError`` whose message is one line naming the file, the field and what was expected.
"""

from __future__ import annotations

from pathlib import Path

from engine.retarget.motion import KeypointMotion, MotionFormatError
from engine.safe_io import ReadError, decode_text, read_npz
from engine.safe_io import read_json as _safe_read_json

MAX_SOURCE_BYTES = 64 * 1024 * 1024  # the largest shared source is < 1 MB


class ImportFormatError(MotionFormatError):
    pass


def _import_error(exc: ReadError) -> ImportFormatError:
    return ImportFormatError(exc.source, exc.field_path, exc.detail)


FORMATS = ("keypoint-npz", "stmr-keypoints", "motion-imitation", "dog-keypoints", "videowalk", "dog-bvh")


def detect_format(path: Path) -> str:
    name = path.name
    if path.is_dir():
        raise ImportFormatError(f"{name}: expected a motion file, got a directory")
    if not path.is_file():
        raise ImportFormatError(f"{name}: file not found")
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
    except OSError as exc:
        raise ImportFormatError(name, "", f"expected a readable file ({exc.strerror or exc})") from None
    if head[:2] == b"PK":
        try:
            keys = set(read_npz(path, source=name))
        except ReadError as exc:
            raise _import_error(exc) from None
        if "format" in keys:
            return "keypoint-npz"
        if {"keypoints", "keypoint_names", "base_pos", "base_rotmat"} <= keys:
            return "stmr-keypoints"
        raise ImportFormatError(f"{name}: expected a keypoint-motion npz or an STMR *_keypoints.npz, found arrays {sorted(keys)}")
    if not head.strip():
        raise ImportFormatError(name, "", "expected a motion file, the file is empty" if not head
                                else "expected a motion file, the file holds only whitespace")
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):  # UTF-16/32: every text format here is UTF-8
        try:
            decode_text(head, name)
        except ReadError as exc:
            raise _import_error(exc) from None
    if head.startswith(b"\xef\xbb\xbf"):  # a UTF-8 BOM (Windows editors): the readers drop it too
        head = head[3:]
    text = head.decode("utf-8", errors="replace").lstrip()
    if text[:9].upper() == "HIERARCHY":  # the BVH reader takes its keywords in any case
        return "dog-bvh"
    if text.startswith("{"):
        if '"Frames"' in text or '"FrameDuration"' in text or '"LoopMode"' in text:
            return "motion-imitation"
        if "_thigh" in text and "_foot" in text:
            return "videowalk"
        raise ImportFormatError(f"{name}: expected motion_imitation frames (LoopMode, FrameDuration, Frames) or videowalk keypoints")
    first = text.splitlines()[0] if text else ""
    cols = [c for c in first.replace("\t", ",").split(",") if c.strip()]
    if len(cols) == 81:
        return "dog-keypoints"
    raise ImportFormatError(f"{name}: unknown format; expected one of {', '.join(FORMATS)}")


def import_source(path: str | Path, fmt: str | None = None) -> KeypointMotion:
    path = Path(path)
    fmt = fmt or detect_format(path)
    if fmt == "keypoint-npz":
        return KeypointMotion.load(path)
    if fmt == "stmr-keypoints":
        from engine.retarget.importers.stmr import import_stmr_keypoints

        return import_stmr_keypoints(path)
    if fmt == "motion-imitation":
        from engine.retarget.importers.motion_imitation import import_frames

        return import_frames(path)
    if fmt == "dog-keypoints":
        from engine.retarget.importers.dog_keypoints import import_dog_keypoints

        return import_dog_keypoints(path)
    if fmt == "videowalk":
        from engine.retarget.importers.videowalk import import_videowalk

        return import_videowalk(path)
    if fmt == "dog-bvh":
        from engine.retarget.importers.dog_bvh import import_dog_bvh

        return import_dog_bvh(path)
    raise ImportFormatError(f"{path.name}: --format: expected one of {', '.join(FORMATS)}, got {fmt!r}")


def read_json(path: Path) -> object:
    """A source's JSON through engine/safe_io.py (size and nesting limits, duplicate keys, encoding named)."""
    try:
        return _safe_read_json(path, max_bytes=MAX_SOURCE_BYTES, source=path.name)
    except ReadError as exc:
        raise _import_error(exc) from None


def read_source_npz(path: Path) -> dict:
    """A source's npz arrays through engine/safe_io.py (headers checked before anything is allocated)."""
    try:
        return read_npz(path, source=path.name)
    except ReadError as exc:
        raise _import_error(exc) from None
