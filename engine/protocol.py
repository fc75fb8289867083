"""Messages between the studio and the engine process.

Two one-way streams over a ``multiprocessing`` pipe: *commands* (studio → engine) and
*events* (engine → studio). Every message is a small dataclass with a ``kind`` tag; arrays
travel as numpy arrays. Later features add message types here without changing the
transport: velocity commands and style updates (gait), telemetry (control), and long
running jobs with progress (retargeting) already have their slots.

The pipe only ever connects two processes of this program; user files never travel as
pickles (styles travel as validated JSON-compatible dicts).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

# ------------------------------------------------------------------ commands (studio → engine)


@dataclass(frozen=True)
class Reset:
    """Put the robot back in its standing pose (and the gait back to its start)."""

    kind: str = "reset"


@dataclass(frozen=True)
class SetPaused:
    paused: bool
    kind: str = "set_paused"


@dataclass(frozen=True)
class ApplyPush:
    """External force on a body (the root link when ``body`` is None), world frame."""

    force_n: tuple[float, float, float]
    duration_s: float
    body: str | None = None
    kind: str = "apply_push"


@dataclass(frozen=True)
class SwitchRobot:
    robot: str
    kind: str = "switch_robot"


@dataclass(frozen=True)
class SetVelocityCommand:
    """Planar gait velocity command in the path frame: forward m/s, left m/s, yaw rad/s."""

    vx_mps: float
    vy_mps: float
    wz_radps: float
    kind: str = "set_velocity_command"


@dataclass(frozen=True)
class SetStyle:
    """A whole walking style as its JSON document (validated by the engine)."""

    style: dict[str, Any]
    revision: int = 0  # frames report the revision they were computed with (edit latency)
    kind: str = "set_style"


@dataclass(frozen=True)
class SetMode:
    """Engine mode, e.g. "stand", "edit" (walk one sample's cycle) or "test" (joystick)."""

    mode: str
    options: dict[str, Any] = field(default_factory=dict)
    kind: str = "set_mode"


@dataclass(frozen=True)
class SetPlaybackSpeed:
    """Simulated time per wall-clock time (slow motion < 1)."""

    speed: float
    kind: str = "set_playback_speed"


@dataclass(frozen=True)
class StartJob:
    """A long-running job (e.g. a retargeting run); progress comes back as JobProgress."""

    job: str
    params: dict[str, Any] = field(default_factory=dict)
    job_id: str = ""  # chosen by the studio; JobProgress and CancelJob name it
    kind: str = "start_job"


@dataclass(frozen=True)
class CancelJob:
    """Stop a running job; a cancelled job writes nothing."""

    job_id: str
    kind: str = "cancel_job"


@dataclass(frozen=True)
class SetRecording:
    """Start (``recording``) or stop the recording of the walk; on stop the engine writes
    ``runs/<name>.npz`` in the motion library and answers with ``JobProgress(job="record", result=…)``."""

    recording: bool
    name: str = ""
    request_id: str = ""
    kind: str = "set_recording"


@dataclass(frozen=True)
class Shutdown:
    kind: str = "shutdown"


Command = (Reset | SetPaused | ApplyPush | SwitchRobot | SetVelocityCommand | SetStyle | SetMode | SetPlaybackSpeed
           | StartJob | CancelJob | SetRecording | Shutdown)

# ------------------------------------------------------------------ events (engine → studio)


@dataclass(frozen=True)
class RobotLoaded:
    """The engine now runs ``robot``; frames carry poses of ``body_names`` in this order."""

    robot: str
    robot_kind: str
    body_names: tuple[str, ...]
    joint_names: tuple[str, ...]
    simulated: bool
    kind: str = "robot_loaded"


@dataclass(frozen=True)
class Frame:
    """Body poses at one instant (published at 60 Hz)."""

    seq: int
    sim_time_s: float
    body_pos: np.ndarray  # (B, 3) float32, world
    body_quat: np.ndarray  # (B, 4) float32, wxyz
    joint_q: np.ndarray  # (n,) float32, actuated joints
    paused: bool
    fallen: bool
    real_time_factor: float
    mode: str = "stand"
    style_revision: int = 0
    kind: str = "frame"


@dataclass(frozen=True)
class Telemetry:
    """Named signals for overlays and plots (CoM, CoP, footholds, sample weights, ...)."""

    sim_time_s: float
    signals: dict[str, np.ndarray]
    kind: str = "telemetry"


@dataclass(frozen=True)
class Notice:
    """Something the user should see: level is "info", "warning" or "error"."""

    level: str
    message: str
    kind: str = "notice"


@dataclass(frozen=True)
class JobProgress:
    job: str
    fraction: float
    message: str = ""
    result: dict[str, Any] | None = None  # set on the last event of a job: {"ok": bool, ...}
    job_id: str = ""
    kind: str = "job_progress"


Event = RobotLoaded | Frame | Telemetry | Notice | JobProgress
