"""Gait phase map Ω: gait phase φ ∈ [0, 1] → gait time t ∈ [0, T_S] (paper Sec. 5.1).

The map interpolates the five waypoints

    (0, t_LLO = 0), (PHI_LTD, t_LTD), (PHI_RLO, t_RLO), (PHI_RTD, t_RTD), (1, T_S)

with a monotone cubic Hermite spline (PCHIP / Fritsch-Butland weighted
harmonic-mean slopes), so Ω is strictly increasing and C1 and contact events
map exactly onto contact events.  Slopes at φ = 0 and φ = 1 are computed
cyclically (the neighbour of the last waypoint is the first one of the next
cycle), so the periodic extension ``Ω(φ + k) = Ω(φ) + k T_S`` is C1 across
cycle boundaries; this keeps phase-space blended periodic curves C1 across
the loop.

Two cycles A and B are related by ``t_B = Ω_B(Ω_A⁻¹(t_A))``
(:func:`equivalent_time`).
"""

from __future__ import annotations

import math
from bisect import bisect_right

import numpy as np

__all__ = [
    "PHI_LLO",
    "PHI_LTD",
    "PHI_RLO",
    "PHI_RTD",
    "PHASE_WAYPOINTS",
    "PhaseMap",
    "equivalent_time",
]

PHI_LLO: float = 0.0
PHI_LTD: float = 0.1
PHI_RLO: float = 0.5
PHI_RTD: float = 0.6
#: Phase of each waypoint: LLO, LTD, RLO, RTD, next LLO.
PHASE_WAYPOINTS: tuple[float, ...] = (PHI_LLO, PHI_LTD, PHI_RLO, PHI_RTD, 1.0)

_MAX_ITER = 60
_SMALL_ARRAY = 48


def _pchip_slope(d_prev: float, d_next: float, h_prev: float, h_next: float) -> float:
    """Fritsch-Butland weighted harmonic mean of two positive secants."""
    w1 = 2.0 * h_next + h_prev
    w2 = h_next + 2.0 * h_prev
    return (w1 + w2) / (w1 / d_prev + w2 / d_next)


#: Phase steps between the waypoints, their squares and :func:`_pchip_slope`'s weights (w1 + w2, w1, w2) of the
#: slope at each waypoint 0..3 (its neighbouring steps; cyclic at waypoint 0): constants of every phase map.
_STEPS: tuple[float, ...] = tuple(PHASE_WAYPOINTS[i + 1] - PHASE_WAYPOINTS[i] for i in range(4))
_STEP_SQUARES: tuple[float, ...] = tuple(h * h for h in _STEPS)


def _slope_weights(h_prev: float, h_next: float) -> tuple[float, float, float]:
    w1 = 2.0 * h_next + h_prev
    w2 = h_next + 2.0 * h_prev
    return w1 + w2, w1, w2


_SLOPE_WEIGHTS: tuple[tuple[float, float, float], ...] = tuple(_slope_weights(_STEPS[i - 1], _STEPS[i]) for i in range(4))


class PhaseMap:
    """Monotone cubic phase map of one two-step walk cycle.

    Parameters
    ----------
    t_ltd_s, t_rlo_s, t_rtd_s : float
        Left touchdown, right liftoff, right touchdown times [s], relative to
        left liftoff (``t_LLO = 0``).
    cycle_s : float
        Cycle period T_S [s].  Requires ``0 < t_ltd_s < t_rlo_s < t_rtd_s < cycle_s``.

    Notes
    -----
    ``time_at`` accepts any phase and extends Ω periodically
    (``Ω(φ + k) = Ω(φ) + k T_S``); ``phase_at`` wraps time into one cycle and
    returns φ ∈ [0, 1).  Use :meth:`cycle_index` / :meth:`unwrapped_phase`
    for the cycle count.
    """

    __slots__ = ("_events", "_cycle_s", "_phi", "_times", "_slopes", "_seg", "_t_list",
                 "_arrays")

    def __init__(self, t_ltd_s: float, t_rlo_s: float, t_rtd_s: float, cycle_s: float) -> None:
        ev = (float(t_ltd_s), float(t_rlo_s), float(t_rtd_s), float(cycle_s))
        if not (math.isfinite(ev[0]) and math.isfinite(ev[1]) and math.isfinite(ev[2]) and math.isfinite(ev[3])):
            raise ValueError(f"event times must be finite, got {ev!r}")
        if not (0.0 < ev[0] < ev[1] < ev[2] < ev[3]):
            raise ValueError(
                "event times must satisfy 0 < t_ltd_s < t_rlo_s < t_rtd_s < cycle_s, got "
                f"t_ltd_s={ev[0]!r}, t_rlo_s={ev[1]!r}, t_rtd_s={ev[2]!r}, cycle_s={ev[3]!r}"
            )
        self._events = ev
        self._cycle_s = ev[3]
        phi = list(PHASE_WAYPOINTS)
        times = [0.0, ev[0], ev[1], ev[2], ev[3]]
        hs = _STEPS
        ds = [(times[i + 1] - times[i]) / hs[i] for i in range(4)]
        # _pchip_slope(ds[i − 1], ds[i], hs[i − 1], hs[i]) with its weights precomputed (the phase steps are
        # constants); ds[−1] is ds[3]: the cyclic ends
        slopes = [w_sum / (w1 / ds[i - 1] + w2 / ds[i]) for i, (w_sum, w1, w2) in enumerate(_SLOPE_WEIGHTS)]
        slopes.append(slopes[0])
        self._phi = phi
        self._times = times
        self._slopes = slopes
        seg = []
        for i in range(4):
            h, d, m0, m1 = hs[i], ds[i], slopes[i], slopes[i + 1]
            c2 = (3.0 * d - 2.0 * m0 - m1) / h
            c3 = (m0 + m1 - 2.0 * d) / _STEP_SQUARES[i]
            seg.append((phi[i], times[i], m0, c2, c3, h, times[i + 1]))
        self._seg = seg
        self._t_list = times[:4]
        self._arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None  # built on first array use

    def _array_tables(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(coefficients (4, 4), waypoint phases (4,), times (5,), phase steps (4,)) for the array paths; built
        on first use (a blend's phase map is rebuilt every planner tick and evaluated on floats only)."""
        if self._arrays is None:
            seg = self._seg
            self._arrays = (np.array([[s[1], s[2], s[3], s[4]] for s in seg]), np.array(self._phi[:4]),
                            np.array(self._times), np.array([s[5] for s in seg]))
        return self._arrays

    # ------------------------------------------------------------- properties
    @property
    def t_ltd_s(self) -> float:
        """Left touchdown time [s]."""
        return self._events[0]

    @property
    def t_rlo_s(self) -> float:
        """Right liftoff time [s]."""
        return self._events[1]

    @property
    def t_rtd_s(self) -> float:
        """Right touchdown time [s]."""
        return self._events[2]

    @property
    def cycle_s(self) -> float:
        """Cycle period T_S [s]."""
        return self._cycle_s

    @property
    def event_times_s(self) -> tuple[float, float, float, float, float]:
        """``(t_LLO=0, t_LTD, t_RLO, t_RTD, T_S)`` [s]."""
        return (0.0, *self._events)

    def __repr__(self) -> str:
        a, b, c, d = self._events
        return f"PhaseMap(t_ltd_s={a!r}, t_rlo_s={b!r}, t_rtd_s={c!r}, cycle_s={d!r})"

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, PhaseMap):
            return NotImplemented
        return self._events == other._events

    def __hash__(self) -> int:
        return hash(self._events)

    # ------------------------------------------------------------ forward map
    def time_at(self, phi: float | np.ndarray) -> float | np.ndarray:
        """Gait time Ω(φ) [s]; periodic extension ``Ω(φ + k) = Ω(φ) + k T_S``."""
        if isinstance(phi, (float, int)):
            p = float(phi)
            k = 0.0
            if not 0.0 <= p < 1.0:
                k = math.floor(p)
                p -= k
                if p >= 1.0:  # rounding of tiny negative inputs
                    p, k = 0.0, k + 1.0
            i = bisect_right(self._phi, p) - 1
            p0, c0, c1, c2, c3, _, _ = self._seg[i]
            s = p - p0
            t = c0 + s * (c1 + s * (c2 + s * c3))
            return t + k * self._cycle_s if k else t
        pa = np.asarray(phi, dtype=float)
        ka = np.floor(pa)
        ra = pa - ka
        wrap = ra >= 1.0
        ra = np.where(wrap, 0.0, ra)
        ka = np.where(wrap, ka + 1.0, ka)
        coef, phi_arr, _, _ = self._array_tables()
        ia = np.clip(np.searchsorted(phi_arr, ra, side="right") - 1, 0, 3)
        sa = ra - phi_arr[ia]
        c = coef[ia]
        ta = c[..., 0] + sa * (c[..., 1] + sa * (c[..., 2] + sa * c[..., 3])) + ka * self._cycle_s
        return ta if pa.ndim else float(ta)

    def dtime_dphase(self, phi: float | np.ndarray) -> float | np.ndarray:
        """dΩ/dφ [s per unit phase] (> 0 everywhere, periodic in φ)."""
        if isinstance(phi, (float, int)):
            p = float(phi) % 1.0
            if p >= 1.0:
                p = 0.0
            i = bisect_right(self._phi, p) - 1
            p0, _, c1, c2, c3, _, _ = self._seg[i]
            s = p - p0
            return c1 + s * (2.0 * c2 + 3.0 * s * c3)
        pa = np.mod(np.asarray(phi, dtype=float), 1.0)
        pa = np.where(pa >= 1.0, 0.0, pa)
        coef, phi_arr, _, _ = self._array_tables()
        ia = np.clip(np.searchsorted(phi_arr, pa, side="right") - 1, 0, 3)
        sa = pa - phi_arr[ia]
        c = coef[ia]
        out = c[..., 1] + sa * (2.0 * c[..., 2] + 3.0 * sa * c[..., 3])
        return out if np.ndim(out) else float(out)

    # ------------------------------------------------------------ inverse map
    def _wrap_time(self, t: float) -> tuple[float, int]:
        T = self._cycle_s
        if 0.0 <= t < T:
            return t, 0
        k = math.floor(t / T)
        r = t - k * T
        if r >= T:
            r -= T
            k += 1
        elif r < 0.0:
            r += T
            k -= 1
        if r >= T or r < 0.0:  # pathological rounding
            r = 0.0
        return r, int(k)

    def _solve_scalar(self, r: float) -> float:
        """Phase in [0, 1) of time r in [0, T_S) (safeguarded Newton)."""
        i = bisect_right(self._t_list, r) - 1
        p0, c0, c1, c2, c3, h, t1 = self._seg[i]
        y = r - c0
        if y == 0.0:
            return p0
        lo, hi = 0.0, h
        s = h * y / (t1 - c0)  # secant initial guess
        for _ in range(_MAX_ITER):
            f = s * (c1 + s * (c2 + s * c3)) - y
            if f > 0.0:
                hi = s
            elif f < 0.0:
                lo = s
            else:
                break
            df = c1 + s * (2.0 * c2 + 3.0 * s * c3)
            s_new = s - f / df if df > 0.0 else -1.0
            if not lo < s_new < hi:
                s_new = 0.5 * (lo + hi)
            if abs(s_new - s) <= 1e-15 * h:
                s = s_new
                break
            s = s_new
        phi = p0 + s
        return phi if phi < 1.0 else math.nextafter(1.0, 0.0)

    def _solve_array(self, r: np.ndarray) -> np.ndarray:
        coef, phi_arr, t_arr, h_arr = self._array_tables()
        i = np.clip(np.searchsorted(t_arr[:4], r, side="right") - 1, 0, 3)
        c = coef[i]
        c0, c1, c2, c3 = c[..., 0], c[..., 1], c[..., 2], c[..., 3]
        h = h_arr[i]
        y = r - c0
        lo = np.zeros_like(r)
        hi = h.copy()
        s = h * y / (t_arr[i + 1] - c0)
        for _ in range(_MAX_ITER):
            f = s * (c1 + s * (c2 + s * c3)) - y
            hi = np.where(f > 0.0, s, hi)
            lo = np.where(f < 0.0, s, lo)
            df = c1 + s * (2.0 * c2 + 3.0 * s * c3)
            with np.errstate(divide="ignore", invalid="ignore"):
                s_new = np.where(df > 0.0, s - f / df, -1.0)
            bad = ~((s_new > lo) & (s_new < hi))
            s_new = np.where(bad, 0.5 * (lo + hi), s_new)
            s_new = np.where(f == 0.0, s, s_new)
            done = np.abs(s_new - s) <= 1e-15 * h
            s = s_new
            if np.all(done):
                break
        phi = phi_arr[i] + s
        return np.minimum(phi, np.nextafter(1.0, 0.0))

    def phase_at(self, t_s: float | np.ndarray) -> float | np.ndarray:
        """Gait phase Ω⁻¹(t) ∈ [0, 1); time outside [0, T_S) wraps periodically."""
        if isinstance(t_s, (float, int)):
            r, _ = self._wrap_time(float(t_s))
            return self._solve_scalar(r)
        t = np.asarray(t_s, dtype=float)
        if t.size <= _SMALL_ARRAY:  # numpy overhead dominates: scalar loop is faster
            flat = [self._solve_scalar(self._wrap_time(x)[0]) for x in t.ravel().tolist()]
            out = np.array(flat, dtype=float).reshape(t.shape)
        else:
            out = self._solve_array(self._wrap_array(t)[0])
        return out if t.ndim else float(out)

    def _wrap_array(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        T = self._cycle_s
        k = np.floor(t / T)
        r = t - k * T
        over = r >= T
        r = np.where(over, r - T, r)
        k = np.where(over, k + 1, k)
        under = r < 0.0
        r = np.where(under, r + T, r)
        k = np.where(under, k - 1, k)
        r = np.where((r >= T) | (r < 0.0), 0.0, r)
        return r, k.astype(np.int64)

    def cycle_index(self, t_s: float | np.ndarray) -> int | np.ndarray:
        """Integer cycle count k such that ``t_s - k T_S ∈ [0, T_S)``."""
        if isinstance(t_s, (float, int)):
            return self._wrap_time(float(t_s))[1]
        t = np.asarray(t_s, dtype=float)
        k = self._wrap_array(t)[1]
        return k if t.ndim else int(k)

    def unwrapped_phase(self, t_s: float | np.ndarray) -> float | np.ndarray:
        """Continuous, strictly increasing phase ``cycle_index(t) + phase_at(t)``."""
        if isinstance(t_s, (float, int)):
            r, k = self._wrap_time(float(t_s))
            return k + self._solve_scalar(r)
        t = np.asarray(t_s, dtype=float)
        if t.size <= _SMALL_ARRAY:
            flat = [self.unwrapped_phase(x) for x in t.ravel().tolist()]
            out = np.array(flat, dtype=float).reshape(t.shape)
        else:
            ra, ka = self._wrap_array(t)
            out = ka + self._solve_array(ra)
        return out if t.ndim else float(out)

    def dphase_dtime(self, t_s: float | np.ndarray) -> float | np.ndarray:
        """Phase rate dΩ⁻¹/dt [1/s] at time ``t_s`` (periodic)."""
        phi = self.phase_at(t_s)
        return 1.0 / self.dtime_dphase(phi)


def equivalent_time(
    t_a: float | np.ndarray, map_a: PhaseMap, map_b: PhaseMap, keep_cycle: bool = False
) -> float | np.ndarray:
    """Equivalent gait time in cycle B of time ``t_a`` of cycle A.

    ``t_B = Ω_B(Ω_A⁻¹(t_A))`` (paper Sec. 5.1): contact events of A map to the
    same events of B.  With ``keep_cycle=False`` (paper definition) the result
    lies in ``[0, T_B)``; with ``keep_cycle=True`` the cycle count of ``t_a`` is
    kept (``t_a + k T_A`` → ``t_b + k T_B``), giving a continuous monotone map.
    """
    if keep_cycle:
        return map_b.time_at(map_a.unwrapped_phase(t_a))
    return map_b.time_at(map_a.phase_at(t_a))
