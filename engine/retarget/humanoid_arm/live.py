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
import math

import numpy as np

from engine.retarget.humanoid_arm.pose15 import MocapPoints, body_frame, pose15_from_points

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


class DatagramError(ValueError):
    """A malformed datagram (one line)."""


def parse_datagram(data: bytes) -> tuple[int, np.ndarray]:
    """(frame, 15-d pose) of one datagram; DatagramError naming the field otherwise."""
    if len(data) > MAX_DATAGRAM_BYTES:
        raise DatagramError(f"datagram: expected at most {MAX_DATAGRAM_BYTES} bytes, got {len(data)}")
    try:
        msg = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DatagramError(f"datagram: expected UTF-8 JSON ({exc.__class__.__name__})") from None
    if not isinstance(msg, dict):
        raise DatagramError("datagram: expected a JSON object")
    if msg.get("format") != FORMAT:
        raise DatagramError(f"datagram.format: expected {FORMAT!r}, got {msg.get('format')!r}")
    joints = msg.get("joints")
    if not isinstance(joints, dict):
        raise DatagramError("datagram.joints: expected an object of joint positions")
    pts = {}
    for name in JOINTS:
        v = joints.get(name)
        if not (isinstance(v, list) and len(v) == 3 and all(isinstance(c, (int, float)) for c in v)):
            raise DatagramError(f"datagram.joints.{name}: expected [x, y, z], got {v!r}"[:200])
        if not all(math.isfinite(c) for c in v):
            raise DatagramError(f"datagram.joints.{name}: expected finite numbers, got {v!r}")
        pts[name] = np.array(v, dtype=float)
    up = msg.get("up", [0.0, 1.0, 0.0])
    if not (isinstance(up, list) and len(up) == 3 and all(isinstance(c, (int, float)) and math.isfinite(c) for c in up)
            and any(c != 0 for c in up)):
        raise DatagramError(f"datagram.up: expected a non-zero [x, y, z], got {up!r}")
    frame = msg.get("frame", 0)
    if not isinstance(frame, int):
        raise DatagramError(f"datagram.frame: expected an integer, got {frame!r}")
    shoulder = np.stack([pts["right_shoulder"], pts["left_shoulder"]])
    elbow = np.stack([pts["right_elbow"], pts["left_elbow"]])
    hand = np.stack([pts["right_hand"], pts["left_hand"]])
    rot = body_frame(pts["hips"], pts["right_hip"], pts["left_hip"], np.array(up, dtype=float))
    pose = pose15_from_points(pts["hips"], shoulder, elbow, hand, rot)
    if not np.all(np.isfinite(pose)):
        raise DatagramError("datagram.joints: degenerate skeleton (coincident joints)")
    return frame, pose


__all__ = ["FORMAT", "JOINTS", "datagrams_from_points", "parse_datagram", "DatagramError"]
