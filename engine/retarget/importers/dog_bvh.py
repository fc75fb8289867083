"""MANN dog BVH (Zhang et al. 2018) → keypoints.

Read by the general BVH reader (engine/retarget/importers/bvh.py: bounded size, depth, joints and joints ×
frames, strict tokens, finite values; its errors are one line), then checked for what the dog mapping needs:
the MANN skeleton — HIERARCHY with the 21 joints + 6 end sites in depth-first order, exactly the 27 points of
motion_imitation's ``dog_*_joint_pos.txt`` (checked: same frames, centimetres → metres) — at least 2 and at
most :data:`MAX_FRAMES` frames, offsets and channel values with |x| ≤ 1e9 (posing never overflows), legs with
length. Required joints missing from a file are reported by name. The dog keypoint mapping of
``dog_keypoints`` applies.

Forward kinematics is the general reader's: rotation channels in the listed order as intrinsic rotations
(degrees), position channels replacing the offset. End sites are named ``<parent>_end`` here (the points of
``source["points"]``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.retarget.importers import ImportFormatError
from engine.retarget.importers.bvh import BvhError, BvhMotion, load_bvh
from engine.retarget.importers.dog_keypoints import POINTS, Y_UP_TO_Z_UP, check_legs, dog_motion, keypoints_from_points
from engine.retarget.motion import MAX_ABS_VALUE, KeypointMotion

CM_TO_M = 0.01
REQUIRED = ("Hips", "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm", "RightHand",
            "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot")
N_NODES = 27
MAX_FRAMES = 36_000  # 10 minutes at 60 fps (the longest MANN clip is ~2 minutes); posing allocates (F, 27, 3, 3)


@dataclass
class BvhNode:
    name: str
    parent: int
    offset: np.ndarray
    channels: list[str] = field(default_factory=list)
    end_site: bool = False


@dataclass
class Bvh:
    nodes: list[BvhNode]
    frame_time_s: float
    motion: np.ndarray  # (T, channels)
    clip: BvhMotion  # what the general reader read (its forward kinematics)


def parse_bvh(path: Path) -> Bvh:
    """The file through the general BVH reader; ImportFormatError (one line) on anything malformed."""
    name = path.name
    try:
        clip = load_bvh(path)
    except BvhError as exc:
        raise ImportFormatError(name, exc.field_path, exc.detail) from None
    nodes = [BvhNode(f"{j.name[:-4]}_end" if j.is_end_site else j.name, j.parent, j.offset, list(j.channels),
                     j.is_end_site) for j in clip.joints]
    if clip.n_frames < 2:
        raise ImportFormatError(name, "MOTION: Frames", f"expected at least 2 frames, got {clip.n_frames}")
    if clip.n_frames > MAX_FRAMES:
        raise ImportFormatError(name, "MOTION: Frames", f"expected at most {MAX_FRAMES} frames (10 minutes at 60 "
                                f"fps), got {clip.n_frames}")
    for node in nodes:
        if not np.all(np.abs(node.offset) <= MAX_ABS_VALUE):
            raise ImportFormatError(name, f"joint {node.name}: OFFSET", f"expected |x| ≤ {MAX_ABS_VALUE:g}, got "
                                    f"{' '.join(f'{v:g}' for v in node.offset)}")
    if clip.values.size and np.abs(clip.values).max() > MAX_ABS_VALUE:
        f, c = np.unravel_index(int(np.argmax(np.abs(clip.values))), clip.values.shape)
        raise ImportFormatError(name, f"MOTION: frame {f}, channel {c}",
                                f"expected |x| ≤ {MAX_ABS_VALUE:g}, got {clip.values[f, c]:g}")
    return Bvh(nodes, clip.frame_time_s, clip.values, clip)


def forward_kinematics(bvh: Bvh) -> np.ndarray:
    """World positions (T, nodes, 3) of every joint and end site, in the file's units and axes."""
    return bvh.clip.global_positions()


def import_dog_bvh(path: Path) -> KeypointMotion:
    bvh = parse_bvh(path)
    names = [n.name for n in bvh.nodes]
    missing = [j for j in REQUIRED if j not in names]
    if missing:
        raise ImportFormatError(path.name, "HIERARCHY", f"expected the MANN dog skeleton, joint {missing[0]!r} is "
                                "missing")
    if len(bvh.nodes) != N_NODES:
        raise ImportFormatError(path.name, "HIERARCHY", f"expected 21 joints + 6 end sites (MANN dog), got "
                                f"{len(bvh.nodes)} nodes")
    points = forward_kinematics(bvh) * CM_TO_M @ Y_UP_TO_Z_UP.T
    kp = keypoints_from_points(points)
    check_legs(kp, path.name, "HIERARCHY")
    return dog_motion(kp, round(1.0 / bvh.frame_time_s, 3), path.name, {
        "format": "dog-bvh", "points": [bvh.nodes[i].name for leg in POINTS for i in leg],
        "licence": "MANN dog mocap: research use only, not redistributable"})
