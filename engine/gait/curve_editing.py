"""The curve editor's editing rules (paper §4.3 "Function Curves"), free of any view.

What a knot drag, a tangent-handle drag, a paste or a mirror does to a :class:`HermiteCurve` of a
style's sample, under the same value ranges the validator enforces
(:func:`engine.gait.style.channel_value_range`). The studio's graph editor
(``studio/panels/curve_editor/``) only maps pointer events to these rules and draws the result.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable

from engine.gait.curves import MIN_KNOT_GAP_S, HermiteCurve, Knot, TangentMode
from engine.gait.style import (
    PELVIS_CURVES,
    GaitSample,
    StyleContext,
    channel_side,
    channel_value_range,
    swing_channels,
)


@dataclass(frozen=True, order=True)
class KnotRef:
    """One knot of the edited sample: channel name and knot index (knots never reorder)."""

    channel: str
    index: int


@dataclass
class Clipboard:
    """Copied knots with the interval they came from (times are rescaled on paste)."""

    channel: str
    sample: str
    duration_s: float
    periodic: bool
    knots: tuple[Knot, ...]
    whole: bool



def channel_interval(channel: str) -> str:
    """"left" / "right" (that foot's swing interval) or "cycle"."""
    return channel_side(channel) or "cycle"


def interval_duration(sample: GaitSample, interval: str) -> float:
    """Duration [s] of an interval of a sample ("left", "right" or "cycle")."""
    return sample.intervals.cycle_s if interval == "cycle" else sample.intervals.swing_duration_s(interval)


def all_channels(ctx: StyleContext) -> list[str]:
    """Every curve channel of the robot, in the editor's list order."""
    return [*swing_channels("left"), *swing_channels("right"), *PELVIS_CURVES,
            *(f"joints.{j}" for j in ctx.upper_joints)]


def channel_tail(channel: str) -> str:
    return channel.split(".", 1)[1]


def channel_unit(channel: str) -> str:
    tail = channel_tail(channel)
    return "m" if tail in ("x", "y", "z") and not channel.startswith("joints.") else "rad"


def channel_limits(channel: str, sample: GaitSample, ctx: StyleContext) -> tuple[float, float]:
    """The value range validation allows for a channel (what knot drags clamp to): the validator's own
    :func:`~engine.gait.style.channel_value_range`, so the editor and the validator never disagree."""
    value_range = channel_value_range(channel, sample.attributes.pelvis_height_m, ctx)
    if value_range is None:
        return (-math.pi, math.pi)
    return (value_range[0], value_range[1])


def channel_default(channel: str, ctx: StyleContext) -> float:
    """Value a channel holds without a curve: the joint's standing angle, else 0."""
    if channel.startswith("joints."):
        return float(ctx.standing_angles.get(channel_tail(channel), 0.0))
    return 0.0


def opposite_channel(channel: str) -> str | None:
    """left ↔ right counterpart (``left_foot.y`` ↔ ``right_foot.y``, ``joints.arm_left_1_joint`` ↔
    ``joints.arm_right_1_joint``), None if unpaired (pelvis, waist, head)."""
    head, tail = channel.split(".", 1)
    swap = {"left": "right", "right": "left"}
    if head in ("left_foot", "right_foot"):
        return f"{swap[head[:-5]]}_foot.{tail}"
    if head != "joints":
        return None
    parts = tail.split("_")
    sides = [i for i, part in enumerate(parts) if part in swap]
    if not sides:
        return None
    parts[sides[0]] = swap[parts[sides[0]]]
    return "joints." + "_".join(parts)


def mirror_sign(channel: str) -> float:
    """−1 for lateral components (y, yaw, roll and roll/yaw joints) when mirrored left ↔ right."""
    tail = channel_tail(channel)
    if channel.startswith("joints."):
        return -1.0 if ("roll" in tail or "yaw" in tail) else 1.0
    return -1.0 if tail in ("y", "yaw", "roll") else 1.0


def is_pinned(channel: str, index: int, n_knots: int) -> bool:
    """Swing boundary knots (liftoff / touchdown) are pinned in time (and at 0 except pitch)."""
    return channel_side(channel) is not None and index in (0, n_knots - 1)


def handle_points(curve: HermiteCurve, index: int) -> dict[str, tuple[float, float]]:
    """Tangent handles of a knot — the adjacent Bézier control points ``P ± m·h/3`` as (t, v).

    ``"in"`` is the previous segment's P2, ``"out"`` the next segment's P1 (periodic curves
    wrap: the first knot's in-handle comes from the wrap segment, shifted by −duration).
    """
    cps = curve.bezier_control_points()
    n = curve.n_knots
    out: dict[str, tuple[float, float]] = {}
    if curve.n_segments == 0:
        return out
    if index < curve.n_segments:
        out["out"] = (float(cps[index, 1, 0]), float(cps[index, 1, 1]))
    if index > 0:
        out["in"] = (float(cps[index - 1, 2, 0]), float(cps[index - 1, 2, 1]))
    elif curve.periodic and n > 1:
        out["in"] = (float(cps[-1, 2, 0]) - curve.duration_s, float(cps[-1, 2, 1]))
    elif curve.periodic and n == 1:
        out["in"] = (float(cps[0, 2, 0]) - curve.duration_s, float(cps[0, 2, 1]))
    return out


def move_knots(channel: str, curve: HermiteCurve, indices: Iterable[int], dt: float, dv: float,
               limits: tuple[float, float]) -> tuple[HermiteCurve, list[str]]:
    """Move knots by (dt, dv) from ``curve`` under the editor's constraints; returns (curve, notes).

    Swing boundary knots keep their time (and value 0, pitch channels: clamped value); other
    knots stay inside the interval (periodic: ``[0, duration)``) and between their
    neighbours; values clamp to ``limits``. Knots move far side first so a group keeps order.
    """
    knots = curve.knots
    n = len(knots)
    d = curve.duration_s
    pitch = channel.endswith("_pitch")
    notes: list[str] = []
    result = curve
    for i in sorted(set(indices), reverse=bool(dt > 0)):
        k = knots[i]
        t, v = k.t_s + dt, k.value + dv
        if is_pinned(channel, i, n):
            t = k.t_s
            if not pitch:
                if abs(dv) > 0 or abs(dt) > 0:
                    notes.append("swing boundary knots stay at 0 at liftoff/touchdown")
                v = k.value
            elif abs(dt) > 0:
                notes.append("swing boundary knots keep their time")
        elif curve.periodic and not 0.0 <= t < d:
            notes.append(f"knots stay inside the cycle [0, {d:.3f}) s")
        elif not curve.periodic and not 0.0 < t < d:
            notes.append(f"knots stay inside the swing (0, {d:.3f}) s")
        lo, hi = limits
        if v < lo or v > hi:
            notes.append(f"{channel} clamped to [{lo:.3g}, {hi:.3g}]")
            v = min(max(v, lo), hi)
        result = result.with_knot_moved(i, t, v)
        got = result.knots[i].t_s
        if abs(got - t) > 1e-9 and not notes and not is_pinned(channel, i, n):
            notes.append("knot times stay between their neighbours")
    return result, list(dict.fromkeys(notes))


def slope_from_handle(curve: HermiteCurve, index: int, side: str, t_h: float, v_h: float) -> float:
    """Slope implied by dragging a knot's ``side`` handle to (t_h, v_h); the handle cannot cross the knot."""
    k = curve.knots[index]
    eps = 1e-3 * curve.duration_s
    dt = t_h - k.t_s
    dt = max(dt, eps) if side == "out" else min(dt, -eps)
    return (v_h - k.value) / dt


def with_handle_slope(curve: HermiteCurve, index: int, side: str, slope: float) -> HermiteCurve:
    """Blender semantics: automatic modes become ALIGNED, ALIGNED mirrors, FREE keeps sides independent."""
    mode = curve.knots[index].mode
    if mode is TangentMode.FREE:
        return curve.with_tangent(index, TangentMode.FREE, **({"in_slope": slope} if side == "in" else {"out_slope": slope}))
    return curve.with_tangent(index, TangentMode.ALIGNED, in_slope=slope)


def paste_knots(clip: Clipboard, target: str, duration_s: float, mirror: bool, half_cycle: bool) -> list[Knot]:
    """The clipboard's knots as they land on channel ``target`` whose interval lasts ``duration_s``.

    Times rescale to the target interval (normalised time) and slopes with them; crossing to the
    opposite side with ``mirror`` negates lateral components (:func:`mirror_sign`); ``half_cycle``
    shifts cycle knots by half a period when crossing sides. Sorted by time.
    """
    d = duration_s
    scale = d / clip.duration_s
    crosses = target == opposite_channel(clip.channel)
    sign = mirror_sign(clip.channel) if (mirror and crosses) else 1.0
    pasted = []
    for k in clip.knots:
        t = k.t_s * scale
        if clip.periodic:
            if half_cycle and crosses:
                t += 0.5 * d
            t %= d
            if t >= d:
                t = 0.0
        else:
            t = d if k.t_s == clip.duration_s else min(t, d)
        pasted.append(Knot(t, sign * k.value, sign * k.in_slope / scale, sign * k.out_slope / scale, k.mode))
    pasted.sort(key=lambda k: k.t_s)
    return pasted


def merge_knots(channel: str, target: HermiteCurve | None, pasted: list[Knot], duration_s: float) -> HermiteCurve:
    """``target`` with ``pasted`` knots replacing its knots in their time span (swing boundary knots kept
    unless a pasted knot lands on them; pasted knots closer than MIN_KNOT_GAP_S to a kept one dropped).
    Raises ValueError if the result is not a valid curve."""
    d = duration_s
    periodic = channel_interval(channel) == "cycle"
    if target is None:
        base = [] if periodic else [Knot(0.0, 0.0, mode=TangentMode.FLAT), Knot(d, 0.0, mode=TangentMode.FLAT)]
    else:
        base = list(target.knots)
    lo, hi = pasted[0].t_s, pasted[-1].t_s
    n = len(base)
    kept = [k for i, k in enumerate(base)
            if not (lo - 1e-9 <= k.t_s <= hi + 1e-9) or (is_pinned(channel, i, n)
                                                        and all(abs(p.t_s - k.t_s) > 1e-9 for p in pasted))]
    merged = kept + [p for p in pasted if all(abs(p.t_s - k.t_s) >= MIN_KNOT_GAP_S for k in kept)]
    return HermiteCurve(sorted(merged, key=lambda k: k.t_s), d, periodic)
