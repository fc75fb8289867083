"""Walking styles: the file format, its data model and its validation (paper §4.3, Tables 1–3).

A style (``styles/<robot>/<name>.json``) holds the nine gait samples of Table 3, each with
time intervals (Table 1), attributes and function curves (Table 2), plus the sample
velocities and the blend gain η of Eq. (10). Files are human-readable, versioned JSON::

    {
      "schema": "motion-studio/style", "version": 1,
      "name": "neutral", "robot": "g1", "description": "...",
      "velocities": {"x_max_mps": 0.5, "x_slow_mps": 0.25, "y_max_mps": 0.15, "yaw_max_radps": 1.0},
      "blend_eta": 0.5,
      "samples": {
        "forward_fast": {
          "intervals": {"cycle_s": 0.9, "left_swing_s": [0.0, 0.36], "right_swing_s": [0.45, 0.81]},
          "attributes": {"stance_width_m": 0.24, ...},
          "curves": {"left_foot.z": {"knots": [[t_s, value, in_slope, out_slope, mode], ...]}, ...}
        }, ... (all nine samples)
      }
    }

Curve channels: ``left_foot.<c>`` / ``right_foot.<c>`` for c in x, y, z, yaw, heel_pitch,
toe_pitch, roll — defined on that foot's swing interval, knot times in seconds from liftoff;
``pelvis.<c>`` for c in z (offset from the pelvis_height_m attribute), yaw, pitch, roll and
``joints.<joint>`` (absolute angle of an upper-body joint) — periodic over the cycle. A
channel without a curve holds its default (0, or the joint's standing angle).

Validation enforces the paper's constraints and reports the first violation as one line:
``<file>: <json.path>: <what was expected>``.
"""

from __future__ import annotations

import copy
import difflib
import functools
import hashlib
import json
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from engine.atomic_io import atomic_write_text
from engine.safe_io import ReadError, one_line, read_json
from engine.gait.curves import HermiteCurve, Knot, TangentMode
from engine.gait.leg_reach import LegReach, max_reachable_speed, sample_step_reach
from engine.robot.config import CurveRateLimits
from engine.gait.phase_map import PhaseMap
from engine.gait.velocity_sampler import SAMPLE_NAMES, SampleVelocities

SCHEMA = "motion-studio/style"
VERSION = 1
from engine.constants import SIDES  # noqa: E402 - re-exported (the feet, in the engine's order)
SWING_CHANNELS = ("x", "y", "z", "yaw", "heel_pitch", "toe_pitch", "roll")
PELVIS_CHANNELS = ("z", "yaw", "pitch", "roll")
BOUNDARY_TOL = 1e-6
MAX_FOOT_OFFSET_M = 0.3  # swing x/y offsets from the nominal path
MAX_FOOT_ANGLE_RAD = 1.0  # swing yaw/roll
MAX_PELVIS_ANGLE_RAD = 0.6
MAX_PELVIS_Z_OFFSET_M = 0.15
#: The validator's bounds of the stance attributes that do not depend on the robot (width and pelvis height come
#: from its StyleContext). A transition longer than the double support it falls in is shortened to it by the planner.
MAX_SPLAY_RAD = 0.6
MAX_X_BIAS_M = 0.2
MAX_TRANSITION_S = 1.0


class StyleError(ValueError):
    """A style that breaks the format or the paper's constraints: ``file: path: expected``."""

    def __init__(self, path: str, message: str, source: str = "style"):
        self.field_path = path
        self.detail = message
        self.source = source
        super().__init__(one_line(source, path, message))

    def with_source(self, source: str) -> "StyleError":
        return StyleError(self.field_path, self.detail, source)


# ----------------------------------------------------------------------------- data model


@dataclass(frozen=True)
class Intervals:
    """Table 1: the cycle CY = (0, T_S), left swing LS = (0, t_LTD), right swing RS = (t_RLO, t_RTD)."""

    cycle_s: float
    left_swing_s: tuple[float, float]
    right_swing_s: tuple[float, float]

    @property
    def events_s(self) -> tuple[float, float, float, float]:
        """(t_LTD, t_RLO, t_RTD, T_S); t_LLO is 0."""
        return (self.left_swing_s[1], self.right_swing_s[0], self.right_swing_s[1], self.cycle_s)

    def swing_s(self, side: str) -> tuple[float, float]:
        return self.left_swing_s if side == "left" else self.right_swing_s

    def swing_duration_s(self, side: str) -> float:
        a, b = self.swing_s(side)
        return b - a

    @property
    def double_support_s(self) -> tuple[float, float]:
        """(after left touchdown, after right touchdown)."""
        t_ltd, t_rlo, t_rtd, cycle = self.events_s
        return (t_rlo - t_ltd, cycle - t_rtd)

    def phase_map(self) -> PhaseMap:
        return PhaseMap(*self.events_s)

    def to_dict(self) -> dict[str, Any]:
        return {"cycle_s": self.cycle_s, "left_swing_s": list(self.left_swing_s), "right_swing_s": list(self.right_swing_s)}


@dataclass(frozen=True)
class Attributes:
    """Stance attributes (Fig. 7), heel/toe transition durations (Δtψ_LO, Δtψ_TD), posture."""

    stance_width_m: float
    stance_splay_rad: float = 0.0
    stance_x_bias_m: float = 0.0
    liftoff_transition_s: float = 0.0
    touchdown_transition_s: float = 0.0
    pelvis_height_m: float = 0.0

    def to_dict(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in ATTRIBUTE_NAMES}


ATTRIBUTE_NAMES = tuple(Attributes.__dataclass_fields__)


@dataclass(frozen=True)
class GaitSample:
    """One authored walk cycle at one of the nine key velocities."""

    intervals: Intervals
    attributes: Attributes
    curves: Mapping[str, HermiteCurve] = field(default_factory=dict)

    def curve(self, channel: str) -> HermiteCurve | None:
        return self.curves.get(channel)

    def with_curve(self, channel: str, curve: HermiteCurve | None) -> "GaitSample":
        curves = dict(self.curves)
        if curve is None:
            curves.pop(channel, None)
        else:
            curves[channel] = curve
        return replace(self, curves=curves)

    def with_intervals(self, intervals: Intervals) -> "GaitSample":
        """New intervals; curve knot times rescale with their interval (paper §6.1)."""
        curves = {}
        for channel, curve in self.curves.items():
            side = channel_side(channel)
            duration = intervals.cycle_s if side is None else intervals.swing_duration_s(side)
            curves[channel] = curve.rescaled(duration) if abs(duration - curve.duration_s) > 1e-12 else curve
        return replace(self, intervals=intervals, curves=curves)

    def to_dict(self) -> dict[str, Any]:
        return {
            "intervals": self.intervals.to_dict(),
            "attributes": self.attributes.to_dict(),
            "curves": {k: self.curves[k].to_dict() for k in sorted(self.curves, key=channel_sort_key)},
        }


@dataclass(frozen=True)
class Style:
    name: str
    robot: str
    velocities: SampleVelocities
    samples: Mapping[str, GaitSample]
    blend_eta: float = 0.5
    description: str = ""

    def sample(self, name: str) -> GaitSample:
        return self.samples[name]

    def with_sample(self, name: str, sample: GaitSample) -> "Style":
        samples = dict(self.samples)
        samples[name] = sample
        return replace(self, samples=samples)

    def to_dict(self) -> dict[str, Any]:
        return {
            "schema": SCHEMA,
            "version": VERSION,
            "name": self.name,
            "robot": self.robot,
            "description": self.description,
            "velocities": self.velocities.to_dict(),
            "blend_eta": self.blend_eta,
            "samples": {n: self.samples[n].to_dict() for n in SAMPLE_NAMES},
        }


def channel_side(channel: str) -> str | None:
    """"left"/"right" for swing channels, None for cycle channels."""
    head = channel.split(".", 1)[0]
    return head[: -len("_foot")] if head in ("left_foot", "right_foot") else None


def channel_sort_key(channel: str) -> tuple[int, int, str]:
    head, _, tail = channel.partition(".")
    order = {"left_foot": 0, "right_foot": 1, "pelvis": 2, "joints": 3}
    sub = SWING_CHANNELS.index(tail) if tail in SWING_CHANNELS and head.endswith("_foot") else (
        PELVIS_CHANNELS.index(tail) if head == "pelvis" and tail in PELVIS_CHANNELS else 99)
    return (order.get(head, 9), sub, tail)


def swing_channels(side: str) -> tuple[str, ...]:
    return tuple(f"{side}_foot.{c}" for c in SWING_CHANNELS)


PELVIS_CURVES = tuple(f"pelvis.{c}" for c in PELVIS_CHANNELS)


# ----------------------------------------------------------------------------- robot context


@dataclass(frozen=True)
class StyleContext:
    """What validation needs to know about the robot a style is for."""

    robot: str
    upper_joints: tuple[str, ...]
    all_joints: tuple[str, ...]
    joint_limits: Mapping[str, tuple[float, float]]
    standing_angles: Mapping[str, float]
    pelvis_height_m: float
    pelvis_height_range_m: tuple[float, float]
    stance_width_m: float
    stance_width_range_m: tuple[float, float]
    min_single_support_s: float
    min_double_support_s: float
    max_cycle_s: float
    max_swing_height_m: float
    # The upper-body joints' velocity limits in the robot model (rad/s): the rate a ``joints.*``
    # curve may reach (engine/gait/curve_rates.py).
    joint_velocity_limits: Mapping[str, float] = field(default_factory=dict)
    # How fast every other curve may change on this robot (robots/<name>.toml [gait.curve_rates]).
    curve_rates: CurveRateLimits = field(default_factory=CurveRateLimits)
    # What the legs physically reach (engine/gait/leg_reach.py): bounds a sample's step (its velocity ×
    # its cycle) and the swing feet's roll. None: no robot-level reach bounds.
    leg_reach: LegReach | None = None

    @classmethod
    def for_robot(cls, robot_name: str) -> "StyleContext":
        from engine.robot.model import load_robot

        robot = load_robot(robot_name)
        gait = robot.config.gait
        if gait is None:
            raise StyleError("robot", f"expected a biped; {robot_name} is a {robot.kind}", robot_name)
        limits = {j: (float(lo), float(hi)) for j, lo, hi in zip(robot.joint_names, robot.joint_lower, robot.joint_upper)}
        standing = {j: float(robot.q_standing[7 + i]) for i, j in enumerate(robot.joint_names)}
        pm = robot.pin_model
        speeds = {j: float(pm.velocityLimit[pm.joints[pm.getJointId(j)].idx_v]) for j in robot.joint_names
                  if pm.existJointName(j)}
        return cls(
            robot=robot_name, upper_joints=tuple(robot.config.upper_body_joints), all_joints=tuple(robot.joint_names),
            joint_limits=limits, standing_angles=standing, pelvis_height_m=gait.pelvis_height_m,
            pelvis_height_range_m=gait.pelvis_height_range_m, stance_width_m=gait.stance_width_m,
            stance_width_range_m=gait.stance_width_range_m, min_single_support_s=gait.min_single_support_s,
            min_double_support_s=gait.min_double_support_s, max_cycle_s=gait.max_cycle_s,
            max_swing_height_m=gait.max_swing_height_m, joint_velocity_limits=speeds, curve_rates=gait.curve_rates,
            leg_reach=_leg_reach(robot_name),
        )


@functools.lru_cache(maxsize=None)
def _leg_reach(robot_name: str) -> LegReach:
    """The robot's :class:`LegReach` (a small optimisation over the leg joints: computed once per robot)."""
    from engine.robot.model import load_robot

    return LegReach.for_robot(load_robot(robot_name))


def channel_value_range(channel: str, pelvis_height_m: float | None,
                        ctx: StyleContext | None) -> tuple[float, float, str] | None:
    """The values a curve channel may take, ``(lo, hi, what)`` — the one source of truth for the validator
    and the curve editor (knot drags clamp to it). ``pelvis_height_m`` is the sample's nominal pelvis height
    (``pelvis.z`` is an offset from it); None for a joint the robot context does not know."""
    head, tail = channel.split(".", 1)
    if head in ("left_foot", "right_foot"):
        if tail == "heel_pitch":
            return (-math.pi / 2, 0.0, "heel pitch ψ_heel")
        if tail == "toe_pitch":
            return (0.0, math.pi / 2, "toe pitch ψ_toe")
        if tail == "z":
            return (0.0, ctx.max_swing_height_m if ctx else 1.0, "swing height (no ground penetration)")
        if tail in ("x", "y"):
            return (-MAX_FOOT_OFFSET_M, MAX_FOOT_OFFSET_M, "a foot offset")
        if tail == "roll" and ctx is not None and ctx.leg_reach is not None \
                and ctx.leg_reach.ankle_roll_range_rad < MAX_FOOT_ANGLE_RAD:
            bound = ctx.leg_reach.ankle_roll_range_rad
            return (-bound, bound, f"a foot roll the ankle roll joint reaches (±{bound:.4g} rad)")
        return (-MAX_FOOT_ANGLE_RAD, MAX_FOOT_ANGLE_RAD, "a foot angle")
    if channel == "pelvis.z":
        lo, hi = -MAX_PELVIS_Z_OFFSET_M, MAX_PELVIS_Z_OFFSET_M
        if ctx is None or pelvis_height_m is None:
            return (lo, hi, "a pelvis height offset")
        h_lo, h_hi = ctx.pelvis_height_range_m
        return (max(lo, h_lo - pelvis_height_m), min(hi, h_hi - pelvis_height_m),
                f"a pelvis height offset (at most {MAX_PELVIS_Z_OFFSET_M} m, pelvis height within {h_lo}..{h_hi} m)")
    if head == "pelvis":
        return (-MAX_PELVIS_ANGLE_RAD, MAX_PELVIS_ANGLE_RAD, f"pelvis {tail}")
    if ctx is not None and tail in ctx.joint_limits:
        lo, hi = ctx.joint_limits[tail]
        return (lo, hi, f"{tail} within its joint limits")
    return None


# ----------------------------------------------------------------------------- parsing


def _expect(cond: bool, path: str, message: str) -> None:
    if not cond:
        raise StyleError(path, message)


def _number(value: Any, path: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise StyleError(path, f"expected a number, got {_show(value)}")
    try:
        value = float(value)
    except OverflowError:  # an integer beyond float range (documents that did not come through safe_io)
        value = math.inf
    if not math.isfinite(value):
        raise StyleError(path, f"expected a finite number, got {value}")
    return value


def _show(value: Any) -> str:
    """A short rendering of a user value for a message (never raises, never long)."""
    try:
        text = json.dumps(value)
        return text if len(text) <= 40 else text[:39] + "…"
    except (TypeError, ValueError, RecursionError):
        return type(value).__name__


def _table(value: Any, path: str, allowed: tuple[str, ...] | None, required: tuple[str, ...] = ()) -> dict:
    if not isinstance(value, dict):
        raise StyleError(path, f"expected an object, got {type(value).__name__}")
    if allowed is not None:
        for key in value:
            if key not in allowed:
                hint = difflib.get_close_matches(str(key), allowed, n=1)
                extra = f" (did you mean {hint[0]!r}?)" if hint else ""
                raise StyleError(f"{path}.{key}" if path else str(key),
                                 f"unknown field{extra}; expected one of {', '.join(allowed)}")
    for key in required:
        if key not in value:
            raise StyleError(f"{path}.{key}" if path else key, "missing required field")
    return value


def _pair(value: Any, path: str) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise StyleError(path, f"expected [min_s, max_s], got {_show(value)}")
    return (_number(value[0], f"{path}[0]"), _number(value[1], f"{path}[1]"))


def parse_intervals(data: Any, path: str) -> Intervals:
    t = _table(data, path, ("cycle_s", "left_swing_s", "right_swing_s"), ("cycle_s", "left_swing_s", "right_swing_s"))
    return Intervals(_number(t["cycle_s"], f"{path}.cycle_s"), _pair(t["left_swing_s"], f"{path}.left_swing_s"),
                     _pair(t["right_swing_s"], f"{path}.right_swing_s"))


def parse_attributes(data: Any, path: str, ctx: StyleContext | None) -> Attributes:
    t = _table(data, path, ATTRIBUTE_NAMES, ("stance_width_m",))
    values = {k: _number(v, f"{path}.{k}") for k, v in t.items()}
    if "pelvis_height_m" not in values:
        values["pelvis_height_m"] = ctx.pelvis_height_m if ctx else 0.0
    return Attributes(**values)


def valid_channels(ctx: StyleContext | None) -> list[str]:
    names = [*swing_channels("left"), *swing_channels("right"), *PELVIS_CURVES]
    if ctx is not None:
        names += [f"joints.{j}" for j in ctx.upper_joints]
    return names


def parse_curve(data: Any, path: str, duration_s: float, periodic: bool) -> HermiteCurve:
    t = _table(data, path, ("knots",), ("knots",))
    rows = t["knots"]
    if not isinstance(rows, list):
        raise StyleError(f"{path}.knots", "expected a list of [t_s, value, in_slope, out_slope, mode]")
    knots = []
    modes = tuple(m.value for m in TangentMode)
    for i, row in enumerate(rows):
        kp = f"{path}.knots[{i}]"
        if not isinstance(row, list) or len(row) not in (2, 3, 5):
            raise StyleError(kp, "expected [t_s, value] or [t_s, value, in_slope, out_slope, mode]")
        t_s, value = _number(row[0], f"{kp}[0]"), _number(row[1], f"{kp}[1]")
        mode_raw = row[-1] if len(row) in (3, 5) else "auto_clamped"
        if mode_raw not in modes:
            raise StyleError(f"{kp}[{len(row) - 1}]", f"expected a tangent mode ({', '.join(modes)}), got {_show(mode_raw)}")
        if len(row) == 5:
            knots.append(Knot(t_s, value, _number(row[2], f"{kp}[2]"), _number(row[3], f"{kp}[3]"), TangentMode(mode_raw)))
        else:
            knots.append(Knot(t_s, value, mode=TangentMode(mode_raw)))
        upper = duration_s if not periodic else duration_s - 1e-9
        if not (-BOUNDARY_TOL <= t_s <= upper + BOUNDARY_TOL):
            where = "the swing interval" if not periodic else "the cycle"
            raise StyleError(f"{kp}[0]", f"expected a knot time inside {where} [0, {duration_s:.4g}"
                                         f"{']' if not periodic else ')'} s, got {t_s:.4g}")
    for i in range(1, len(knots)):
        if knots[i].t_s <= knots[i - 1].t_s:
            raise StyleError(f"{path}.knots[{i}][0]", f"expected knot times increasing, got {knots[i].t_s:.4g} "
                                                       f"after {knots[i - 1].t_s:.4g}")
    knots = [replace(k, t_s=min(max(k.t_s, 0.0), duration_s)) for k in knots]
    try:
        return HermiteCurve(knots, duration_s, periodic)
    except ValueError as exc:
        raise StyleError(path, str(exc)) from None


def parse_sample(data: Any, path: str, ctx: StyleContext | None) -> GaitSample:
    t = _table(data, path, ("intervals", "attributes", "curves"), ("intervals", "attributes"))
    intervals = parse_intervals(t["intervals"], f"{path}.intervals")
    validate_intervals(intervals, f"{path}.intervals", ctx)
    attributes = parse_attributes(t["attributes"], f"{path}.attributes", ctx)
    curves_raw = _table(t.get("curves", {}), f"{path}.curves", None)
    channels = valid_channels(ctx)
    curves: dict[str, HermiteCurve] = {}
    for channel, raw in curves_raw.items():
        cp = f"{path}.curves.{channel}"
        generic_joint = ctx is None and channel.startswith("joints.") and len(channel) > len("joints.")
        if channel not in channels and not generic_joint:
            raise StyleError(cp, _unknown_channel_message(channel, channels, ctx))
        side = channel_side(channel)
        duration = intervals.cycle_s if side is None else intervals.swing_duration_s(side)
        curves[channel] = parse_curve(raw, cp, duration, periodic=side is None)
    sample = GaitSample(intervals, attributes, curves)
    validate_sample(sample, path, ctx)
    return sample


def _unknown_channel_message(channel: str, channels: list[str], ctx: StyleContext | None) -> str:
    if channel.startswith("joints.") and ctx is not None:
        joint = channel[len("joints."):]
        if joint in ctx.all_joints:
            return f"{joint} is not an upper-body joint of {ctx.robot} (legs follow the feet); expected one of " \
                   f"{', '.join(ctx.upper_joints)}"
        hint = difflib.get_close_matches(joint, ctx.upper_joints, n=1, cutoff=0.5)
        extra = f"; did you mean 'joints.{hint[0]}'?" if hint else ""
        return f"expected a joint of {ctx.robot}, {joint!r} does not exist{extra}"
    hint = difflib.get_close_matches(channel, channels, n=1)
    extra = f"; did you mean {hint[0]!r}?" if hint else ""
    return f"unknown curve channel{extra}"


def style_from_dict(data: Any, ctx: StyleContext | None = None, expected_robot: str | None = None) -> Style:
    """Parse and validate a style document; raises :class:`StyleError` (source "style")."""
    top = _table(data, "", ("schema", "version", "name", "robot", "description", "velocities", "blend_eta", "samples"),
                 ("schema", "version", "name", "robot", "velocities", "samples"))
    _expect(top["schema"] == SCHEMA, "schema", f"expected {SCHEMA!r}, got {_show(top['schema'])}")
    version = top["version"]
    _expect(isinstance(version, int) and not isinstance(version, bool), "version", f"expected an integer, got {_show(version)}")
    _expect(version <= VERSION, "version", f"expected {VERSION} or older; this file was written by a newer studio "
                                           f"(version {version})")
    _expect(version >= 1, "version", f"expected 1..{VERSION}, got {version}")
    _expect(isinstance(top["name"], str) and top["name"].strip() != "", "name", "expected a non-empty string")
    robot = top["robot"]
    _expect(isinstance(robot, str), "robot", "expected a robot name")
    want = expected_robot or (ctx.robot if ctx else None)
    if want is not None:
        _expect(robot == want, "robot", f"expected {want!r} (this style is for {robot!r})")
    description = top.get("description", "")
    _expect(isinstance(description, str), "description", "expected a string")

    vel = _table(top["velocities"], "velocities", ("x_max_mps", "x_slow_mps", "y_max_mps", "yaw_max_radps"),
                 ("x_max_mps", "x_slow_mps", "y_max_mps", "yaw_max_radps"))
    v = {k: _number(vel[k], f"velocities.{k}") for k in vel}
    for k, value in v.items():
        _expect(value > 0, f"velocities.{k}", f"expected a positive velocity, got {value}")
    _expect(v["x_slow_mps"] < v["x_max_mps"], "velocities.x_slow_mps",
            f"expected below x_max_mps ({v['x_max_mps']}), got {v['x_slow_mps']}")
    velocities = SampleVelocities(v["x_max_mps"], v["x_slow_mps"], v["y_max_mps"], v["yaw_max_radps"])
    eta = _number(top.get("blend_eta", 0.5), "blend_eta")
    _expect(0.0 <= eta <= 1.0, "blend_eta", f"expected 0 ≤ η ≤ 1, got {eta}")

    samples_raw = _table(top["samples"], "samples", SAMPLE_NAMES)
    for name in SAMPLE_NAMES:
        _expect(name in samples_raw, f"samples.{name}", "missing gait sample (a style needs all nine of Table 3)")
    samples = {name: parse_sample(samples_raw[name], f"samples.{name}", ctx) for name in SAMPLE_NAMES}
    if ctx is not None and ctx.leg_reach is not None:
        validate_step_reach(velocities, samples, ctx.leg_reach)
    return Style(name=top["name"], robot=robot, velocities=velocities, samples=samples, blend_eta=eta,
                 description=description)


# ----------------------------------------------------------------------------- validation


def validate_intervals(iv: Intervals, path: str, ctx: StyleContext | None) -> None:
    """Event ordering t_LLO < t_LTD < t_RLO < t_RTD < t_LLO + T_S and minimum phase durations."""
    cycle = iv.cycle_s
    _expect(cycle > 0, f"{path}.cycle_s", f"expected a positive cycle duration, got {cycle}")
    if ctx is not None:
        _expect(cycle <= ctx.max_cycle_s, f"{path}.cycle_s", f"expected at most {ctx.max_cycle_s} s, got {cycle}")
    _expect(abs(iv.left_swing_s[0]) <= BOUNDARY_TOL, f"{path}.left_swing_s[0]",
            f"expected 0 (the cycle starts at left liftoff), got {iv.left_swing_s[0]}")
    t_ltd, t_rlo, t_rtd, _ = iv.events_s
    _expect(0 < t_ltd < t_rlo < t_rtd < cycle, f"{path}",
            f"expected event order 0 = t_LLO < t_LTD < t_RLO < t_RTD < T_S, got t_LTD={t_ltd:.3f}, "
            f"t_RLO={t_rlo:.3f}, t_RTD={t_rtd:.3f}, T_S={cycle:.3f}")
    min_ss = ctx.min_single_support_s if ctx else 1e-3
    min_ds = ctx.min_double_support_s if ctx else 1e-3
    _expect(t_ltd >= min_ss - 1e-9, f"{path}.left_swing_s[1]",
            f"expected a left swing (right single support) of at least {min_ss} s, got {t_ltd:.3f} s")
    _expect(t_rtd - t_rlo >= min_ss - 1e-9, f"{path}.right_swing_s",
            f"expected a right swing (left single support) of at least {min_ss} s, got {t_rtd - t_rlo:.3f} s")
    _expect(t_rlo - t_ltd >= min_ds - 1e-9, f"{path}.right_swing_s[0]",
            f"expected a double support after left touchdown of at least {min_ds} s, got {t_rlo - t_ltd:.3f} s")
    _expect(cycle - t_rtd >= min_ds - 1e-9, f"{path}.right_swing_s[1]",
            f"expected a double support after right touchdown of at least {min_ds} s, got {cycle - t_rtd:.3f} s")


# The velocity field each sample walks at (velocity_of's table): its step is that velocity × its timings.
VELOCITY_FIELD = {"forward_fast": "x_max_mps", "forward_slow": "x_slow_mps", "reverse_slow": "x_slow_mps",
                  "reverse_fast": "x_max_mps", "left_strafe": "y_max_mps", "right_strafe": "y_max_mps",
                  "left_turn": "yaw_max_radps", "right_turn": "yaw_max_radps"}


def validate_step_reach(velocities: SampleVelocities, samples: Mapping[str, "GaitSample"], reach: LegReach) -> None:
    """Each sample's steps within what the legs reach (engine/gait/leg_reach.py): in each double support,
    the two ankles at most as far apart as two legs at the sample's pelvis height reach."""
    for name in SAMPLE_NAMES:
        field_name = VELOCITY_FIELD.get(name)
        if field_name is None:
            continue
        velocity = velocities.velocity_of(name)
        found = sample_step_reach(reach, samples[name], velocity)
        if found.excess_m <= 1e-9:
            continue
        value = getattr(velocities, field_name)
        unit = tuple(v / value for v in velocity)
        top = max_reachable_speed(reach, samples[name], unit, value)
        units = "rad/s" if field_name.startswith("yaw") else "m/s"
        raise StyleError(f"velocities.{field_name}",
                         f"expected at most {top:.3g} {units} (or a shorter samples.{name}.intervals.cycle_s or a lower "
                         f"pelvis): at {value:.4g} {units} its ankles are {found.ankle_distance_m:.3f} m apart "
                         f"{found.double_support}, more than the legs reach at its pelvis height "
                         f"({found.limit_m:.3f} m), got {value:.4g}")


def _check_range(curve: HermiteCurve, path: str, lo: float, hi: float, what: str) -> None:
    vmin, vmax = curve.value_range()
    if vmin < lo - 1e-9 or vmax > hi + 1e-9:
        bad = vmin if vmin < lo - 1e-9 else vmax
        raise StyleError(path, f"expected {what} within [{lo:.4g}, {hi:.4g}], the curve reaches {bad:.4g}")


def validate_sample(sample: GaitSample, path: str, ctx: StyleContext | None) -> None:
    a = sample.attributes
    ap = f"{path}.attributes"
    if ctx is not None:
        lo, hi = ctx.stance_width_range_m
        _expect(lo <= a.stance_width_m <= hi, f"{ap}.stance_width_m", f"expected {lo}..{hi} m, got {a.stance_width_m}")
        lo, hi = ctx.pelvis_height_range_m
        _expect(lo <= a.pelvis_height_m <= hi, f"{ap}.pelvis_height_m", f"expected {lo}..{hi} m, got {a.pelvis_height_m}")
    _expect(abs(a.stance_splay_rad) <= MAX_SPLAY_RAD, f"{ap}.stance_splay_rad",
            f"expected -{MAX_SPLAY_RAD:g}..{MAX_SPLAY_RAD:g} rad, got {a.stance_splay_rad}")
    _expect(abs(a.stance_x_bias_m) <= MAX_X_BIAS_M, f"{ap}.stance_x_bias_m",
            f"expected -{MAX_X_BIAS_M:g}..{MAX_X_BIAS_M:g} m, got {a.stance_x_bias_m}")
    for key in ("liftoff_transition_s", "touchdown_transition_s"):
        value = getattr(a, key)
        _expect(0.0 <= value <= MAX_TRANSITION_S, f"{ap}.{key}", f"expected 0..{MAX_TRANSITION_S:g} s, got {value}")

    cp = f"{path}.curves"
    for side in SIDES:
        duration = sample.intervals.swing_duration_s(side)
        for channel in swing_channels(side):
            curve = sample.curves.get(channel)
            if curve is None:
                continue
            p = f"{cp}.{channel}"
            knots = curve.knots
            _expect(len(knots) >= 2, f"{p}.knots", "expected knots at liftoff (t=0) and touchdown (t=swing duration)")
            _expect(abs(knots[0].t_s) <= BOUNDARY_TOL, f"{p}.knots[0][0]", "expected the first knot at liftoff, t = 0")
            _expect(abs(knots[-1].t_s - duration) <= BOUNDARY_TOL, f"{p}.knots[{len(knots) - 1}][0]",
                    f"expected the last knot at touchdown, t = {duration:.4g} s")
            pitch = channel.endswith("_pitch")
            for idx in (0, len(knots) - 1):
                k = knots[idx]
                if not pitch:
                    _expect(abs(k.value) <= BOUNDARY_TOL, f"{p}.knots[{idx}][1]",
                            f"expected 0 at the swing boundary (the foot starts and ends on its foothold), got {k.value:.4g}")
                slope = k.out_slope if idx == 0 else k.in_slope
                _expect(abs(slope) <= 1e-6, f"{p}.knots[{idx}]",
                        f"expected a flat tangent at the swing boundary (the foot is at rest in contact), got slope {slope:.4g}")
            value_range = channel_value_range(channel, a.pelvis_height_m, ctx)
            if value_range is not None:
                _check_range(curve, p, *value_range)
        heel = sample.curves.get(f"{side}_foot.heel_pitch")
        toe = sample.curves.get(f"{side}_foot.toe_pitch")
        if heel is not None and toe is not None:
            for t_s, where in ((0.0, "liftoff"), (duration, "touchdown")):
                _expect(abs(float(heel.evaluate(t_s))) <= BOUNDARY_TOL or abs(float(toe.evaluate(t_s))) <= BOUNDARY_TOL,
                        f"{cp}.{side}_foot.heel_pitch",
                        f"expected heel or toe pitch to be zero at {where} (contact on the heel or on the toe)")

    for channel, curve in sample.curves.items():
        if channel_side(channel) is not None:
            continue
        p = f"{cp}.{channel}"
        _expect(abs(curve.duration_s - sample.intervals.cycle_s) < 1e-9, p, "expected a curve over the whole cycle")
        value_range = channel_value_range(channel, a.pelvis_height_m, ctx)
        if value_range is not None:
            _check_range(curve, p, *value_range)


def validate_style(style: Style, ctx: StyleContext | None) -> None:
    """Re-validate a style built in code (edits): same rules as loading a file."""
    style_from_dict(style_to_json_dict(style), ctx, expected_robot=style.robot)


# ----------------------------------------------------------------------------- files


def style_to_json_dict(style: Style) -> dict[str, Any]:
    return style.to_dict()


def style_digest(style: Style) -> str:
    """A fingerprint of what the robot walks: the style's content without its name and description (two styles
    with the same digest walk the same; a verdict about one holds for the other)."""
    content = style.to_dict()
    content.pop("name", None)
    content.pop("description", None)
    return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()[:16]


def dumps_style(style: Style | dict[str, Any]) -> str:
    """Human-readable JSON: one knot per line, stable key order, rounded numbers."""
    doc = style.to_dict() if isinstance(style, Style) else copy.deepcopy(style)

    def clean(x: Any) -> Any:
        if isinstance(x, float):
            r = round(x, 9)
            return 0.0 if r == 0 else r
        if isinstance(x, list):
            return [clean(v) for v in x]
        if isinstance(x, dict):
            return {k: clean(v) for k, v in x.items()}
        return x

    doc = clean(doc)
    text = json.dumps(doc, indent=2, ensure_ascii=False)
    # Put each knot row (and each short number list) on one line.
    import re

    def squash(match: re.Match) -> str:
        inner = re.sub(r"\s+", " ", match.group(0))
        return inner.replace("[ ", "[").replace(" ]", "]")

    text = re.sub(r"\[\s*(-?[\d.e+-]+|\"[a-z_]+\")(,\s*(-?[\d.e+-]+|\"[a-z_]+\"))*\s*\]", squash, text)
    return text + "\n"


def load_style(path: str | os.PathLike, ctx: StyleContext | None = None, expected_robot: str | None = None) -> Style:
    """Load and validate a style file; errors name the file: ``neutral.json: samples.x...: ...``."""
    path = Path(path)
    source = str(path)
    try:
        data = read_json(path, source=source)
    except ReadError as exc:
        raise StyleError(exc.field_path, exc.detail, source) from None
    if ctx is None:
        robot = expected_robot or (data.get("robot") if isinstance(data, dict) else None)
        if isinstance(robot, str):
            try:
                ctx = StyleContext.for_robot(robot)
            except StyleError as exc:
                raise exc.with_source(source) from None
            except Exception as exc:
                raise StyleError("robot", f"expected a robot of the library: {exc}", source) from None
    try:
        return style_from_dict(data, ctx, expected_robot)
    except StyleError as exc:
        raise exc.with_source(source) from None


STYLES_ROOT = Path(__file__).resolve().parents[2] / "styles"


def styles_dir(robot: str) -> Path:
    """The folder of ``robot``'s styles (``MOTION_STUDIO_STYLES`` overrides the repo's styles/)."""
    root = Path(os.environ["MOTION_STUDIO_STYLES"]) if os.environ.get("MOTION_STUDIO_STYLES") else STYLES_ROOT
    return root / robot


def save_style(path: str | os.PathLike, style: Style) -> None:
    atomic_write_text(path, dumps_style(style))


def default_swing_curves(ctx: StyleContext, intervals: Intervals) -> dict[str, HermiteCurve]:
    """A plain swing: a foot-height bump on each swing (used for new styles)."""
    curves = {}
    for side in SIDES:
        d = intervals.swing_duration_s(side)
        curves[f"{side}_foot.z"] = HermiteCurve(
            [Knot(0.0, 0.0, mode=TangentMode.FLAT), Knot(0.5 * d, min(0.06, ctx.max_swing_height_m)),
             Knot(d, 0.0, mode=TangentMode.FLAT)], d)
    return curves
