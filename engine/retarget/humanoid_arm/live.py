"""Live mocap datagrams: one UDP datagram (UTF-8 JSON) per frame, what `studio stream-bvh` sends and what a
real mocap bridge should send to drive LWL2 live.

    {"format": "mocap-joints/1", "frame": 12, "t_s": 0.1, "up": [0, 1, 0],
     "joints": {"hips": [x, y, z], "right_hip": [...], "left_hip": [...],
                "right_shoulder": [...], "right_elbow": [...], "right_hand": [...],
                "left_shoulder": [...], "left_elbow": [...], "left_hand": [...]}}

Positions are global, in any one unit (only directions matter), in a right-handed frame whose up axis is
``up``; ``hips`` is the pelvis centre, ``*_hip`` the hip joints (they give the heading), ``*_hand`` the wrists.
Extra keys are ignored. A datagram is at most 64 KiB.
"""

from __future__ import annotations

import json

import numpy as np

from engine.retarget.humanoid_arm.pose15 import MocapPoints, body_frame, pose15_from_points
from engine.safe_io import ReadError, decode_text, finite_number, parse_json

FORMAT = "mocap-joints/1"
JOINTS = ("hips", "right_hip", "left_hip", "right_shoulder", "right_elbow", "right_hand",
          "left_shoulder", "left_elbow", "left_hand")
MAX_DATAGRAM_BYTES = 65_507


def datagrams_from_points(points: MocapPoints, up=(0.0, 1.0, 0.0), stride: int = 1):
    """Yield (t_s, bytes) for every ``stride``-th frame of a clip's key points."""
    assert points.up_leg is not None
    for f in range(0, len(points.hips), stride):
        joints = {"hips": points.hips[f], "right_hip": points.up_leg[f, 0], "left_hip": points.up_leg[f, 1]}
        for i, side in enumerate(("right", "left")):
            joints[f"{side}_shoulder"] = points.shoulder[f, i]
            joints[f"{side}_elbow"] = points.elbow[f, i]
            joints[f"{side}_hand"] = points.hand[f, i]
        msg = {"format": FORMAT, "frame": f, "t_s": round(f / points.fps, 6), "up": list(up),
               "joints": {k: [round(float(c), 6) for c in v] for k, v in joints.items()}}
        yield f / points.fps, json.dumps(msg, separators=(",", ":")).encode()


class DatagramError(ReadError):
    """A malformed datagram: one line, ``datagram: field.path: what was expected`` (a ReadError whose source is
    ``datagram``, or the sender's address when the receiver knows it)."""

    def __init__(self, field_path: str, detail: str, source: str = "datagram"):
        super().__init__(source, field_path, detail)

    def __reduce__(self):
        return type(self), (self.field_path, self.detail, self.source)


def _point(value, field_path: str) -> np.ndarray:
    """[x, y, z] of finite numbers (bool, text, 400-digit integers refused without an OverflowError)."""
    if not (isinstance(value, list) and len(value) == 3):
        raise DatagramError(field_path, f"expected [x, y, z], got {_shown(value)}")
    try:
        return np.array([finite_number(c, f"{field_path}[{i}]") for i, c in enumerate(value)])
    except ReadError as exc:
        raise DatagramError(exc.field_path, exc.detail) from None


def _shown(value) -> str:
    text = repr(value) if not isinstance(value, (dict, list)) or len(repr(value)) < 60 else type(value).__name__
    return text[:60]


def parse_datagram(data: bytes) -> tuple[int, np.ndarray]:
    """(frame, 15-d pose) of one datagram; DatagramError naming the field otherwise. The JSON goes through
    engine/safe_io.py (nesting limit, duplicate keys refused, no int-conversion error on huge integers)."""
    if len(data) > MAX_DATAGRAM_BYTES:
        raise DatagramError("", f"expected at most {MAX_DATAGRAM_BYTES} bytes, got {len(data)}")
    try:
        msg = parse_json(decode_text(bytes(data), "datagram"), "datagram", max_depth=8)
    except ReadError as exc:
        detail = exc.detail.replace("expected valid JSON", "expected UTF-8 JSON", 1)
        raise DatagramError(exc.field_path, detail) from None
    if not isinstance(msg, dict):
        raise DatagramError("", f"expected a JSON object, got {type(msg).__name__}")
    if msg.get("format") != FORMAT:
        raise DatagramError("format", f"expected {FORMAT!r}, got {_shown(msg.get('format'))}")
    joints = msg.get("joints")
    if not isinstance(joints, dict):
        raise DatagramError("joints", f"expected an object of joint positions, got {_shown(joints)}")
    pts = {name: _point(joints.get(name), f"joints.{name}") for name in JOINTS}
    up_value = msg.get("up", [0.0, 1.0, 0.0])
    up = _point(up_value, "up")
    if not np.any(up != 0):
        raise DatagramError("up", "expected a non-zero [x, y, z], got [0, 0, 0]")
    frame = msg.get("frame", 0)
    if not isinstance(frame, int) or isinstance(frame, bool) or not 0 <= frame < 2 ** 63:
        raise DatagramError("frame", f"expected an integer 0 ≤ frame < 2⁶³, got {_shown(frame)}")
    shoulder = np.stack([pts["right_shoulder"], pts["left_shoulder"]])
    elbow = np.stack([pts["right_elbow"], pts["left_elbow"]])
    hand = np.stack([pts["right_hand"], pts["left_hand"]])
    with np.errstate(all="ignore"):  # a degenerate skeleton gives NaN: refused below
        rot = body_frame(pts["hips"], pts["right_hip"], pts["left_hip"], up)
        pose = pose15_from_points(pts["hips"], shoulder, elbow, hand, rot)
    bone_norms = np.sqrt((pose * pose).reshape(5, 3).sum(axis=1))
    if not np.all(np.isfinite(pose)) or np.any(np.abs(bone_norms - 1.0) > 0.05):
        raise DatagramError("joints", "expected a skeleton, got coincident joints (degenerate)")
    return frame, pose


__all__ = ["FORMAT", "JOINTS", "datagrams_from_points", "parse_datagram", "DatagramError"]
