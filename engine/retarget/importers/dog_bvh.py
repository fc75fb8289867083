"""MANN dog BVH (Zhang et al. 2018) → keypoints.

A small BVH reader specific to what the dog files need (engine/retarget/importers/bvh.py, the general human
BVH reader another branch is writing, was not on main when this was written): HIERARCHY with ROOT / JOINT /
End Site, OFFSET, CHANNELS (6 on the root: X/Y/Zposition + rotations, 3 elsewhere: rotations in the listed
order, intrinsic), MOTION with Frames and Frame Time. Forward kinematics gives the 21 joints + 6 end sites in
depth-first order — exactly the 27 points of motion_imitation's ``dog_*_joint_pos.txt`` (checked: same
frames, centimetres → metres) — and the dog keypoint mapping of ``dog_keypoints`` applies. Required joints
missing from a file are reported by name.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from engine.retarget.contacts import estimate_contacts
from engine.retarget.importers import ImportFormatError
from engine.retarget.importers.dog_keypoints import POINTS, Y_UP_TO_Z_UP, keypoints_from_points
from engine.retarget.motion import KeypointMotion

CM_TO_M = 0.01
REQUIRED = ("Hips", "LeftArm", "LeftForeArm", "LeftHand", "RightArm", "RightForeArm", "RightHand",
            "LeftUpLeg", "LeftLeg", "LeftFoot", "RightUpLeg", "RightLeg", "RightFoot")


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


def parse_bvh(path: Path) -> Bvh:
    name = path.name
    try:
        tokens_by_line = [ln.split() for ln in path.read_text(encoding="utf-8", errors="strict").splitlines()]
    except UnicodeDecodeError:
        raise ImportFormatError(f"{name}: expected BVH text") from None
    nodes: list[BvhNode] = []
    stack: list[int] = []
    i = 0
    pending: BvhNode | None = None
    while i < len(tokens_by_line):
        tok = tokens_by_line[i]
        i += 1
        if not tok:
            continue
        key = tok[0]
        if key == "HIERARCHY":
            continue
        if key in ("ROOT", "JOINT"):
            if len(tok) < 2:
                raise ImportFormatError(f"{name}: line {i}: {key} without a name")
            pending = BvhNode(tok[1], stack[-1] if stack else -1, np.zeros(3))
        elif key == "End":
            pending = BvhNode(f"{nodes[stack[-1]].name}_end" if stack else "end", stack[-1] if stack else -1, np.zeros(3), end_site=True)
        elif key == "{":
            if pending is None:
                raise ImportFormatError(f"{name}: line {i}: '{{' without a joint")
            nodes.append(pending)
            stack.append(len(nodes) - 1)
            pending = None
        elif key == "}":
            if not stack:
                raise ImportFormatError(f"{name}: line {i}: unbalanced '}}'")
            stack.pop()
        elif key == "OFFSET":
            try:
                nodes[stack[-1]].offset = np.array([float(v) for v in tok[1:4]])
            except (ValueError, IndexError):
                raise ImportFormatError(f"{name}: line {i}: OFFSET: expected three numbers") from None
        elif key == "CHANNELS":
            try:
                n = int(tok[1])
            except (ValueError, IndexError):
                raise ImportFormatError(f"{name}: line {i}: CHANNELS: expected a count") from None
            if len(tok) != n + 2:
                raise ImportFormatError(f"{name}: line {i}: CHANNELS: expected {n} channel names")
            nodes[stack[-1]].channels = tok[2:]
        elif key == "MOTION":
            break
        else:
            raise ImportFormatError(f"{name}: line {i}: unexpected {key!r} in HIERARCHY")
    if not nodes or stack:
        raise ImportFormatError(f"{name}: HIERARCHY: expected a complete joint tree")
    header: dict[str, str] = {}
    while i < len(tokens_by_line) and len(header) < 2:
        tok = tokens_by_line[i]
        i += 1
        if tok and tok[0] == "Frames:":
            header["frames"] = tok[1] if len(tok) > 1 else ""
        elif tok and tok[0] == "Frame" and len(tok) > 2:
            header["time"] = tok[2]
    try:
        n_frames, frame_time = int(header["frames"]), float(header["time"])
    except (KeyError, ValueError):
        raise ImportFormatError(f"{name}: MOTION: expected 'Frames: N' and 'Frame Time: dt'") from None
    if not 0 < frame_time < 10:
        raise ImportFormatError(f"{name}: MOTION: Frame Time: expected a positive number of seconds, got {frame_time}")
    n_channels = sum(len(n.channels) for n in nodes)
    rows = [t for t in tokens_by_line[i:] if t]
    if len(rows) < n_frames:
        raise ImportFormatError(f"{name}: MOTION: expected {n_frames} frames, found {len(rows)} (truncated?)")
    if n_frames < 2:
        raise ImportFormatError(f"{name}: MOTION: expected at least 2 frames, got {n_frames}")
    motion = np.empty((n_frames, n_channels))
    for f, row in enumerate(rows[:n_frames]):
        if len(row) != n_channels:
            raise ImportFormatError(f"{name}: MOTION frame {f}: expected {n_channels} numbers, got {len(row)}")
        try:
            motion[f] = [float(v) for v in row]
        except ValueError:
            raise ImportFormatError(f"{name}: MOTION frame {f}: expected numbers") from None
    if not np.all(np.isfinite(motion)):
        raise ImportFormatError(f"{name}: MOTION: expected finite numbers")
    return Bvh(nodes, frame_time, motion)


def forward_kinematics(bvh: Bvh) -> np.ndarray:
    """World positions (T, nodes, 3) of every joint and end site, in the file's units and axes."""
    t_n = len(bvh.motion)
    pos = np.zeros((t_n, len(bvh.nodes), 3))
    rot = np.zeros((t_n, len(bvh.nodes), 3, 3))
    col = 0
    for k, node in enumerate(bvh.nodes):
        local_t = np.tile(node.offset, (t_n, 1))
        local_r = np.tile(np.eye(3), (t_n, 1, 1))
        rot_axes, rot_cols = "", []
        for c in node.channels:
            axis = c[0].upper()
            if c.endswith("position"):
                local_t[:, "XYZ".index(axis)] = bvh.motion[:, col] + (0.0 if node.parent >= 0 else 0.0)
            else:
                rot_axes += axis
                rot_cols.append(col)
            col += 1
        if node.parent < 0 and any(c.endswith("position") for c in node.channels):
            pass  # root: the position channels replace the offset
        if rot_axes:
            local_r = Rotation.from_euler(rot_axes, bvh.motion[:, rot_cols], degrees=True).as_matrix()
        if node.parent < 0:
            pos[:, k], rot[:, k] = local_t, local_r
        else:
            p = node.parent
            pos[:, k] = pos[:, p] + np.einsum("tij,tj->ti", rot[:, p], local_t)
            rot[:, k] = rot[:, p] @ local_r
    return pos


def import_dog_bvh(path: Path) -> KeypointMotion:
    bvh = parse_bvh(path)
    names = [n.name for n in bvh.nodes]
    missing = [j for j in REQUIRED if j not in names]
    if missing:
        raise ImportFormatError(f"{path.name}: HIERARCHY: expected the MANN dog skeleton, joint {missing[0]!r} is missing")
    if len(bvh.nodes) != 27:
        raise ImportFormatError(f"{path.name}: HIERARCHY: expected 21 joints + 6 end sites (MANN dog), got {len(bvh.nodes)} nodes")
    points = forward_kinematics(bvh) * CM_TO_M @ Y_UP_TO_Z_UP.T
    kp = keypoints_from_points(points)
    fps = round(1.0 / bvh.frame_time_s, 3)
    ground = float(np.percentile(kp[:, 3::4, 2], 2))
    kp[:, :, 2] -= ground
    contact = estimate_contacts(kp[:, 3::4], fps, 0.0)
    return KeypointMotion(
        fps=fps, keypoints=kp, contact=contact,
        source={"file": path.name, "format": "dog-bvh", "contact_from": "estimated", "ground_shift_m": -ground,
                "points": [bvh.nodes[i].name for leg in POINTS for i in leg],
                "licence": "MANN dog mocap: research use only, not redistributable"},
    )
