"""Velocity command schedules for headless runs: ``vx,vy,wz``, a preset, or a keyframe file.

Presets scale with the style's sample velocities, so ``sweep`` reaches each style's own
limits: forward fast, reverse, strafe both ways, turn both ways, then stop.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from engine.gait.velocity_sampler import SampleVelocities

PRESETS = ("stand", "forward", "sweep")


class CommandError(ValueError):
    """A command spec a user typed that cannot be used (one line)."""


@dataclass(frozen=True)
class CommandSchedule:
    """Piecewise-linear [vx, vy, wz] keyframes, held after the last one."""

    times_s: np.ndarray  # (K,)
    values: np.ndarray  # (K, 3)
    # The keyframes as Python floats, for the per-tick lookup (numpy's per-call cost dominates at K ≈ 30).
    _times: list[float] = field(init=False, repr=False, compare=False)
    _rows: list[list[float]] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_times", np.asarray(self.times_s, dtype=float).tolist())
        object.__setattr__(self, "_rows", np.asarray(self.values, dtype=float).tolist())

    def __call__(self, t_s: float) -> np.ndarray:
        times = self._times
        if t_s <= times[0]:
            return self.values[0].copy()
        if t_s >= times[-1]:
            return self.values[-1].copy()
        # np.interp's formula on all three axes (bisect = searchsorted side="right"), on floats: the same
        # operations as the former (3,)-array expression (v1 − v0) / (t1 − t0) · (t − t0) + v0.
        j = bisect.bisect_right(times, t_s) - 1
        t0 = times[j]
        h, s = times[j + 1] - t0, t_s - t0
        (a0, a1, a2), (b0, b1, b2) = self._rows[j], self._rows[j + 1]
        return np.array([(b0 - a0) / h * s + a0, (b1 - a1) / h * s + a1, (b2 - a2) / h * s + a2])

    @property
    def end_s(self) -> float:
        return float(self.times_s[-1])


def sweep_keyframes(v: SampleVelocities, ramp_s: float = 1.5, hold_s: float = 4.0, pause_s: float = 1.5) -> list[list[float]]:
    """Stand, forward fast, reverse, strafe left/right, turn left/right, stop — with a short stop
    between legs (as a joystick user changes direction)."""
    legs = [(v.x_max_mps, 0, 0), (-v.x_slow_mps, 0, 0), (0, v.y_max_mps, 0), (0, -v.y_max_mps, 0),
            (0, 0, v.yaw_max_radps), (0, 0, -v.yaw_max_radps)]
    frames, t = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]], 1.0
    for target in legs:
        t += ramp_s
        frames.append([t, *map(float, target)])
        t += hold_s
        frames.append([t, *map(float, target)])
        t += ramp_s
        frames.append([t, 0.0, 0.0, 0.0])
        t += pause_s
        frames.append([t, 0.0, 0.0, 0.0])
    return frames


def preset(name: str, v: SampleVelocities) -> CommandSchedule:
    if name == "stand":
        frames = [[0.0, 0.0, 0.0, 0.0]]
    elif name == "forward":
        frames = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [3.0, v.x_slow_mps, 0.0, 0.0]]
    elif name == "sweep":
        frames = sweep_keyframes(v)
    else:
        raise CommandError(f"unknown preset {name!r}; presets: {', '.join(PRESETS)}")
    return from_keyframes(frames, name)


def from_keyframes(frames: object, source: str) -> CommandSchedule:
    if not isinstance(frames, list) or not frames:
        raise CommandError(f"{source}: keyframes: expected a non-empty list of [t, vx, vy, wz]")
    rows = []
    for i, row in enumerate(frames):
        if not isinstance(row, list) or len(row) != 4 or not all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in row):
            raise CommandError(f"{source}: keyframes[{i}]: expected [t, vx, vy, wz] of finite numbers, got {repr(row)[:60]}")
        rows.append([float(x) for x in row])
    arr = np.array(rows)
    if np.any(np.diff(arr[:, 0]) <= 0):
        raise CommandError(f"{source}: keyframes: expected increasing times")
    return CommandSchedule(arr[:, 0], arr[:, 1:])


def parse_command(spec: str, velocities: SampleVelocities, cwd: Path | None = None) -> CommandSchedule:
    """``vx,vy,wz`` | preset name | path to ``{"keyframes": [[t, vx, vy, wz], ...]}``."""
    spec = spec.strip()
    if spec in PRESETS:
        return preset(spec, velocities)
    if "," in spec and not spec.endswith(".json"):
        parts = spec.split(",")
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise CommandError(f"--command: expected vx,vy,wz numbers, a preset ({', '.join(PRESETS)}) "
                               f"or a JSON file, got {spec!r}") from None
        if len(values) != 3 or not all(math.isfinite(x) for x in values):
            raise CommandError(f"--command: expected three finite numbers vx,vy,wz, got {spec!r}")
        return CommandSchedule(np.array([0.0]), np.array([values]))
    path = Path(spec) if cwd is None else (cwd / spec)
    if not path.is_file():
        raise CommandError(f"--command: {spec!r} is neither vx,vy,wz, a preset ({', '.join(PRESETS)}) nor a file")
    from engine.safe_io import ReadError, read_json

    try:
        doc = read_json(path, source=path.name)
    except ReadError as exc:
        raise CommandError(str(exc)) from None
    if not isinstance(doc, dict) or "keyframes" not in doc:
        raise CommandError(f"{path.name}: keyframes: missing required field")
    return from_keyframes(doc["keyframes"], path.name)
