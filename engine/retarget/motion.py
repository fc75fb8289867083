"""The two motion formats of the retargeting side: what sources import to, what methods produce.

``KeypointMotion`` — a source motion as the paper's 16 keypoints (§IV-A): 4 legs × (hip, thigh, knee, foot),
legs in the engine's order FL, FR, RL, RR (keypoint ``4 * leg + k``), positions in metres, world frame, z up.

``RobotMotion`` — a motion of one robot: ``qpos`` (T, 7 + n) in MuJoCo order (xyz, quaternion w,x,y,z,
joints in ``joint_names`` order). Nothing here is quadruped-specific, so a biped recording is one too
(contact then has one column per foot of that robot, named by ``foot_names``). A dynamic motion (TMR, the
temporal stage) adds ``qvel``, ``ctrl`` (joint torques, ``joint_names`` order) and the fields of
``DYNAMIC_FIELDS`` in ``extra``: ``pd_targets`` (T, n) with ``pd_kp``/``pd_kd`` (n,) — the PD targets that
reproduce the torques, τ = K_p (θ* − θ) − K_d θ̇ —, ``alpha`` (S,), ``segment_knots_s`` (S + 1,) in the
motion's time, and ``contact_sim`` (T, F) the feet touching the floor in the physics replay.

Both are npz files written atomically and read with ``allow_pickle=False``. Validation errors are one line
naming the file and the field (``MotionFormatError``).
"""

from __future__ import annotations

import io
import json
from dataclasses import InitVar, dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from engine.atomic_io import atomic_write_bytes
from engine.safe_io import ReadError, parse_json, read_npz, split_message

LEGS = ("FL", "FR", "RL", "RR")
KEYPOINT_KINDS = ("hip", "thigh", "knee", "foot")
KEYPOINT_NAMES = tuple(f"{leg}_{kind}" for leg in LEGS for kind in KEYPOINT_KINDS)
N_KEYPOINTS = len(KEYPOINT_NAMES)
FOOT_INDEX = tuple(4 * i + 3 for i in range(4))  # κ(j): keypoint index of foot j
KEYPOINT_FORMAT = "keypoint-motion/1"
ROBOT_FORMAT = "robot-motion/1"
DYNAMIC_FIELDS = ("pd_targets", "pd_kp", "pd_kd", "alpha", "segment_knots_s", "contact_sim")


class MotionFormatError(ReadError):
    """A malformed motion: one line naming the file and the field (engine/safe_io.py's ReadError).

    ``MotionFormatError(source, field_path, detail)``; the one-string form (``f"{name}: {field}: expected …"``, as
    the importers raise it) is split into those parts by :func:`engine.safe_io.split_message`."""

    def __init__(self, source: str, field_path: str | None = None, detail: str | None = None):
        if field_path is None and detail is None:
            source, field_path, detail = split_message(source)
        super().__init__(source, field_path or "", detail or "")


def _fail(where: str, field_name: str, what: str) -> MotionFormatError:
    return MotionFormatError(where, field_name, what)


def _finite(where: str, name: str, arr: np.ndarray) -> None:
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise _fail(where, name, f"expected finite numbers, found {arr[tuple(bad)]} at index {tuple(int(b) for b in bad)}")


MAX_ABS_VALUE = 1e9  # no field of a motion (m, rad, m/s, N·m, gains, s) is meaningful beyond this


def _float_array(where: str, name: str, value: Any, shape: tuple) -> np.ndarray:
    try:
        kind = np.asarray(value).dtype.kind
        if kind not in "iuf":  # text, booleans, complex or objects are not numbers here (np.array parses "1.5")
            raise TypeError
        arr = np.array(value, dtype=float)  # a copy: arrays from Ray or np.load may be read-only
    except (TypeError, ValueError, OverflowError):
        raise _fail(where, name, f"expected numbers of shape {_shape_text(shape)}") from None
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        raise _fail(where, name, f"expected shape {_shape_text(shape)}, got {arr.shape}")
    _finite(where, name, arr)
    if arr.size and np.abs(arr).max() > MAX_ABS_VALUE:
        bad = np.unravel_index(int(np.argmax(np.abs(arr))), arr.shape)
        raise _fail(where, name, f"expected |x| ≤ {MAX_ABS_VALUE:g}, found {arr[bad]:g} at index "
                    f"{tuple(int(b) for b in bad)}")
    return arr


def _shape_text(shape: tuple) -> str:
    return "(" + ", ".join("T" if s is None and i == 0 else ("n" if s is None else str(s)) for i, s in enumerate(shape)) + ")"


def _fps(where: str, value: Any) -> float:
    try:
        arr = np.asarray(value)
        if arr.dtype.kind not in "iuf":
            raise TypeError
        fps = float(arr.reshape(()))
    except (TypeError, ValueError, OverflowError):
        shown = f"shape {arr.shape} {arr.dtype}" if isinstance(value, np.ndarray) else repr(value)[:40]
        raise _fail(where, "fps", f"expected a number, got {shown}") from None
    if not np.isfinite(fps) or fps <= 0 or fps > 10000:
        raise _fail(where, "fps", f"expected 0 < fps ≤ 10000, got {fps}")
    return fps


def _names(where: str, name: str, value: Any, n: int | None) -> list[str]:
    """``n`` names (``None``: one or more) as a 1-D text array or list."""
    count = "one or more" if n is None else str(n)
    try:
        arr = np.asarray(value)
    except ValueError:  # a ragged list
        raise _fail(where, name, f"expected {count} names") from None
    if arr.ndim != 1 or (len(arr) != n if n is not None else not len(arr)) or arr.dtype.kind != "U":
        raise _fail(where, name, f"expected {count} names, got {arr.shape} {arr.dtype}")
    return [str(x) for x in arr]


def _text(where: str, name: str, value: Any) -> str:
    """A one-line name (robot, method) stored as a 0-d text array (or given as a str)."""
    arr = np.asarray(value)
    if arr.ndim != 0 or arr.dtype.kind != "U":
        raise _fail(where, name, f"expected a name (text), got shape {arr.shape} {arr.dtype}")
    text = str(arr)
    if not text or len(text) > 64 or not text.isprintable() or "/" in text or "\\" in text:
        raise _fail(where, name, f"expected a name of at most 64 printable characters, got {text[:40]!r}")
    return text


def _contact(where: str, value: Any, t: int, k: int, name: str = "contact") -> np.ndarray:
    try:
        arr = np.asarray(value)
    except ValueError:  # a ragged list
        raise _fail(where, name, f"expected shape ({t}, {k})") from None
    if arr.shape != (t, k):
        raise _fail(where, name, f"expected shape ({t}, {k}), got {arr.shape}")
    if arr.dtype != bool:
        if arr.dtype.kind not in "iuf" or not np.all(np.isin(arr, (0, 1))):
            raise _fail(where, name, "expected booleans (0/1)")
        arr = arr.astype(bool)
    return arr


def _quat(where: str, name: str, value: Any, t: int) -> np.ndarray:
    q = _float_array(where, name, value, (t, 4))
    norm = np.linalg.norm(q, axis=1)
    if np.any(np.abs(norm - 1.0) > 1e-3):
        i = int(np.argmax(np.abs(norm - 1.0)))
        raise _fail(where, name, f"expected unit quaternions (w,x,y,z), frame {i} has norm {norm[i]:.4f}")
    return q / norm[:, None]


@dataclass
class KeypointMotion:
    """Source keypoints (T, 16, 3), legs FL, FR, RL, RR × (hip, thigh, knee, foot), world frame, metres."""

    fps: float
    keypoints: np.ndarray
    contact: np.ndarray  # (T, 4) bool, feet in LEGS order
    keypoint_names: list[str] = field(default_factory=lambda: list(KEYPOINT_NAMES))
    foot_names: list[str] = field(default_factory=lambda: list(LEGS))
    base_pos: np.ndarray | None = None  # (T, 3)
    base_quat: np.ndarray | None = None  # (T, 4) w,x,y,z
    source: dict = field(default_factory=dict)  # free metadata: file, format, licence note, …
    known: np.ndarray | None = None  # (16,) bool: keypoints the source measured (False: filled from the target)
    loaded_from: InitVar[str | None] = None  # the file's name in error messages (``source["file"]`` is metadata)

    def __post_init__(self, loaded_from: str | None = None) -> None:
        self.validate(loaded_from or self.source.get("file", "<keypoint motion>"))

    @property
    def frames(self) -> int:
        return int(self.keypoints.shape[0])

    @property
    def duration_s(self) -> float:
        return self.frames / self.fps

    @property
    def feet(self) -> np.ndarray:
        return self.keypoints[:, list(FOOT_INDEX)]

    def validate(self, where: str) -> None:
        self.fps = _fps(where, self.fps)
        self.keypoints = _float_array(where, "keypoints", self.keypoints, (None, N_KEYPOINTS, 3))
        t = self.keypoints.shape[0]
        if t < 2:
            raise _fail(where, "keypoints", f"expected at least 2 frames, got {t}")
        self.keypoint_names = _names(where, "keypoint_names", self.keypoint_names, N_KEYPOINTS)
        if tuple(self.keypoint_names) != KEYPOINT_NAMES:
            raise _fail(where, "keypoint_names", f"expected {', '.join(KEYPOINT_NAMES)}")
        self.foot_names = _names(where, "foot_names", self.foot_names, 4)
        if tuple(self.foot_names) != LEGS:
            raise _fail(where, "foot_names", f"expected {', '.join(LEGS)} (the engine's leg order)")
        self.contact = _contact(where, self.contact, t, 4)
        if self.base_pos is not None:
            self.base_pos = _float_array(where, "base_pos", self.base_pos, (t, 3))
        if self.base_quat is not None:
            self.base_quat = _quat(where, "base_quat", self.base_quat, t)
        if self.known is None:
            self.known = np.ones(N_KEYPOINTS, dtype=bool)
        known = np.asarray(self.known)
        if known.shape != (N_KEYPOINTS,) or known.dtype.kind not in "biu" or not np.all(np.isin(known, (0, 1))):
            raise _fail(where, "known", f"expected {N_KEYPOINTS} booleans, got {known.shape} {known.dtype}")
        self.known = known.astype(bool)
        if not isinstance(self.source, dict):
            raise _fail(where, "source", "expected a JSON object")

    def save(self, path: str | Path) -> None:
        arrays = {
            "format": np.array(KEYPOINT_FORMAT), "fps": np.array(self.fps), "keypoints": self.keypoints,
            "keypoint_names": np.array(self.keypoint_names), "contact": self.contact,
            "foot_names": np.array(self.foot_names), "known": self.known,
            "source": np.array(json.dumps(self.source)),
        }
        if self.base_pos is not None:
            arrays["base_pos"] = self.base_pos
        if self.base_quat is not None:
            arrays["base_quat"] = self.base_quat
        _write_npz(path, arrays)

    @classmethod
    def load(cls, path: str | Path) -> "KeypointMotion":
        where = Path(path).name
        data = _read_npz(path)
        if str(data.get("format", "")) != KEYPOINT_FORMAT:
            raise _fail(where, "format", f"expected {KEYPOINT_FORMAT!r}, got {str(data.get('format', 'nothing'))!r}")
        for key in ("fps", "keypoints", "contact"):
            if key not in data:
                raise _fail(where, key, "missing")
        source = _source(where, data)
        source.setdefault("file", where)
        return cls(
            fps=data["fps"], keypoints=data["keypoints"], contact=data["contact"],
            keypoint_names=data.get("keypoint_names", np.array(KEYPOINT_NAMES)),
            foot_names=data.get("foot_names", np.array(LEGS)), base_pos=data.get("base_pos"),
            base_quat=data.get("base_quat"), source=source, known=data.get("known"), loaded_from=where,
        )


@dataclass
class RobotMotion:
    """A robot's motion: qpos (T, 7+n) in MuJoCo order (xyz, quat w,x,y,z, joints in ``joint_names`` order)."""

    fps: float
    qpos: np.ndarray
    joint_names: list[str]
    contact: np.ndarray  # (T, F) bool, one column per foot in foot_names
    robot: str
    method: str
    foot_names: list[str] = field(default_factory=lambda: list(LEGS))
    keypoints: np.ndarray | None = None  # (T, K, 3) robot sites (quadrupeds: the 16 keypoints)
    keypoint_names: list[str] | None = None
    qvel: np.ndarray | None = None  # (T, 6+n) MuJoCo qvel (world linear, body angular, joints)
    ctrl: np.ndarray | None = None  # (T, n) joint torques in joint_names order (temporal stage)
    source: dict = field(default_factory=dict)
    metrics: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)  # the dynamic fields (DYNAMIC_FIELDS), see the module docstring
    loaded_from: InitVar[str | None] = None  # the file's name in error messages (``source["file"]`` is metadata)

    def __post_init__(self, loaded_from: str | None = None) -> None:
        self.validate(loaded_from or self.source.get("file", "<robot motion>"))

    @property
    def frames(self) -> int:
        return int(self.qpos.shape[0])

    @property
    def duration_s(self) -> float:
        return self.frames / self.fps

    @property
    def base_pos(self) -> np.ndarray:
        return self.qpos[:, 0:3]

    @property
    def base_quat(self) -> np.ndarray:
        return self.qpos[:, 3:7]

    @property
    def joints(self) -> np.ndarray:
        return self.qpos[:, 7:]

    def validate(self, where: str) -> None:
        self.fps = _fps(where, self.fps)
        self.qpos = _float_array(where, "qpos", self.qpos, (None, None))
        t, nq = self.qpos.shape
        if t < 1:
            raise _fail(where, "qpos", "expected at least 1 frame, got 0")
        if nq < 7:
            raise _fail(where, "qpos", f"expected (T, 7 + n) columns, got {nq}")
        self.qpos[:, 3:7] = _quat(where, "qpos[:, 3:7]", self.qpos[:, 3:7], t)
        self.joint_names = _names(where, "joint_names", self.joint_names, nq - 7)
        self.foot_names = _names(where, "foot_names", self.foot_names, None)
        self.contact = _contact(where, self.contact, t, len(self.foot_names))
        self.robot = _text(where, "robot", self.robot)
        self.method = _text(where, "method", self.method)
        if self.keypoints is not None:
            self.keypoints = _float_array(where, "keypoints", self.keypoints, (t, None, 3))
            k = self.keypoints.shape[1]
            if self.keypoint_names is None:
                self.keypoint_names = list(KEYPOINT_NAMES) if k == N_KEYPOINTS else [f"k{i}" for i in range(k)]
            self.keypoint_names = _names(where, "keypoint_names", self.keypoint_names, k)
        if self.qvel is not None:
            self.qvel = _float_array(where, "qvel", self.qvel, (t, nq - 1))
        if self.ctrl is not None:
            self.ctrl = _float_array(where, "ctrl", self.ctrl, (t, None))
        self.extra = _dynamic_fields(where, self.extra, t, nq - 7, len(self.foot_names))

    def save(self, path: str | Path) -> None:
        _write_npz(path, self.arrays())

    def arrays(self) -> dict[str, np.ndarray]:
        """The npz's entries (what :meth:`save` writes; a writer may add its own keys beside them)."""
        arrays = {
            "format": np.array(ROBOT_FORMAT), "fps": np.array(self.fps), "qpos": self.qpos,
            "joint_names": np.array(self.joint_names), "contact": self.contact,
            "foot_names": np.array(self.foot_names), "robot": np.array(self.robot), "method": np.array(self.method),
            "source": np.array(json.dumps(self.source)), "metrics": np.array(json.dumps(self.metrics)),
        }
        if self.keypoints is not None:
            arrays["keypoints"] = self.keypoints
            arrays["keypoint_names"] = np.array(self.keypoint_names)
        if self.qvel is not None:
            arrays["qvel"] = self.qvel
        if self.ctrl is not None:
            arrays["ctrl"] = self.ctrl
        for key, value in self.extra.items():
            arrays[key] = value
        return arrays

    @classmethod
    def load(cls, path: str | Path) -> "RobotMotion":
        where = Path(path).name
        data = _read_npz(path)
        if str(data.get("format", "")) != ROBOT_FORMAT:
            raise _fail(where, "format", f"expected {ROBOT_FORMAT!r}, got {str(data.get('format', 'nothing'))!r}")
        for key in ("fps", "qpos", "joint_names", "contact", "robot", "method"):
            if key not in data:
                raise _fail(where, key, "missing")
        source = _source(where, data)
        source.setdefault("file", where)
        metrics = _json_field(where, data, "metrics")
        return cls(
            fps=data["fps"], qpos=data["qpos"], joint_names=data["joint_names"], contact=data["contact"],
            robot=_text(where, "robot", data["robot"]), method=_text(where, "method", data["method"]),
            foot_names=data.get("foot_names", np.array(LEGS)), keypoints=data.get("keypoints"),
            keypoint_names=data.get("keypoint_names"), qvel=data.get("qvel"), ctrl=data.get("ctrl"),
            source=source, metrics=metrics,
            extra={k: data[k] for k in DYNAMIC_FIELDS if k in data}, loaded_from=where,
        )


def _dynamic_fields(where: str, extra: Any, t: int, n: int, feet: int) -> dict:
    if not isinstance(extra, dict):
        raise _fail(where, "extra", f"expected a mapping of {', '.join(DYNAMIC_FIELDS)}")
    unknown = sorted(set(extra) - set(DYNAMIC_FIELDS))
    if unknown:
        raise _fail(where, unknown[0], f"expected one of {', '.join(DYNAMIC_FIELDS)}")
    shapes = {"pd_targets": (t, n), "pd_kp": (n,), "pd_kd": (n,), "alpha": (None,), "segment_knots_s": (None,)}
    out = {}
    for key, value in extra.items():
        if key == "contact_sim":
            out[key] = _contact(where, value, t, feet, key)
        else:
            out[key] = _float_array(where, key, value, shapes[key])
    if "alpha" in out and "segment_knots_s" in out and len(out["segment_knots_s"]) != len(out["alpha"]) + 1:
        raise _fail(where, "segment_knots_s", f"expected S + 1 = {len(out['alpha']) + 1} knots")
    if "alpha" in out and np.any(out["alpha"] <= 0):
        raise _fail(where, "alpha", "expected positive time scales")
    return out


def load_motion(path: str | Path) -> KeypointMotion | RobotMotion:
    """Either kind of motion file, by its ``format`` field."""
    data = _read_npz(path)
    fmt = str(data.get("format", ""))
    if fmt == KEYPOINT_FORMAT:
        return KeypointMotion.load(path)
    if fmt == ROBOT_FORMAT:
        return RobotMotion.load(path)
    raise _fail(Path(path).name, "format", f"expected {KEYPOINT_FORMAT!r} or {ROBOT_FORMAT!r}, got {fmt or 'nothing'!r}")


def _json_field(where: str, data: dict, key: str) -> dict:
    """A JSON object stored as a 0-d text array (``source``, ``metrics``), parsed with safe_io's limits."""
    if key not in data:
        return {}
    arr = np.asarray(data[key])
    if arr.ndim != 0 or arr.dtype.kind != "U":
        raise _fail(where, key, f"expected a JSON object as text, got shape {arr.shape} {arr.dtype}")
    try:
        value = parse_json(str(arr), where)
    except ReadError as exc:
        raise _fail(where, key, f"{exc.field_path + ': ' if exc.field_path else ''}{exc.detail}") from None
    if not isinstance(value, dict):
        raise _fail(where, key, f"expected a JSON object, got {type(value).__name__}")
    return value


def _source(where: str, data: dict) -> dict:
    return _json_field(where, data, "source")


def _write_npz(path: str | Path, arrays: Mapping[str, np.ndarray | None]) -> None:
    buf = io.BytesIO()
    present = {k: v for k, v in arrays.items() if v is not None}
    np.savez_compressed(buf, **present)  # type: ignore[arg-type]  # numpy's stub reads **kwds as allow_pickle
    atomic_write_bytes(path, buf.getvalue())


def _read_npz(path: str | Path) -> dict[str, Any]:
    """The file's arrays, unvalidated (the dataclasses' ``__post_init__`` checks every field); the archive itself
    through :func:`engine.safe_io.read_npz` (sizes and dtypes checked before anything is allocated)."""
    where = Path(path).name
    try:
        return read_npz(path, source=where)
    except ReadError as exc:
        raise MotionFormatError(exc.source, exc.field_path, exc.detail) from None
