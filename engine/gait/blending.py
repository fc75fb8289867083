"""Phase-space blending of gait samples (paper §5.1–5.2), generalised to N weighted samples.

Two-sample blending (the paper's six steps) nests: blending the blends of the three-step
velocity sampler (§5.3) with the same phase φ is the same as a convex combination of all
samples evaluated at their own equivalent times, value(t) = Σ wᵢ fᵢ(Ωᵢ(Ω⁻¹(t))), where Ω is
the phase map of the blended intervals. Attributes and intervals blend linearly (Eq. 7), so
event ordering and minimum durations survive any convex combination.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import numpy as np

from engine.gait.curves import HermiteCurve
from engine.gait.phase_map import PHASE_WAYPOINTS, PHI_LTD, PHI_RLO, PHI_RTD, PhaseMap
from engine.gait.planner_kernels import merged_bank_at_phase, merged_bank_rows
from engine.gait.style import (
    ATTRIBUTE_NAMES,
    PELVIS_CURVES,
    SIDES,
    Attributes,
    GaitSample,
    Intervals,
    Style,
    swing_channels,
)

SWING_PHASES = {"left": (0.0, PHI_LTD), "right": (PHI_RLO, PHI_RTD)}  # (liftoff φ, touchdown φ)
# A blend member of this weight or less is dropped (the rest renormalised): the blend is then the others alone.
MIN_MEMBER_WEIGHT = 1e-9
HEEL, TOE = 4, 5  # indices of heel_pitch / toe_pitch in a swing bank
ATTRIBUTE_INDEX = {name: i for i, name in enumerate(ATTRIBUTE_NAMES)}
WAYPOINT_PHASES = np.array(PHASE_WAYPOINTS)  # the phase maps' waypoint phases (bisect in PhaseMap.time_at)


class CurveBank:
    """Several curves on one interval evaluated together (values and time derivatives)."""

    def __init__(self, curves: Sequence[HermiteCurve | None], defaults: np.ndarray, duration_s: float, periodic: bool):
        self.duration_s = float(duration_s)
        self.periodic = periodic
        rows = []
        for curve, default in zip(curves, defaults):
            segs = curve.segments() if curve is not None else np.zeros((0, 5))
            if curve is None or len(segs) == 0:
                value = float(default) if curve is None or curve.n_knots == 0 else float(curve.knots[0].value)
                rows.append(np.array([[-math.inf, value, 0.0, 0.0, 0.0]]))
                continue
            if periodic:  # the wrap segment also covers [0, first knot)
                wrap = segs[-1].copy()
                wrap[0] -= self.duration_s
                segs = np.vstack([wrap, segs])
            rows.append(segs)
        n_seg = max(len(r) for r in rows)
        self.n = len(rows)
        self.t0 = np.zeros((self.n, n_seg))
        self.search = np.full((self.n, n_seg), math.inf)
        self.coef = np.zeros((self.n, n_seg, 4))
        for i, segs in enumerate(rows):
            k = len(segs)
            self.t0[i, :k] = segs[:, 0]
            self.search[i, :k] = segs[:, 0]
            self.search[i, 0] = -math.inf
            self.coef[i, :k] = segs[:, 1:]
            self.t0[i, 0] = segs[0, 0] if math.isfinite(segs[0, 0]) else 0.0
        self._rows = np.arange(self.n)

    def evaluate(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        if self.periodic:
            t = t_s % self.duration_s
        else:
            t = min(max(t_s, 0.0), self.duration_s)
        idx = (self.search <= t).sum(axis=1) - 1
        tau = t - self.t0[self._rows, idx]
        c = self.coef[self._rows, idx]
        a, b, cc, d = c[:, 0], c[:, 1], c[:, 2], c[:, 3]
        values = a + tau * (b + tau * (cc + tau * d))
        rates = b + tau * (2.0 * cc + 3.0 * d * tau)
        return values, rates


@dataclass(frozen=True)
class ChannelLayout:
    """The curve channels a robot's reference is built from, in a fixed order."""

    upper_joints: tuple[str, ...]
    upper_defaults: np.ndarray  # standing angles

    @property
    def cycle_channels(self) -> tuple[str, ...]:
        return (*PELVIS_CURVES, *(f"joints.{j}" for j in self.upper_joints))

    @property
    def cycle_defaults(self) -> np.ndarray:
        return np.concatenate([np.zeros(len(PELVIS_CURVES)), self.upper_defaults])


class SampleBanks:
    """A gait sample prepared for fast evaluation: its phase map and three curve banks."""

    def __init__(self, sample: GaitSample, layout: ChannelLayout):
        self.sample = sample
        iv = sample.intervals
        self.intervals = iv
        self.phase_map = iv.phase_map()
        self.swing_start_s = {"left": iv.left_swing_s[0], "right": iv.right_swing_s[0]}
        self.swing = {
            side: CurveBank([sample.curves.get(c) for c in swing_channels(side)], np.zeros(7),
                            iv.swing_duration_s(side), periodic=False)
            for side in SIDES
        }
        self.cycle = CurveBank([sample.curves.get(c) for c in layout.cycle_channels], layout.cycle_defaults,
                               iv.cycle_s, periodic=True)
        self.events = np.array(iv.events_s)
        self.attribute_vector = np.array([getattr(sample.attributes, k) for k in ATTRIBUTE_NAMES])
        # Heel/toe pitch at the swing boundaries, for the support-phase transitions.
        self.boundary_pitch = {}
        for side in SIDES:
            start, _ = self.swing[side].evaluate(0.0)
            end, _ = self.swing[side].evaluate(iv.swing_duration_s(side))
            self.boundary_pitch[side] = ((start[HEEL], start[TOE]), (end[HEEL], end[TOE]))


class MergedBank:
    """All channels of several samples in one vectorised evaluation (rows: per sample, cycle
    channels then left swing then right swing), each row at its own sample's equivalent time."""

    def __init__(self, banks: Sequence[SampleBanks]):
        self.banks = list(banks)  # pinned: caches key merged banks by the members' identities
        self.n_members = len(banks)
        parts = []
        self.n_cycle = banks[0].cycle.n
        for b in banks:
            parts += [b.cycle, b.swing["left"], b.swing["right"]]
        width = max(p.search.shape[1] for p in parts)

        def pad(arr, fill):
            out = np.full((arr.shape[0], width) + arr.shape[2:], fill, dtype=float)
            out[:, : arr.shape[1]] = arr
            return out

        self.search = np.vstack([pad(p.search, math.inf) for p in parts])
        self.t0 = np.vstack([pad(p.t0, 0.0) for p in parts])
        self.coef = np.vstack([pad(p.coef, 0.0) for p in parts])
        rows_per = self.n_cycle + 14
        self.rows_per_member = rows_per
        self.member_of_row = np.repeat(np.arange(self.n_members), rows_per)
        offset, period, hi = [], [], []
        for b in banks:
            offset += [0.0] * self.n_cycle + [0.0] * 7 + [b.swing_start_s["right"]] * 7
            period += [b.intervals.cycle_s] * self.n_cycle + [0.0] * 14
            hi += [b.intervals.cycle_s] * self.n_cycle + [b.intervals.swing_duration_s("left")] * 7 + \
                  [b.intervals.swing_duration_s("right")] * 7
        self.events = np.array([b.events for b in banks])
        self.attributes = np.array([b.attribute_vector for b in banks])
        self.boundary_pitch = np.array([[b.boundary_pitch[side] for side in SIDES] for b in banks])
        self.boundary_pitch_rows = self.boundary_pitch.reshape(self.n_members, -1)  # tensordot's (members, 8) operand
        self.offset = np.array(offset)
        self.periodic = np.array(period) > 0
        self.period = np.where(self.periodic, np.array(period), 1.0)
        self.hi = np.array(hi)
        self._rows = np.arange(len(self.offset))
        # The members' phase maps for merged_bank_at_phase: per segment its phase and cubic (PhaseMap._seg), cycles
        self.phase_segments = np.array([[seg[:5] for seg in b.phase_map._seg] for b in banks])
        self.cycles = np.array([b.phase_map.cycle_s for b in banks])

    def evaluate(self, member_times: np.ndarray, member_rate_scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Values and d/dt of every row; shapes (members, rows_per_member). Compiled
        (:func:`engine.gait.planner_kernels.merged_bank_rows`); :meth:`evaluate_numpy` is the reference."""
        values, rates = merged_bank_rows(
            np.ascontiguousarray(member_times, dtype=np.float64), np.ascontiguousarray(member_rate_scale, dtype=np.float64),
            self.member_of_row, self.offset, self.periodic, self.period, self.hi, self.search, self.t0, self.coef)
        shape = (self.n_members, self.rows_per_member)
        return values.reshape(shape), rates.reshape(shape)

    def evaluate_at_phase(self, phase: float, dphase_dt: float) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`evaluate` with each member at its own time Ωᵢ(φ) of ``phase`` and its rates scaled by Ωᵢ'(φ) ·
        ``dphase_dt`` (the chain rule of :meth:`BlendedGait.channels`), in one compiled call."""
        values, rates = merged_bank_at_phase(
            float(phase), float(dphase_dt), WAYPOINT_PHASES, self.phase_segments, self.cycles, self.member_of_row, self.offset,
            self.periodic, self.period, self.hi, self.search, self.t0, self.coef)
        shape = (self.n_members, self.rows_per_member)
        return values.reshape(shape), rates.reshape(shape)

    def evaluate_numpy(self, member_times: np.ndarray, member_rate_scale: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        t = member_times[self.member_of_row] - self.offset
        t = np.where(self.periodic, np.mod(t, self.period), np.clip(t, 0.0, self.hi))
        idx = (self.search <= t[:, None]).sum(axis=1) - 1
        tau = t - self.t0[self._rows, idx]
        c = self.coef[self._rows, idx]
        values = c[:, 0] + tau * (c[:, 1] + tau * (c[:, 2] + tau * c[:, 3]))
        rates = (c[:, 1] + tau * (2.0 * c[:, 2] + 3.0 * c[:, 3] * tau)) * member_rate_scale[self.member_of_row]
        shape = (self.n_members, self.rows_per_member)
        return values.reshape(shape), rates.reshape(shape)


class BlendedGait:
    """Π of a velocity: samples with convex weights, evaluated in phase space."""

    def __init__(self, members: Sequence[tuple[float, SampleBanks]], merged: MergedBank | None = None):
        members = [(float(w), b) for w, b in members if w > MIN_MEMBER_WEIGHT]
        raw = [w for w, _ in members]
        total = sum(raw)  # (left to right from 0, as over the members)
        if not members or total <= 0:
            raise ValueError("a blend needs at least one sample with positive weight")
        normed = [w / total for w in raw]
        self.members = [(w, b) for w, (_, b) in zip(normed, members)]
        self.weights = np.array(normed)
        self.merged = merged if merged is not None else MergedBank([b for _, b in self.members])
        m = self.merged
        self.events_array = self.weights @ m.events  # (4,) t_LTD, t_RLO, t_RTD, cycle: events_s as an array
        t_ltd, t_rlo, t_rtd, cycle = self.events_array.tolist()
        self.events_s = (t_ltd, t_rlo, t_rtd, cycle)
        self.attribute_values = self.weights @ m.attributes
        self._attribute_list: list[float] = self.attribute_values.tolist()  # read one by one, as floats
        self.phase_map = PhaseMap(t_ltd, t_rlo, t_rtd, cycle)
        self._last_time_at: tuple[float, float] | None = None  # (φ, time_at(φ)) of the last call
        # np.tensordot(weights, boundary_pitch, axes=1) without its Python overhead: the same (1, n) · (n, 8) dot
        # (boundary_pitch_array: (2, 2, 2) per side (liftoff, touchdown) (heel, toe), boundary_pitch's numbers)
        self.boundary_pitch_array = np.dot(self.weights.reshape(1, -1), m.boundary_pitch_rows).reshape(
            m.boundary_pitch.shape[1:])
        bp = self.boundary_pitch_array.tolist()
        self.boundary_pitch = {side: (tuple(bp[i][0]), tuple(bp[i][1])) for i, side in enumerate(SIDES)}

    @cached_property
    def intervals(self) -> Intervals:
        t_ltd, t_rlo, t_rtd, cycle = self.events_s
        return Intervals(cycle, (0.0, t_ltd), (t_rlo, t_rtd))

    @cached_property
    def attributes(self) -> Attributes:
        return Attributes(**{k: float(v) for k, v in zip(ATTRIBUTE_NAMES, self.attribute_values)})

    def attribute(self, name: str) -> float:
        return self._attribute_list[ATTRIBUTE_INDEX[name]]

    def time_at(self, phi: float) -> float:
        """Gait time of phase φ in the blended cycle (φ may exceed 1: later cycles). The last answer is kept:
        a planner tick asks for the time of its phase several times."""
        last = self._last_time_at
        if last is not None and last[0] == phi:
            return last[1]
        k = math.floor(phi)
        t = k * self.events_s[3] + float(self.phase_map.time_at(phi - k))
        self._last_time_at = (phi, t)
        return t

    def phase_of_time(self, t_s: float) -> float:
        """Inverse of :meth:`time_at` on the unwrapped gait time (cycles + phase)."""
        cycle = self.events_s[3]
        k = math.floor(t_s / cycle)
        return k + float(self.phase_map.phase_at(t_s - k * cycle))

    def event_time(self, phi_event: float) -> float:
        """Gait time of an event phase (integer + 0, 0.1, 0.5 or 0.6): exact, no spline evaluation."""
        k = math.floor(phi_event + 1e-9)
        f = phi_event - k
        t_ltd, t_rlo, t_rtd, cycle = self.events_s
        if f < 0.05:
            t = 0.0
        elif f < 0.3:
            t = t_ltd
        elif f < 0.55:
            t = t_rlo
        else:
            t = t_rtd
        return k * cycle + t

    def dtime_dphase(self, phi: float) -> float:
        return float(self.phase_map.dtime_dphase(phi - math.floor(phi)))

    def channels(self, phi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Blended (cycle, left swing, right swing) values and their time rates at phase φ.

        Each sample is evaluated at its equivalent time Ωᵢ(φ); rates follow the chain rule
        dfᵢ/dt = fᵢ'(tᵢ) Ωᵢ'(φ) / Ω'(φ).
        """
        f = phi - math.floor(phi)
        dphi_dt = 1.0 / self.dtime_dphase(phi)
        values, rates = self.merged.evaluate_at_phase(f, dphi_dt)  # times[i] = Ωᵢ(f), rates scaled by Ωᵢ'(f) dφ/dt
        v = self.weights @ values
        r = self.weights @ rates
        c = self.merged.n_cycle
        return v[:c], v[c:c + 7], v[c + 7:], r[:c], r[c:c + 7], r[c + 7:]

    def channel_values(self, phi: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`channels`' values alone (cycle, left swing, right swing): the same numbers, without the rates'
        weighted sum, their slices and the phase map's slope dΩ/dφ (the values do not depend on it: it only scales
        the rates)."""
        values, _ = self.merged.evaluate_at_phase(phi - math.floor(phi), 1.0)
        v = self.weights @ values
        c = self.merged.n_cycle
        return v[:c], v[c:c + 7], v[c + 7:]

    def swing_values(self, side: str, phi: float) -> tuple[np.ndarray, np.ndarray]:
        """Blended swing channels (x, y, z, yaw, heel_pitch, toe_pitch, roll) and their rates at φ."""
        cv, lv, rv, cr, lr, rr = self.channels(phi)
        return (lv, lr) if side == "left" else (rv, rr)

    def cycle_values(self, phi: float) -> tuple[np.ndarray, np.ndarray]:
        """Blended cycle channels (pelvis z, yaw, pitch, roll, upper joints...) and rates at φ."""
        cv, _, _, cr, _, _ = self.channels(phi)
        return cv, cr


class StyleBanks:
    """A style prepared for blending: banks per sample, cached by sample identity."""

    def __init__(self, style: Style, layout: ChannelLayout, previous: "StyleBanks | None" = None):
        self.style = style
        self.layout = layout
        old: dict[str, SampleBanks] = previous.banks if previous is not None and previous.layout == layout else {}
        self.banks: dict[str, SampleBanks] = {}
        for name, sample in style.samples.items():
            prev = old.get(name)
            self.banks[name] = prev if prev is not None and prev.sample is sample else SampleBanks(sample, layout)

        self._merged: dict[tuple[int, ...], MergedBank] = {}

    def merged_for(self, banks: Sequence[SampleBanks]) -> MergedBank:
        """The merged bank of a member set (rebuilt only when the set of blended samples changes)."""
        key = tuple(id(b) for b in banks)
        merged = self._merged.get(key)
        if merged is None:
            if len(self._merged) > 32:
                self._merged.clear()
            merged = self._merged[key] = MergedBank(banks)
        return merged

    def blend(self, members: Sequence[tuple[float, SampleBanks]]) -> BlendedGait:
        members = [(float(w), b) for w, b in members if w > MIN_MEMBER_WEIGHT]
        return BlendedGait(members, self.merged_for([b for _, b in members]))
