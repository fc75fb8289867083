"""The walk-run file: a closed-loop walk recorded as a RobotMotion, with its reference beside it.

``studio walk --out RUN.npz``, the studio's Record button and the gait library's ``simulated.npz`` all
write this one layout. It *is* a ``robot-motion/1`` npz (engine/retarget/motion.py), so every reader of
robot motions (``studio export``) reads it as the simulated motion:

=====================  ==========================================================================
key                    what
=====================  ==========================================================================
format                 ``robot-motion/1``
fps                    frames per second of the recording (125: every 4th 500 Hz tick)
qpos (T, 7+n)          simulated MuJoCo qpos: xyz, quaternion **w,x,y,z**, joints in ``joint_names``
qvel (T, 6+n)          MuJoCo qvel: world linear, body-frame angular, joints
joint_names (n,)       names of qpos[7:] (MuJoCo order)
contact (T, 2)         the reference's foot contacts, ``foot_names`` = left, right
robot, method          robot name; ``walk-simulated``
source (JSON)          ``{"kind": "walk-run", "style": …, "command": …}``
metrics (JSON)         the walk's summary (fell, slip, CoP inside, …)
reference_qpos (T, …)  the reference the controller tracked at the same instants: the kinematic
                       preview (whole-body IK, the studio's ghost) of the gait reference r(t)
t, command, com, …     the analysis arrays of ``studio walk --out`` (README)
=====================  ==========================================================================

:func:`load_run_motion` returns either take as a RobotMotion (``take="reference"`` builds it from
``reference_qpos``). Writes are atomic; reads use ``allow_pickle=False``.
"""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np

from engine.retarget.motion import ROBOT_FORMAT, MotionFormatError, RobotMotion, _read_npz, _write_npz

TAKES = ("simulated", "reference")
RUN_KIND = "walk-run"
FOOT_NAMES = ("left", "right")


def mujoco_joint_names(robot) -> list[str]:  # noqa: ANN001 - RobotModel
    """Names of qpos[7:] in MuJoCo order (the free joint excluded)."""
    names = []
    for j in range(robot.mj_model.njnt):
        if robot.mj_model.jnt_type[j] != mujoco.mjtJoint.mjJNT_FREE:
            names.append(robot.mj_model.joint(j).name)
    return names


def run_fields(robot, style_name: str, arrays: dict[str, np.ndarray], summary: dict, fps: float,  # noqa: ANN001
               command: str | None = None) -> dict[str, np.ndarray]:
    """The RobotMotion keys of a walk recording (added to its analysis arrays)."""
    source = {"kind": RUN_KIND, "style": style_name, "robot": robot.name}
    if command is not None:
        source["command"] = command
    return {
        "format": np.array(ROBOT_FORMAT), "fps": np.array(float(fps)),
        "joint_names": np.array(mujoco_joint_names(robot), dtype=str),
        "foot_names": np.array(FOOT_NAMES, dtype=str), "robot": np.array(robot.name),
        "method": np.array("walk-simulated"), "style": np.array(style_name),
        "source": np.array(json.dumps(source)), "metrics": np.array(json.dumps(_jsonable(summary))),
    }


def _jsonable(value):  # noqa: ANN001, ANN202
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return value


def save_run(path: str | Path, arrays: dict[str, np.ndarray]) -> None:
    """Compressed npz, atomically (never half-written)."""
    _write_npz(path, arrays)


def load_run_motion(path: str | Path, take: str = "simulated") -> RobotMotion:
    """A take of a walk-run file (or any robot-motion npz for ``simulated``) as a RobotMotion."""
    if take not in TAKES:
        raise MotionFormatError(f"{Path(path).name}: take: expected one of {', '.join(TAKES)}, got {take!r}")
    if take == "simulated":
        return RobotMotion.load(path)
    data = _read_npz(path)
    where = Path(path).name
    if "reference_qpos" not in data:
        raise MotionFormatError(f"{where}: reference_qpos: missing (not a walk-run file with its reference)")
    sim = RobotMotion.load(path)
    ref = data["reference_qpos"]
    if ref.shape != sim.qpos.shape:
        raise MotionFormatError(f"{where}: reference_qpos: expected shape {sim.qpos.shape}, got {ref.shape}")
    return RobotMotion(fps=sim.fps, qpos=ref, joint_names=sim.joint_names, contact=sim.contact, robot=sim.robot,
                       method="walk-reference", foot_names=sim.foot_names,
                       source={**sim.source, "file": where, "take": "reference"}, metrics=sim.metrics)


class WalkRecorder:
    """Accumulates a walk in the studio's engine (the Record button): one frame every 4th 500 Hz tick,
    the simulated state and the reference (the ghost's IK at that instant); :meth:`arrays` is a
    walk-run file. At most ``max_s`` seconds (then :attr:`full`)."""

    def __init__(self, robot, style_name: str, fps: float, command_text: str = "joystick",  # noqa: ANN001
                 max_s: float = 600.0):
        self.robot = robot
        self.style_name = style_name
        self.fps = float(fps)
        self.command_text = command_text
        self.max_frames = int(max_s * self.fps)
        self._rows: dict[str, list] = {k: [] for k in ("t", "qpos", "qvel", "contact", "reference_qpos", "command")}

    @property
    def frames(self) -> int:
        return len(self._rows["t"])

    @property
    def duration_s(self) -> float:
        return self.frames / self.fps

    @property
    def full(self) -> bool:
        return self.frames >= self.max_frames

    def add(self, t_s: float, qpos: np.ndarray, qvel: np.ndarray, contact: np.ndarray, reference_qpos: np.ndarray,
            command: np.ndarray) -> None:
        if self.full:
            return
        for key, value in (("t", t_s), ("qpos", qpos), ("qvel", qvel), ("contact", contact),
                           ("reference_qpos", reference_qpos), ("command", command)):
            self._rows[key].append(np.array(value, copy=True))

    def arrays(self) -> dict[str, np.ndarray]:
        if self.frames == 0:
            raise ValueError("nothing recorded yet (the robot must walk: Test or Edit mode)")
        arrays = {k: np.asarray(v) for k, v in self._rows.items()}
        arrays["contact"] = arrays["contact"].astype(bool)
        summary = {"frames": self.frames, "duration_s": round(self.duration_s, 3)}
        arrays.update(run_fields(self.robot, self.style_name, arrays, summary, self.fps, self.command_text))
        return arrays
