"""Cubic Hermite function curves, as edited in an animator's graph editor.

A :class:`HermiteCurve` is the representation of the function curves of a
gait sample (paper Sec. 4.3 "Function Curves", Sec. 6.1): a list of knots
(time, value, in/out slope, tangent mode) living on a time interval of
duration ``duration_s``.  Curve time is relative to the start of that
interval (``0 .. duration_s``).

* Periodic curves (cycle interval CY: pelvis, upper body) wrap: the segment
  after the last knot runs to the first knot at ``t + duration_s``,
  evaluation takes time modulo ``duration_s`` and automatic tangents are
  computed cyclically, so the curve is C1 across the loop.
* Non-periodic curves (swing intervals LS / RS) hold the first / last knot
  value outside the knot range (constant extrapolation, derivative 0).

Slopes are ``dvalue/dt`` in value-units per second.  Each segment between
knots ``(t0, v0, m0)`` and ``(t1, v1, m1)`` is the cubic Hermite polynomial
with end slopes ``m0`` (out-slope of the left knot) and ``m1`` (in-slope of
the right knot).

The class is immutable: all editing helpers return new curves.  Knot slopes
stored in a curve are always the *resolved* slopes, i.e. for the automatic
modes (AUTO_CLAMPED, FLAT, LINEAR) ``curve.knots[i].in_slope`` is the slope
actually used, so switching a knot to ALIGNED / FREE without giving slopes
keeps the current shape (as in Blender / Maya).
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass, replace
from enum import Enum
from typing import Any, Iterable, Mapping, Sequence

import numpy as np

__all__ = [
    "MIN_KNOT_GAP_S",
    "TangentMode",
    "Knot",
    "HermiteCurve",
]

#: Minimum time between neighbouring knots enforced by the editing helpers.
MIN_KNOT_GAP_S: float = 1e-3
#: Arrays up to this size are evaluated through the (faster) scalar path.
_SMALL_ARRAY = 16


class TangentMode(str, Enum):
    """Tangent (handle) mode of a knot.

    AUTO_CLAMPED
        Smooth finite-difference slope, clamped so the curve never
        overshoots between keys: slope 0 at local extrema and next to flat
        neighbours, and limited to ``3 * min(|secant|)`` (Fritsch-Carlson box)
        so every segment between two auto-clamped knots stays within the
        ``[min, max]`` of its two keys.  First / last knot of a non-periodic
        curve get slope 0 (Blender behaviour with constant extrapolation).
    FLAT
        In and out slope 0.
    LINEAR
        In-slope is the secant to the previous knot, out-slope the secant to
        the next one (a missing side copies the other side).
    ALIGNED
        One user-set slope used for both sides (C1).
    FREE
        Independent user-set in and out slopes ("broken" tangents).
    """

    AUTO_CLAMPED = "auto_clamped"
    FLAT = "flat"
    LINEAR = "linear"
    ALIGNED = "aligned"
    FREE = "free"


_AUTOMATIC_MODES = (TangentMode.AUTO_CLAMPED, TangentMode.FLAT, TangentMode.LINEAR)


@dataclass
class Knot:
    """A function-curve key.

    Parameters
    ----------
    t_s : float
        Knot time relative to the start of the curve's interval [s].
    value : float
        Curve value at the knot (value units).
    in_slope, out_slope : float
        Incoming / outgoing slope [value-units / s].  Only meaningful for
        ALIGNED (must be equal) and FREE knots; recomputed for the others.
    mode : TangentMode
        Tangent mode.
    """

    t_s: float
    value: float
    in_slope: float = 0.0
    out_slope: float = 0.0
    mode: TangentMode = TangentMode.AUTO_CLAMPED


def _as_mode(mode: TangentMode | str) -> TangentMode:
    try:
        return TangentMode(mode)
    except ValueError:
        valid = ", ".join(m.value for m in TangentMode)
        raise ValueError(f"unknown tangent mode {mode!r} (expected one of: {valid})") from None


def _auto_clamped_slope(d_prev: float, d_next: float, h_prev: float, h_next: float) -> float:
    """Clamped three-point slope from the two adjacent secants.

    Parabolic (second-order) finite difference through the three knots,
    zeroed at extrema / flat neighbours and limited to ``3 * min(|d|)``.
    """
    if d_prev == 0.0 or d_next == 0.0 or (d_prev > 0.0) != (d_next > 0.0):
        return 0.0
    m = (h_next * d_prev + h_prev * d_next) / (h_prev + h_next)
    limit = 3.0 * min(abs(d_prev), abs(d_next))
    if abs(m) > limit:
        m = math.copysign(limit, m)
    return m


class HermiteCurve:
    """Piecewise cubic Hermite function curve.

    Parameters
    ----------
    knots : iterable of Knot
        Keys; sorted by time on construction.  Identical times raise
        ``ValueError``.  Periodic curves need ``0 <= t_s < duration_s``,
        non-periodic ones ``0 <= t_s <= duration_s``.
    duration_s : float
        Duration of the interval the curve lives on [s], > 0.
    periodic : bool
        Whether the curve loops with period ``duration_s``.

    Notes
    -----
    0 knots evaluate to constant 0, 1 knot to a constant.  Derivatives at a
    knot are right-sided (out-slope), except at the last knot of a
    non-periodic curve (in-slope).  Outside the knot range of a
    non-periodic curve the value is held and derivatives are 0.
    """

    __slots__ = (
        "_knots",
        "_duration_s",
        "_periodic",
        "_t",
        "_v",
        "_m_in",
        "_m_out",
        "_seg_t0",
        "_seg_h",
        "_coef",
        "_seg_list",
        "_t_list",
        "_t_first",
        "_t_last",
        "_v_first",
        "_v_last",
        "_n_seg",
    )

    def __init__(self, knots: Iterable[Knot], duration_s: float, periodic: bool = False) -> None:
        duration_s = float(duration_s)
        if not (math.isfinite(duration_s) and duration_s > 0.0):
            raise ValueError(f"duration_s must be a positive finite number, got {duration_s!r}")
        self._duration_s = duration_s
        self._periodic = bool(periodic)

        raw = list(knots)
        for i, k in enumerate(raw):
            if not isinstance(k, Knot):
                raise TypeError(f"knot {i} is not a Knot: {k!r}")
            for name in ("t_s", "value", "in_slope", "out_slope"):
                if not math.isfinite(float(getattr(k, name))):
                    raise ValueError(f"knot {i}: {name} must be finite, got {getattr(k, name)!r}")
        order = sorted(range(len(raw)), key=lambda i: float(raw[i].t_s))
        for a, b in zip(order, order[1:]):
            if float(raw[a].t_s) == float(raw[b].t_s):
                raise ValueError(
                    f"knot {b} has the same time as knot {a} (t_s={float(raw[b].t_s)!r}); "
                    "knot times must be distinct"
                )
        for i in order:
            t = float(raw[i].t_s)
            if self._periodic and not (0.0 <= t < duration_s):
                raise ValueError(
                    f"knot {i}: t_s={t!r} outside [0, {duration_s!r}) of a periodic curve"
                )
            if not self._periodic and not (0.0 <= t <= duration_s):
                raise ValueError(f"knot {i}: t_s={t!r} outside [0, {duration_s!r}]")

        sorted_knots = [
            Knot(
                float(raw[i].t_s),
                float(raw[i].value),
                float(raw[i].in_slope),
                float(raw[i].out_slope),
                _as_mode(raw[i].mode),
            )
            for i in order
        ]
        for j, k in zip(order, sorted_knots):
            if k.mode is TangentMode.ALIGNED and k.in_slope != k.out_slope:
                raise ValueError(
                    f"knot {j}: ALIGNED tangents need in_slope == out_slope "
                    f"(got {k.in_slope!r} and {k.out_slope!r}); use FREE for broken tangents"
                )

        m_in, m_out = self._resolve(sorted_knots)
        self._knots = tuple(
            replace(k, in_slope=a, out_slope=b) for k, a, b in zip(sorted_knots, m_in, m_out)
        )
        self._build()

    # ------------------------------------------------------------------ setup
    def _resolve(self, knots: Sequence[Knot]) -> tuple[list[float], list[float]]:
        """Apply the tangent modes, returning (in_slopes, out_slopes)."""
        n = len(knots)
        m_in = [k.in_slope for k in knots]
        m_out = [k.out_slope for k in knots]
        if n == 0:
            return m_in, m_out
        if n == 1:
            k = knots[0]
            if k.mode in _AUTOMATIC_MODES:
                m_in[0] = m_out[0] = 0.0
            return m_in, m_out
        D = self._duration_s
        for i, k in enumerate(knots):
            if k.mode in (TangentMode.ALIGNED, TangentMode.FREE):
                continue
            if k.mode is TangentMode.FLAT:
                m_in[i] = m_out[i] = 0.0
                continue
            # neighbours (possibly wrapped) -> secants; None when absent
            d_prev = d_next = None
            h_prev = h_next = 0.0
            if i > 0:
                h_prev = k.t_s - knots[i - 1].t_s
                d_prev = (k.value - knots[i - 1].value) / h_prev
            elif self._periodic:
                h_prev = k.t_s + D - knots[-1].t_s
                d_prev = (k.value - knots[-1].value) / h_prev
            if i < n - 1:
                h_next = knots[i + 1].t_s - k.t_s
                d_next = (knots[i + 1].value - k.value) / h_next
            elif self._periodic:
                h_next = knots[0].t_s + D - k.t_s
                d_next = (knots[0].value - k.value) / h_next
            if k.mode is TangentMode.LINEAR:
                a = d_prev if d_prev is not None else d_next
                b = d_next if d_next is not None else d_prev
                assert a is not None and b is not None  # a curve has ≥ 2 knots or is periodic
                m_in[i], m_out[i] = float(a), float(b)
            else:  # AUTO_CLAMPED
                if d_prev is None or d_next is None:
                    m = 0.0  # end knot of a non-periodic curve: flat handle
                else:
                    m = _auto_clamped_slope(d_prev, d_next, h_prev, h_next)
                m_in[i] = m_out[i] = m
        return m_in, m_out

    def _build(self) -> None:
        """Precompute per-segment polynomial coefficients."""
        ks = self._knots
        n = len(ks)
        D = self._duration_s
        self._t = np.array([k.t_s for k in ks], dtype=float)
        self._v = np.array([k.value for k in ks], dtype=float)
        self._m_in = np.array([k.in_slope for k in ks], dtype=float)
        self._m_out = np.array([k.out_slope for k in ks], dtype=float)
        if n >= 2:
            # plain Python floats: the scalar path avoids numpy-scalar overhead
            t0 = self._t.tolist()
            t1 = t0[1:]
            v0 = self._v.tolist()
            v1 = v0[1:]
            m0 = self._m_out.tolist()
            m1 = self._m_in.tolist()[1:]
            if self._periodic:
                t1.append(ks[0].t_s + D)
                v1.append(ks[0].value)
                m1.append(ks[0].in_slope)
            else:
                t0, v0, m0 = t0[:-1], v0[:-1], m0[:-1]
            seg = []
            for a_t, b_t, a_v, b_v, a_m, b_m in zip(t0, t1, v0, v1, m0, m1):
                h = b_t - a_t
                d = (b_v - a_v) / h
                c2 = (3.0 * d - 2.0 * a_m - b_m) / h
                c3 = (a_m + b_m - 2.0 * d) / (h * h)
                seg.append((a_t, a_v, a_m, c2, c3, h))
            self._seg_list = [s[:5] for s in seg]
            self._seg_t0 = np.array([s[0] for s in seg], dtype=float)
            self._seg_h = np.array([s[5] for s in seg], dtype=float)
            self._coef = np.array([s[1:5] for s in seg], dtype=float)  # (n_seg, 4)
        else:
            self._seg_list = []
            self._seg_t0 = np.zeros(0)
            self._seg_h = np.zeros(0)
            self._coef = np.zeros((0, 4))
        self._n_seg = len(self._seg_list)
        self._t_list = [s[0] for s in self._seg_list]
        self._t_first = ks[0].t_s if n else 0.0
        self._t_last = ks[-1].t_s if n else 0.0
        self._v_first = ks[0].value if n else 0.0
        self._v_last = ks[-1].value if n else 0.0

    # ------------------------------------------------------------- properties
    @property
    def knots(self) -> tuple[Knot, ...]:
        """Knots sorted by time, with resolved slopes (copies)."""
        return tuple(replace(k) for k in self._knots)

    @property
    def duration_s(self) -> float:
        """Duration of the curve's interval [s]."""
        return self._duration_s

    @property
    def periodic(self) -> bool:
        """Whether the curve wraps with period ``duration_s``."""
        return self._periodic

    @property
    def n_knots(self) -> int:
        """Number of knots."""
        return len(self._knots)

    @property
    def n_segments(self) -> int:
        """Number of cubic segments (``n`` periodic, ``n - 1`` otherwise)."""
        return self._n_seg

    def __len__(self) -> int:
        return len(self._knots)

    def __repr__(self) -> str:
        kind = "periodic" if self._periodic else "non-periodic"
        return f"HermiteCurve({len(self._knots)} knots, duration_s={self._duration_s!r}, {kind})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, HermiteCurve):
            return NotImplemented
        return (
            self._knots == other._knots
            and self._duration_s == other._duration_s
            and self._periodic == other._periodic
        )

    __hash__ = None  # type: ignore[assignment]

    def resolved_slopes(self) -> tuple[np.ndarray, np.ndarray]:
        """Slopes after applying the tangent modes.

        Returns
        -------
        in_slopes, out_slopes : np.ndarray
            Shape ``(n_knots,)`` each [value-units / s].
        """
        return self._m_in.copy(), self._m_out.copy()

    # ------------------------------------------------------------- evaluation
    def _locate_scalar(self, t: float) -> tuple[int, float] | None:
        """Segment index and local time, or None when in a constant region."""
        if self._periodic:
            # t % D is exact for t in [0, D), so knot times hit their knots exactly
            tau = t % self._duration_s
            if tau < self._t_first:
                tau += self._duration_s
        else:
            if t < self._t_first or t >= self._t_last:
                return None
            tau = t
        k = bisect_right(self._t_list, tau) - 1
        if k < 0:
            k = 0
        return k, tau - self._t_list[k]

    def _locate_array(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Vectorised segment lookup: (segment index, local time, inside mask)."""
        if self._periodic:
            tau = np.mod(t, self._duration_s)
            tau = np.where(tau < self._t_first, tau + self._duration_s, tau)
            inside = np.ones(t.shape, dtype=bool)
        else:
            tau = t
            inside = (t >= self._t_first) & (t < self._t_last)
        k = np.searchsorted(self._seg_t0, tau, side="right") - 1
        k = np.clip(k, 0, self._n_seg - 1)
        return k, tau - self._seg_t0[k], inside

    @staticmethod
    def _small(fn: Any, t: np.ndarray) -> float | np.ndarray:
        """Small arrays: the scalar path beats numpy's per-call overhead."""
        if t.ndim == 0:
            return float(fn(float(t)))
        return np.array([fn(x) for x in t.ravel().tolist()], dtype=float).reshape(t.shape)

    def evaluate(self, t_s: float | np.ndarray) -> float | np.ndarray:
        """Curve value at time(s) ``t_s`` [s] (scalar or array of any shape)."""
        if isinstance(t_s, (float, int)):
            n = self._n_seg
            if n == 0:
                return float(self._v_first)
            loc = self._locate_scalar(float(t_s))
            if loc is None:
                return self._v_first if t_s < self._t_first else self._v_last
            k, s = loc
            _, c0, c1, c2, c3 = self._seg_list[k]
            return c0 + s * (c1 + s * (c2 + s * c3))
        ta = np.asarray(t_s, dtype=float)
        if ta.size <= _SMALL_ARRAY:
            return self._small(self.evaluate, ta)
        if self._n_seg == 0:
            out = np.full(ta.shape, float(self._v_first))
            return out if ta.ndim else float(out)
        ka, sa, inside = self._locate_array(ta)
        c = self._coef[ka]
        out = c[..., 0] + sa * (c[..., 1] + sa * (c[..., 2] + sa * c[..., 3]))
        if not self._periodic:
            out = np.where(inside, out, np.where(ta < self._t_first, self._v_first, self._v_last))
        return out if ta.ndim else float(out)

    def derivative(self, t_s: float | np.ndarray) -> float | np.ndarray:
        """First time derivative [value-units / s] at ``t_s``."""
        if isinstance(t_s, (float, int)):
            if self._n_seg == 0:
                return 0.0
            t = float(t_s)
            if not self._periodic and t == self._t_last:
                return float(self._m_in[-1])
            loc = self._locate_scalar(t)
            if loc is None:
                return 0.0
            k, s = loc
            _, _, c1, c2, c3 = self._seg_list[k]
            return c1 + s * (2.0 * c2 + 3.0 * s * c3)
        ta = np.asarray(t_s, dtype=float)
        if ta.size <= _SMALL_ARRAY:
            return self._small(self.derivative, ta)
        if self._n_seg == 0:
            out = np.zeros(ta.shape)
            return out if ta.ndim else float(out)
        ka, sa, inside = self._locate_array(ta)
        c = self._coef[ka]
        out = c[..., 1] + sa * (2.0 * c[..., 2] + 3.0 * sa * c[..., 3])
        if not self._periodic:
            out = np.where(inside, out, np.where(ta == self._t_last, self._m_in[-1], 0.0))
        return out if ta.ndim else float(out)

    def second_derivative(self, t_s: float | np.ndarray) -> float | np.ndarray:
        """Second time derivative [value-units / s^2] at ``t_s``."""
        if isinstance(t_s, (float, int)):
            if self._n_seg == 0:
                return 0.0
            t = float(t_s)
            if not self._periodic and t == self._t_last:
                _, _, _, c2, c3 = self._seg_list[-1]
                return 2.0 * c2 + 6.0 * c3 * float(self._seg_h[-1])
            loc = self._locate_scalar(t)
            if loc is None:
                return 0.0
            k, s = loc
            _, _, _, c2, c3 = self._seg_list[k]
            return 2.0 * c2 + 6.0 * c3 * s
        ta = np.asarray(t_s, dtype=float)
        if ta.size <= _SMALL_ARRAY:
            return self._small(self.second_derivative, ta)
        if self._n_seg == 0:
            out = np.zeros(ta.shape)
            return out if ta.ndim else float(out)
        ka, sa, inside = self._locate_array(ta)
        c = self._coef[ka]
        out = 2.0 * c[..., 2] + 6.0 * c[..., 3] * sa
        if not self._periodic:
            at_end = ta == self._t_last
            end_val = 2.0 * self._coef[-1, 2] + 6.0 * self._coef[-1, 3] * self._seg_h[-1]
            out = np.where(inside, out, np.where(at_end, end_val, 0.0))
        return out if ta.ndim else float(out)

    __call__ = evaluate

    # ---------------------------------------------------------------- drawing
    def segments(self) -> np.ndarray:
        """Per-segment polynomials ``(n_seg, 5)`` rows [t0, a, b, c, d]: v = a + bτ + cτ² + dτ³, τ = t − t0.

        For periodic curves the last row is the wrap segment (last knot → first knot + duration).
        """
        if not self._seg_list:
            return np.zeros((0, 5))
        return np.array(self._seg_list, dtype=float)

    def value_range(self) -> tuple[float, float]:
        """Exact (min, max) of the curve over its whole domain (cubic extrema per segment)."""
        if not self._knots:
            return (0.0, 0.0)
        lo = hi = self._knots[0].value
        for k in self._knots:
            lo, hi = min(lo, k.value), max(hi, k.value)
        for (t0, a, b, c, d), h in zip(self._seg_list, self._seg_h.tolist()):
            # v(τ) = a + bτ + cτ² + dτ³ on [0, h]; v'(τ) = b + 2cτ + 3dτ² = 0
            roots: list[float] = []
            if abs(d) > 1e-15:
                disc = 4 * c * c - 12 * d * b
                if disc >= 0:
                    sq = math.sqrt(disc)
                    roots = [(-2 * c + sq) / (6 * d), (-2 * c - sq) / (6 * d)]
            elif abs(c) > 1e-15:
                roots = [-b / (2 * c)]
            for tau in roots:
                if 0.0 < tau < h:
                    v = a + tau * (b + tau * (c + tau * d))
                    lo, hi = min(lo, v), max(hi, v)
        return (float(lo), float(hi))

    def bezier_control_points(self) -> np.ndarray:
        """Cubic Bézier control points of every segment, for drawing.

        Returns
        -------
        np.ndarray
            Shape ``(n_segments, 4, 2)``; rows are ``(t_s, value)`` of
            ``P0 = (t0, v0)``, ``P1 = (t0 + h/3, v0 + m0 h/3)``,
            ``P2 = (t1 - h/3, v1 - m1 h/3)``, ``P3 = (t1, v1)``.  For a
            periodic curve the last segment ends at ``t_first + duration_s``.
        """
        n = self._n_seg
        out = np.empty((n, 4, 2))
        if n == 0:
            return out
        t0 = self._seg_t0
        h = self._seg_h
        v0 = self._coef[:, 0]
        m0 = self._coef[:, 1]
        if self._periodic:
            idx1 = np.r_[np.arange(1, len(self._knots)), 0]
        else:
            idx1 = np.arange(1, len(self._knots))
        v1 = self._v[idx1]
        m1 = self._m_in[idx1]
        t1 = t0 + h
        out[:, 0, 0], out[:, 0, 1] = t0, v0
        out[:, 1, 0], out[:, 1, 1] = t0 + h / 3.0, v0 + m0 * h / 3.0
        out[:, 2, 0], out[:, 2, 1] = t1 - h / 3.0, v1 - m1 * h / 3.0
        out[:, 3, 0], out[:, 3, 1] = t1, v1
        return out

    # ---------------------------------------------------------------- editing
    def _with_knots(self, knots: Iterable[Knot]) -> "HermiteCurve":
        return HermiteCurve(knots, self._duration_s, self._periodic)

    def _check_index(self, index: int) -> int:
        n = len(self._knots)
        if not -n <= index < n:
            raise IndexError(f"knot index {index} out of range for a curve with {n} knots")
        return index % n

    def _time_bounds(self, i: int, gap: float) -> tuple[float, float]:
        """Allowed time range for knot ``i`` keeping order and ``gap``."""
        ks = self._knots
        n = len(ks)
        D = self._duration_s
        if self._periodic:
            if i > 0:
                lo = ks[i - 1].t_s + gap
            else:  # keep clear of the wrapped last knot
                lo = max(0.0, ks[-1].t_s - D + gap) if n > 1 else 0.0
            if i < n - 1:
                hi = ks[i + 1].t_s - gap
            else:  # stay inside [0, D) and clear of the wrapped first knot
                hi = min(ks[0].t_s + D, D) - gap if n > 1 else D - gap
        else:
            lo = ks[i - 1].t_s + gap if i > 0 else 0.0
            hi = ks[i + 1].t_s - gap if i < n - 1 else D
        if lo > hi:  # neighbours closer than 2 * gap: park in the middle
            lo = hi = 0.5 * (lo + hi)
        return lo, hi

    def with_knot_moved(
        self, index: int, t_s: float, value: float, min_gap_s: float = MIN_KNOT_GAP_S
    ) -> "HermiteCurve":
        """Move knot ``index`` to ``(t_s, value)``.

        The time is clamped between the neighbouring knots (keeping at least
        ``min_gap_s``), to ``[0, duration_s]`` for non-periodic curves and to
        ``[0, duration_s)`` for periodic ones.  Knots never reorder.
        """
        i = self._check_index(index)
        lo, hi = self._time_bounds(i, float(min_gap_s))
        t_new = min(max(float(t_s), lo), hi)
        if self._periodic and t_new >= self._duration_s:
            t_new = math.nextafter(self._duration_s, 0.0)
        ks = list(self._knots)
        ks[i] = replace(ks[i], t_s=t_new, value=float(value))
        return self._with_knots(ks)

    def with_knot_added(self, t_s: float) -> "HermiteCurve":
        """Insert an AUTO_CLAMPED knot on the curve at ``t_s``.

        The new value is the current curve value at ``t_s`` (periodic curves
        wrap ``t_s`` into ``[0, duration_s)``).  Note that auto tangents of
        the new knot and its neighbours are recomputed, so the shape can
        change slightly (as in Blender).  Raises ``ValueError`` when a knot
        already exists at that time.
        """
        t = float(t_s)
        if self._periodic:
            t = t % self._duration_s
            if t >= self._duration_s:
                t = 0.0
        elif not 0.0 <= t <= self._duration_s:
            raise ValueError(f"t_s={t!r} outside [0, {self._duration_s!r}]")
        for j, k in enumerate(self._knots):
            if k.t_s == t:
                raise ValueError(f"knot {j} already exists at t_s={t!r}")
        new = Knot(t, float(self.evaluate(t)), mode=TangentMode.AUTO_CLAMPED)
        return self._with_knots([*self._knots, new])

    def with_knot_removed(self, index: int) -> "HermiteCurve":
        """Curve without knot ``index``."""
        i = self._check_index(index)
        return self._with_knots(k for j, k in enumerate(self._knots) if j != i)

    def with_tangent(
        self,
        index: int,
        mode: TangentMode | str,
        in_slope: float | None = None,
        out_slope: float | None = None,
    ) -> "HermiteCurve":
        """Set the tangent mode (and optionally slopes) of knot ``index``.

        For ALIGNED the single slope is ``in_slope`` or ``out_slope`` (they
        must agree if both are given); for FREE each missing slope keeps its
        current resolved value.  Slopes are ignored for the automatic modes.
        """
        i = self._check_index(index)
        mode = _as_mode(mode)
        k = self._knots[i]
        a, b = k.in_slope, k.out_slope
        if mode is TangentMode.ALIGNED:
            if in_slope is not None and out_slope is not None and float(in_slope) != float(out_slope):
                raise ValueError(
                    f"knot {i}: ALIGNED needs in_slope == out_slope, got {in_slope!r} and {out_slope!r}"
                )
            if in_slope is not None:
                a = b = float(in_slope)
            elif out_slope is not None:
                a = b = float(out_slope)
            elif a != b:
                a = b = 0.5 * (a + b)
        elif mode is TangentMode.FREE:
            a = float(in_slope) if in_slope is not None else a
            b = float(out_slope) if out_slope is not None else b
        ks = list(self._knots)
        ks[i] = replace(k, in_slope=a, out_slope=b, mode=mode)
        return self._with_knots(ks)

    def rescaled(self, new_duration_s: float) -> "HermiteCurve":
        """Curve on a resized interval (paper Sec. 6.1).

        Knot times scale by ``new / old`` and slopes by ``old / new``, so the
        shape in normalised time ``t / duration_s`` is unchanged.
        """
        new = float(new_duration_s)
        if not (math.isfinite(new) and new > 0.0):
            raise ValueError(f"new_duration_s must be a positive finite number, got {new!r}")
        old = self._duration_s
        ts = new / old
        ms = old / new
        ks = []
        for k in self._knots:
            t = k.t_s * ts
            if k.t_s == old:
                t = new
            if self._periodic and t >= new:
                t = math.nextafter(new, 0.0)
            elif t > new:
                t = new
            ks.append(replace(k, t_s=t, in_slope=k.in_slope * ms, out_slope=k.out_slope * ms))
        return HermiteCurve(ks, new, self._periodic)

    # ---------------------------------------------------------- serialisation
    def to_dict(self) -> dict[str, list[list[Any]]]:
        """JSON-friendly ``{"knots": [[t_s, value, in_slope, out_slope, mode], ...]}``.

        Slopes are the resolved ones; duration and periodicity are not stored
        (they belong to the interval the curve lives on).
        """
        return {
            "knots": [[k.t_s, k.value, k.in_slope, k.out_slope, k.mode.value] for k in self._knots]
        }

    @classmethod
    def from_dict(
        cls, d: Mapping[str, Any], duration_s: float, periodic: bool = False
    ) -> "HermiteCurve":
        """Inverse of :meth:`to_dict`.

        Rows may also be abbreviated for hand-written files: ``[t_s, value]``
        (AUTO_CLAMPED) or ``[t_s, value, mode]``.
        """
        if "knots" not in d:
            raise ValueError("curve dict needs a 'knots' list")
        ks = []
        for i, row in enumerate(d["knots"]):
            row = list(row)
            if len(row) == 2:
                ks.append(Knot(float(row[0]), float(row[1])))
            elif len(row) == 3:
                ks.append(Knot(float(row[0]), float(row[1]), mode=_as_mode(row[2])))
            elif len(row) == 5:
                ks.append(
                    Knot(float(row[0]), float(row[1]), float(row[2]), float(row[3]), _as_mode(row[4]))
                )
            else:
                raise ValueError(
                    f"knot {i}: expected [t_s, value, in_slope, out_slope, mode], got {row!r}"
                )
        return cls(ks, duration_s, periodic)
