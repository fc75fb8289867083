"""The robot-motion files TMR reads and writes, in the retargeting side's npz layout (``robot-motion/1``).

Until the spatial stage's ``engine.retarget.motion.RobotMotion`` is on main, TMR works on any object with
``fps``, ``qpos`` (T, 7+n, MuJoCo order: xyz, quat w,x,y,z, joints), ``joint_names``, ``contact`` (T, 4) bool in
leg order FL, FR, RL, RR and ``robot``; this module's :class:`RobotMotion` is such an object, and it reads and
writes the same npz fields (``format``, ``fps``, ``qpos``, ``joint_names``, ``contact``, ``foot_names``, ``robot``,
``method``, ``source`` and ``metrics`` as JSON, optional ``keypoints``, ``qvel``, ``ctrl``) plus the dynamic
fields TMR adds (``pd_targets``, ``pd_kp``, ``pd_kd``, ``alpha``, ``segment_knots_s``, ``contact_sim``).
Written atomically; read with ``allow_pickle=False``.
"""

from __future__ import annotations

import io
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.atomic_io import atomic_write_bytes

ROBOT_FORMAT = "robot-motion/1"
LEGS = ("FL", "FR", "RL", "RR")
DYNAMIC_FIELDS = ("pd_targets", "pd_kp", "pd_kd", "alpha", "segment_knots_s", "contact_sim")


class MotionFileError(ValueError):
    """One line naming the file, the field and what was expected."""


@dataclass
class RobotMotion:
    fps: float
    qpos: np.ndarray
    joint_names: list[str]
    contact: np.ndarray
    robot: str
    method: str
    keypoints: np.ndarray | None = None
    qvel: np.ndarray | None = None
    ctrl: np.ndarray | None = None
    source: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)  # the dynamic fields (DYNAMIC_FIELDS)

    @property
    def frames(self) -> int:
        return int(self.qpos.shape[0])

    @property
    def duration_s(self) -> float:
        return (self.frames - 1) / self.fps

    def save(self, path: str | Path) -> None:
        arrays = {
            "format": np.array(ROBOT_FORMAT), "fps": np.array(float(self.fps)), "qpos": np.asarray(self.qpos, float),
            "joint_names": np.array(list(self.joint_names)), "contact": np.asarray(self.contact, bool),
            "foot_names": np.array(LEGS), "robot": np.array(self.robot), "method": np.array(self.method),
            "source": np.array(json.dumps(self.source)), "metrics": np.array(json.dumps(self.metrics)),
        }
        for key in ("keypoints", "qvel", "ctrl"):
            if getattr(self, key) is not None:
                arrays[key] = np.asarray(getattr(self, key), float)
        if self.keypoints is not None:
            arrays["keypoint_names"] = np.array([f"{leg}_{k}" for leg in LEGS for k in ("hip", "thigh", "knee", "foot")])
        for key, value in self.extra.items():
            arrays[key] = np.asarray(value)
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        atomic_write_bytes(path, buf.getvalue())


def load_robot_motion(path: str | Path) -> RobotMotion:
    where = Path(path).name
    try:
        with np.load(path, allow_pickle=False) as f:
            data = {k: f[k] for k in f.files}
    except FileNotFoundError:
        raise MotionFileError(f"{where}: file not found") from None
    except Exception as exc:  # noqa: BLE001 - any unreadable file is one line
        raise MotionFileError(f"{where}: expected an npz robot motion ({type(exc).__name__})") from None
    fmt = str(data.get("format", ""))
    if fmt != ROBOT_FORMAT:
        raise MotionFileError(f"{where}: format: expected {ROBOT_FORMAT!r} (a retargeted robot motion), got {fmt or 'nothing'!r}")
    for key in ("fps", "qpos", "joint_names", "contact", "robot"):
        if key not in data:
            raise MotionFileError(f"{where}: {key}: missing")
    try:
        fps = float(np.asarray(data["fps"]).reshape(()))
    except (TypeError, ValueError):
        raise MotionFileError(f"{where}: fps: expected a number") from None
    if not (np.isfinite(fps) and 0 < fps <= 10000):
        raise MotionFileError(f"{where}: fps: expected 0 < fps ≤ 10000, got {fps}")
    qpos = np.asarray(data["qpos"])
    if qpos.dtype.kind not in "fi" or qpos.ndim != 2 or qpos.shape[1] < 7:
        raise MotionFileError(f"{where}: qpos: expected numbers of shape (T, 7 + n), got {qpos.shape}")
    qpos = qpos.astype(float)
    if not np.all(np.isfinite(qpos)):
        raise MotionFileError(f"{where}: qpos: expected finite numbers")
    T = qpos.shape[0]
    norms = np.linalg.norm(qpos[:, 3:7], axis=1)
    if np.any(np.abs(norms - 1.0) > 1e-3):
        raise MotionFileError(f"{where}: qpos[:, 3:7]: expected unit quaternions (w,x,y,z)")
    qpos[:, 3:7] /= norms[:, None]
    names = [str(x) for x in np.asarray(data["joint_names"]).ravel()]
    if len(names) != qpos.shape[1] - 7:
        raise MotionFileError(f"{where}: joint_names: expected {qpos.shape[1] - 7} names, got {len(names)}")
    contact = np.asarray(data["contact"])
    if contact.shape != (T, 4):
        raise MotionFileError(f"{where}: contact: expected shape ({T}, 4) (feet FL, FR, RL, RR), got {contact.shape}")
    feet = [str(x) for x in np.asarray(data.get("foot_names", np.array(LEGS))).ravel()]
    if tuple(feet) != LEGS:
        raise MotionFileError(f"{where}: foot_names: expected {', '.join(LEGS)}, got {', '.join(feet)}")
    source = _json(where, data, "source")
    metrics = _json(where, data, "metrics")
    source.setdefault("file", where)
    extra = {k: data[k] for k in DYNAMIC_FIELDS if k in data}
    return RobotMotion(fps=fps, qpos=qpos, joint_names=names, contact=contact.astype(bool), robot=str(data["robot"]),
                       method=str(data.get("method", "unknown")), keypoints=data.get("keypoints"), qvel=data.get("qvel"),
                       ctrl=data.get("ctrl"), source=source, metrics=metrics, extra=extra)


def _json(where: str, data: dict, key: str) -> dict:
    if key not in data:
        return {}
    try:
        value = json.loads(str(data[key]))
    except json.JSONDecodeError:
        raise MotionFileError(f"{where}: {key}: expected a JSON object") from None
    if not isinstance(value, dict):
        raise MotionFileError(f"{where}: {key}: expected a JSON object")
    return value
