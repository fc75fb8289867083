"""motion_imitation / AMP_for_hardware frame files → keypoints by FK of the robot they were made for.

JSON with ``FrameDuration`` and ``Frames``; each frame is root xyz (3), root quaternion **x,y,z,w** (4) and
12 joint angles (hip, thigh, calf per leg), optionally followed by the AMP_for_hardware extras (61 values:
toe positions, velocities). The leg order differs per file (PROVENANCE.md of each source folder):

* 61-value AMP frames carry toe positions in the base frame, so the order is *measured*: the joints are
  put through A1's FK in both candidate orders and the one reproducing the file's toes wins;
* 19-value frames: pybullet order FR, FL, RR, RL, except the STMR trot/pace ``*_raw.txt`` clips, which
  are the AMP clips with FR↔FL and RR↔RL swapped (FL, FR, RL, RR; checked against the AMP toes).

Frames made for Laikago (Peng's clips: root quaternion starting at motion_imitation's INIT_ROT (0.5, 0.5,
0.5, 0.5)) go through the FK of that model (``laikago.py``). Contacts are estimated from foot height and speed.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from engine.retarget.contacts import estimate_contacts
from engine.retarget.importers import ImportFormatError, read_json
from engine.retarget.motion import LEGS, KeypointMotion
from engine.safe_io import ReadError, finite_number

PYBULLET_ORDER = ("FR", "FL", "RR", "RL")
ENGINE_ORDER = LEGS
# Per-file leg order of 19-value frames whose order is not pybullet's (stem → order).
FILE_LEG_ORDER = {stem: ENGINE_ORDER for stem in ("trot0_raw", "trot1_raw", "pace0_raw", "pace1_raw")}


def read_frames(path: Path) -> tuple[np.ndarray, float, dict]:
    data = read_json(path)
    name = path.name
    if not isinstance(data, dict):
        raise ImportFormatError(f"{name}: expected a JSON object with FrameDuration and Frames")
    dt = data.get("FrameDuration")
    if not isinstance(dt, (int, float)) or isinstance(dt, bool) or not (0.0001 <= dt < 10):
        raise ImportFormatError(f"{name}: FrameDuration: expected 0.0001 ≤ seconds < 10, got {dt!r}"[:200])
    frames = data.get("Frames")
    if not isinstance(frames, list) or len(frames) < 2:
        n = len(frames) if isinstance(frames, list) else "no"
        raise ImportFormatError(f"{name}: Frames: expected at least 2 frames, got {n}")
    width = len(frames[0]) if isinstance(frames[0], list) else -1
    if width not in (19, 61):
        raise ImportFormatError(f"{name}: Frames[0]: expected 19 (or 61 AMP) numbers, got {width}")
    for i, row in enumerate(frames):
        if not isinstance(row, list) or len(row) != width:
            raise ImportFormatError(f"{name}: Frames[{i}]: expected {width} numbers, got {len(row) if isinstance(row, list) else type(row).__name__}")
        for j, v in enumerate(row):
            try:
                finite_number(v, f"Frames[{i}][{j}]", name)  # also a 400-digit integer (no OverflowError)
            except ReadError as exc:
                raise ImportFormatError(exc.source, exc.field_path, exc.detail) from None
    arr = np.array(frames, dtype=float)
    norms = np.linalg.norm(arr[:, 3:7], axis=1)
    if np.any(np.abs(norms - 1) > 0.05):
        i = int(np.argmax(np.abs(norms - 1)))
        raise ImportFormatError(f"{name}: Frames[{i}][3:7]: expected a unit quaternion x,y,z,w, norm {norms[i]:.3f}")
    meta = {k: data[k] for k in ("LoopMode", "EnableCycleOffsetPosition", "EnableCycleOffsetRotation", "MotionWeight") if k in data}
    return arr, float(dt), meta


def pin_configurations(kin, frames: np.ndarray, order: tuple[str, ...]) -> np.ndarray:
    """Pinocchio q (T, 19) of A1-like robots from file frames in leg ``order``."""
    q = np.zeros((len(frames), kin.nq))
    q[:, 0:3] = frames[:, 0:3]
    q[:, 3:7] = frames[:, 3:7] / np.linalg.norm(frames[:, 3:7], axis=1, keepdims=True)
    legs = frames[:, 7:19].reshape(-1, 4, 3)
    for i, leg in enumerate(order):
        e = ENGINE_ORDER.index(leg)
        q[:, kin.leg_q[e]] = legs[:, i]
    return q


def keypoints_of(kin, q: np.ndarray) -> np.ndarray:
    data = kin.model.createData()
    return np.array([kin.keypoints(data, qi) for qi in q])


def _toe_error(kin, frames: np.ndarray, order: tuple[str, ...]) -> float:
    import pinocchio as pin

    q = pin_configurations(kin, frames, order)
    kp = keypoints_of(kin, q)
    toes = frames[:, 19:31].reshape(-1, 4, 3)  # base frame, file order
    err = 0.0
    for t in range(len(frames)):
        rot = pin.Quaternion(q[t, 3:7]).toRotationMatrix()
        local = (kp[t, 3::4] - q[t, :3]) @ rot
        file_local = local[[ENGINE_ORDER.index(leg) for leg in order]]
        err = max(err, float(np.abs(file_local - toes[t]).max()))
    return err


def import_frames(path: Path) -> KeypointMotion:
    from engine.retarget.quadruped.kinematics import quadruped_kinematics

    frames, dt, meta = read_frames(path)
    name = path.name
    first = frames[0, 3:7]
    if frames.shape[1] == 19 and np.allclose(np.abs(first), 0.5, atol=0.08):
        return _import_laikago(path, frames, dt, meta)
    kin = quadruped_kinematics("a1")
    if frames.shape[1] == 61:
        errors = {order: _toe_error(kin, frames, order) for order in (PYBULLET_ORDER, ENGINE_ORDER)}
        order = min(errors, key=lambda o: errors[o])
        how = f"measured from the toe positions (residual {errors[order] * 1000:.1f} mm)"
    else:
        order = FILE_LEG_ORDER.get(path.stem, PYBULLET_ORDER)
        how = "per-file table" if path.stem in FILE_LEG_ORDER else "pybullet default"
    q = pin_configurations(kin, frames, order)
    kp = keypoints_of(kin, q)
    fps = round(1.0 / dt, 6)
    contact = estimate_contacts(kp[:, 3::4], fps)
    quat = q[:, [6, 3, 4, 5]]
    return KeypointMotion(
        fps=fps, keypoints=kp, contact=contact, base_pos=q[:, 0:3].copy(), base_quat=quat,
        source={"file": name, "format": "motion-imitation", "robot": "a1", "frame_values": int(frames.shape[1]),
                "leg_order": ",".join(order), "leg_order_from": how, "contact_from": "estimated", **meta},
    )


def _import_laikago(path: Path, frames: np.ndarray, dt: float, meta: dict) -> KeypointMotion:
    from engine.retarget.importers.laikago import laikago_keypoints

    order = FILE_LEG_ORDER.get(path.stem, PYBULLET_ORDER)
    kp, base_pos, base_quat = laikago_keypoints(frames, order)
    ground = float(np.percentile(kp[:, 3::4, 2], 2))
    kp[:, :, 2] -= ground
    base_pos = base_pos.copy()
    base_pos[:, 2] -= ground
    fps = round(1.0 / dt, 6)
    contact = estimate_contacts(kp[:, 3::4], fps, 0.0)
    return KeypointMotion(
        fps=fps, keypoints=kp, contact=contact, base_pos=base_pos, base_quat=base_quat,
        source={"file": path.name, "format": "motion-imitation", "robot": "laikago (laikago_toes.urdf)",
                "frame_values": 19, "leg_order": ",".join(order), "leg_order_from": "pybullet default",
                "contact_from": "estimated", "ground_shift_m": -ground, **meta},
    )
