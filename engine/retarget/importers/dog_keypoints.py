"""Dog keypoint clips (motion_imitation ``retarget_keypoints/dog_*_joint_pos.txt``): 27 points per frame.

Comma(+tab)-separated rows of 81 numbers = 27 points × (x, y, z) in metres, **Y up**, 60 fps — the MANN
dog skeleton's 21 joints + 6 end sites in BVH depth-first order (see PROVENANCE.md). Rotated to Z up by
+90° about x (as motion_imitation's REF_COORD_ROT). The robot's four keypoints per leg map to:

* front legs: hip = thigh = shoulder joint (LeftArm 7 / RightArm 12; the robot's lateral hip link has no dog
  counterpart, so the zero-length hip→thigh vector takes the robot's own direction), knee = elbow
  (ForeArm 8 / 13), foot = paw end site (10 / 15);
* hind legs: hip = thigh = hip joint (UpLeg 16 / 20), knee = stifle (Leg 17 / 21), foot = paw end (19 / 23).

No contact schedule in the source: estimated from foot height and speed.

Reading is bounded and strict (issue 14): at most :data:`MAX_KEYPOINT_BYTES` of UTF-8 text (a UTF-8 BOM is
fine; UTF-16, invalid bytes and NUL bytes are named by engine/safe_io.py), every value a plain decimal number
(no ``nan``, ``inf``, ``1_000``, hex or non-ASCII digits) with |x| ≤ 1e9, every row exactly 81 values (16 MiB hold at most ~100 000
frames: ≤ 65 MB of numbers), at least 2 frames, a skeleton whose legs have length. Errors are one line:
``dog.txt: line 3, value 17: expected a finite number, got 'nan'``.
"""

from __future__ import annotations

import io
import re
from array import array
from pathlib import Path

import numpy as np

from engine.retarget.contacts import estimate_contacts
from engine.retarget.importers import ImportFormatError
from engine.retarget.motion import MAX_ABS_VALUE, KeypointMotion
from engine.safe_io import ReadError, decode_text, read_bytes

FPS = 60.0
# (hip, thigh, knee, foot) point indices per leg FL, FR, RL, RR
POINTS = ((7, 7, 8, 10), (12, 12, 13, 15), (16, 16, 17, 19), (20, 20, 21, 23))
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
MAX_KEYPOINT_BYTES = 16 * 1024 * 1024  # the largest motion_imitation dog file is 3.5 MB (dog_walk09)
MIN_BONE_M = 1e-3  # a leg bone shorter than this is not a skeleton (all points coincident)
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?", re.ASCII)
_NOT_FINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)


def read_rows(path: Path, width: int, max_bytes: int = MAX_KEYPOINT_BYTES) -> np.ndarray:
    """(T, width) numbers of a comma(+tab)-separated text file; ImportFormatError (one line) otherwise."""
    name = path.name
    try:
        text = decode_text(read_bytes(path, max_bytes, name), name)
    except ReadError as exc:
        raise ImportFormatError(exc.source, exc.field_path, exc.detail) from None
    values = array("d")  # 8 bytes per value: no list of Python floats per row
    rows = 0
    for ln, line in enumerate(io.StringIO(text, newline=None), 1):  # lazily: a file of blank lines stays small
        if not line.strip():
            continue
        pieces = line.replace("\t", ",").split(",", 4 * width)  # bounded: a 16 MiB line is not split in millions
        cells = [c for c in (p.strip() for p in pieces) if c]
        if len(cells) != width:
            got = f"more than {len(cells) - 1}" if len(pieces) > 4 * width else str(len(cells))
            raise ImportFormatError(name, f"line {ln}", f"expected {width} comma-separated numbers, got {got}")
        row = []
        for j, cell in enumerate(cells):
            if not _NUMBER.fullmatch(cell):
                what = "a finite number" if _NOT_FINITE.fullmatch(cell) else "a number"
                raise ImportFormatError(name, f"line {ln}, value {j + 1}", f"expected {what}, got {cell[:20]!r}")
            x = float(cell)  # a regex-checked decimal: "1e999" is inf, never an exception
            if not abs(x) <= MAX_ABS_VALUE:
                raise ImportFormatError(name, f"line {ln}, value {j + 1}",
                                        f"expected |x| ≤ {MAX_ABS_VALUE:g} (metres), got {cell[:20]}")
            row.append(x)
        values.extend(row)
        rows += 1
    if rows < 2:
        detail = "the file is empty" if not text.strip() else f"got {rows}"
        raise ImportFormatError(name, "", f"expected at least 2 frames of {width} numbers, {detail}")
    return np.frombuffer(values, dtype=float).reshape(rows, width).copy()


def keypoints_from_points(points: np.ndarray) -> np.ndarray:
    """(T, 27, 3) Z-up dog points → (T, 16, 3) keypoints, legs FL, FR, RL, RR."""
    return np.stack([points[:, idx] for leg in POINTS for idx in leg], axis=1)


def check_legs(kp: np.ndarray, name: str, field_path: str) -> None:
    """Every leg's upper (hip→knee) and lower (knee→foot) bone has length (median over the frames)."""
    legs = ("front left", "front right", "hind left", "hind right")
    for leg in range(4):
        hip, knee, foot = kp[:, 4 * leg], kp[:, 4 * leg + 2], kp[:, 4 * leg + 3]
        for bone, a, b in (("upper", hip, knee), ("lower", knee, foot)):
            length = float(np.median(np.linalg.norm(b - a, axis=1)))
            if not length >= MIN_BONE_M:
                raise ImportFormatError(name, field_path, f"expected a dog skeleton, the {legs[leg]} leg's {bone} "
                                        f"bone is {length * 1000:.2g} mm long (coincident points: degenerate)")


def dog_motion(kp: np.ndarray, fps: float, name: str, source: dict) -> KeypointMotion:
    """Ground the keypoints (2nd percentile of the feet at z = 0), estimate contacts, build the motion."""
    ground = float(np.percentile(kp[:, 3::4, 2], 2))
    kp[:, :, 2] -= ground
    contact = estimate_contacts(kp[:, 3::4], fps, 0.0)
    return KeypointMotion(fps=fps, keypoints=kp, contact=contact, known=np.ones(16, dtype=bool),
                          source={"file": name, **source, "contact_from": "estimated", "ground_shift_m": -ground},
                          loaded_from=name)


def import_dog_keypoints(path: Path) -> KeypointMotion:
    rows = read_rows(path, 81)
    points = rows.reshape(len(rows), 27, 3) @ Y_UP_TO_Z_UP.T
    kp = keypoints_from_points(points)
    check_legs(kp, path.name, "")
    return dog_motion(kp, FPS, path.name, {"format": "dog-keypoints",
                                           "licence": "CC BY-NC 4.0 (MANN dog mocap): test data only"})
