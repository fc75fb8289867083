"""Centre-of-mass model predictive controller (paper Sec. 7.1 and Appendix "MPC").

Plans the horizontal CoM and the Centre of Pressure (CoP) over a preview window
(default T = 2 s) given the upcoming convex support polygons and their timing.

Model (Eq. 11 with constant CoM height ``z`` and constant angular momentum)::

    x'' = omega^2 (x - p(t)),   omega^2 = g / z

Decision variables (Eqs. 12-13): CoP waypoints ``z_0 .. z_N`` (``N = 2K``: one at
the midpoint and one at the end of each of the ``K`` support intervals, the CoP
being linear in between) and the final CoM state ``xi_T = [x_T, v_T]``.
``z_0`` equals the current CoP, midpoints lie in their polygon ``C_k``, end points in
``C_k ∩ C_k+1`` (both polygons' half-planes stacked; the last one in ``C_K``).

Cost (Eq. 14): ``W_T |x_T + v_T / omega - c_T|^2 + sum_n W_c |z_n - c_n|^2 +
sum_n W_v |(z_n+1 - z_n) / dt_n|^2`` with ``c_n`` the centroid of waypoint ``n``'s
region (clipped intersection polygon for end points) and ``c_T`` the last polygon's.

Discretisation
--------------
The paper integrates Eq. 11 backwards with a 0.02 s step.  Here the CoP is exactly
piecewise linear, so the LIP is integrated *exactly* in closed form: with the
divergent / convergent components ``zeta = x + v/omega`` and ``eta = x - v/omega``
(``zeta' = omega (zeta - p)``, ``eta' = -omega (eta - p)``), a segment of duration
``h`` with CoP going linearly from ``p_j`` to ``p_j+1`` gives, with ``E = exp(-omega h)``
and ``r = (1 - E) / (omega h)``::

    zeta_j   = E zeta_j+1 + (1 - r) p_j + (r - E) p_j+1
    eta_j+1  = E eta_j    + (r - E) p_j + (1 - r) p_j+1

Chaining these gives the initial-state equality constraints of Eq. 14 (``A_p, A_v,
b_p, b_v``; the ``b`` terms vanish since tau = 0) pre-multiplied by the invertible
modal transform ``[1, 1/omega; 1, -1/omega]`` -- the same feasible set.  The DCM
row is scaled by ``exp(-omega T / 2)`` and the QP is posed in a frame centred on the
current capture point, which keeps its coefficients and residuals well scaled.
The returned trajectory is re-propagated from the given initial state with the
optimised CoP, so ``com_at`` is exactly consistent with ``cop_at`` and the initial
state; ``final_com_*`` is that propagated final state.

Long supports (e.g. standing) are split into equal pieces of at most
``max_interval_s`` (anchored at the support's start, same polygon), each with its
two waypoints.  Without this a 2 s stance is steered by a single CoP ramp per second,
which cannot stabilise the capture point in closed loop; ``max_interval_s=inf``
gives the paper's literal two waypoints per support.

QP layout (fixed sparsity)
--------------------------
Variables and rows are padded to ``max_intervals`` intervals and ``max_halfplanes``
half-planes per polygon (end waypoints stack both polygons: ``2 * max_halfplanes``
rows).  Unused rows keep their structural non-zeros with value 0 and bounds
(-inf, +inf); unused waypoints are decoupled and pinned to 0 by a unit diagonal
cost.  Consecutive calls only ``update`` the numeric values (``q, l, u, Px, Ax``) and
warm start from the previous primal/dual solution shifted by the elapsed intervals;
``setup`` is re-run only when the padded shape must grow (``setup_count`` counts it).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "GRAVITY_MPS2",
    "ComMpc",
    "ComMpcSolution",
    "ComMpcWeights",
    "SupportInterval",
    "benchmark_solve",
    "clip_convex_polygons",
    "convex_hull",
    "example_walking_supports",
    "polygon_area",
    "polygon_centroid",
    "polygon_halfplanes",
    "propagate_lip",
]

GRAVITY_MPS2 = 9.81
#: CoM height used only to keep fallback outputs finite when the given height is invalid.
FALLBACK_COM_HEIGHT_M = 0.8
#: Polygons with a smaller (convex hull) area are considered degenerate.
MIN_POLYGON_AREA_M2 = 1e-6
#: Tolerance used to accept an OSQP solution's polygon constraints.
CONSTRAINT_TOL_M = 1e-4

FloatArray = NDArray[np.float64]


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class SupportInterval:
    """A support phase: ``polygon`` (M, 2) convex, CCW, world frame [m], over [t_start_s, t_end_s]."""

    t_start_s: float
    t_end_s: float
    polygon: np.ndarray


@dataclass(frozen=True)
class ComMpcWeights:
    """Objective weights of Eq. 14 (diagonal, same for x and y).

    Attributes
    ----------
    final_capture_point : float
        ``W_T`` on ``(x_T + v_T / omega) - c_T`` [1/m^2].
    cop_centroid : float
        ``W_c`` on each CoP waypoint minus the centroid of its constraint region [1/m^2].
    cop_velocity : float
        ``W_v`` on the CoP velocity between consecutive waypoints [s^2/m^2].
    """

    final_capture_point: float = 100.0
    cop_centroid: float = 1.0
    cop_velocity: float = 0.01


@dataclass(frozen=True)
class ComMpcSolution:
    """Optimised CoP waypoints and the exactly integrated CoM trajectory.

    ``status`` is ``"solved"`` for a clean optimum; ``"solved_inaccurate"`` or
    ``"solved_empty_intersection"`` for a usable optimum with a caveat; otherwise it
    starts with ``"solver_failed"`` or ``"invalid_input"`` followed by the fallback
    used: ``"_previous_solution"`` (last good plan, which is indexed by absolute time),
    ``"_centroid_fallback"`` (CoP from the current CoP to the region centroids, CoM
    integrated) or ``"_hold_fallback"`` (CoP held).  Arrays are always finite.
    Times outside the waypoint range hold the end CoP (the CoM follows the LIP).
    ``region_centroids_xy_m`` holds the centroid target of each waypoint's region and
    ``qp_final_state`` the QP's decision variable ``xi_T = [x_T, y_T, vx_T, vy_T]``
    (equal to the propagated final state up to the solver tolerance; for fallbacks it
    is the propagated final state).
    """

    waypoint_times_s: FloatArray  # (N+1,)
    waypoints_xy_m: FloatArray  # (N+1, 2) CoP waypoints
    waypoint_com_xy_m: FloatArray  # (N+1, 2) CoM position at the waypoint times
    waypoint_com_vel_xy_mps: FloatArray  # (N+1, 2) CoM velocity at the waypoint times
    com_height_m: float
    status: str
    solve_time_s: float
    message: str = ""
    osqp_iterations: int = 0
    osqp_time_s: float = 0.0
    region_centroids_xy_m: FloatArray = field(default_factory=lambda: np.zeros((0, 2)), repr=False)
    qp_final_state: FloatArray = field(default_factory=lambda: np.full(4, np.nan), repr=False)

    @property
    def ok(self) -> bool:
        """True when the QP optimum (possibly with a caveat) is returned."""
        return self.status.startswith("solved")

    @property
    def omega_rps(self) -> float:
        """LIP natural frequency sqrt(g / z) [1/s]."""
        return math.sqrt(GRAVITY_MPS2 / self.com_height_m)

    @property
    def final_com_xy_m(self) -> FloatArray:
        return self.waypoint_com_xy_m[-1].copy()

    @property
    def final_com_vel_xy_mps(self) -> FloatArray:
        return self.waypoint_com_vel_xy_mps[-1].copy()

    @property
    def final_capture_point_xy_m(self) -> FloatArray:
        """Capture point ``x_T + v_T / omega`` at the end of the preview window [m]."""
        return self.waypoint_com_xy_m[-1] + self.waypoint_com_vel_xy_mps[-1] / self.omega_rps

    @property
    def t_start_s(self) -> float:
        return float(self.waypoint_times_s[0])

    @property
    def t_end_s(self) -> float:
        return float(self.waypoint_times_s[-1])

    def cop_at(self, t_s: ArrayLike) -> FloatArray:
        """CoP [m] at time(s) ``t_s``: shape (2,) for a scalar, (T, 2) for an array."""
        t = np.asarray(t_s, dtype=float)
        tt = np.atleast_1d(t)
        times, wps = self.waypoint_times_s, self.waypoints_xy_m
        out = np.stack([np.interp(tt, times, wps[:, 0]), np.interp(tt, times, wps[:, 1])], axis=-1)
        return out[0] if t.ndim == 0 else out

    def com_at(self, t_s: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """CoM position [m], velocity [m/s], acceleration [m/s^2] at ``t_s`` (exact LIP solution)."""
        t = np.asarray(t_s, dtype=float)
        tt = np.atleast_1d(t)
        times, wps = self.waypoint_times_s, self.waypoints_xy_m
        n_seg = len(times) - 1
        omega = self.omega_rps
        j = np.clip(np.searchsorted(times, tt, side="right") - 1, 0, n_seg - 1)
        h = np.maximum(times[1:] - times[:-1], 1e-12)
        slope = (wps[1:] - wps[:-1]) / h[:, None]
        anchor = j.copy()
        pdot = slope[j]
        after = tt > times[-1]
        before = tt < times[0]
        anchor[after] = n_seg
        pdot[after | before] = 0.0
        s = (tt - times[anchor])[:, None]
        p = wps[anchor] + pdot * s
        e0 = self.waypoint_com_xy_m[anchor] - wps[anchor]
        de0 = self.waypoint_com_vel_xy_mps[anchor] - pdot
        ch, sh = np.cosh(omega * s), np.sinh(omega * s)
        err = e0 * ch + de0 * sh / omega
        pos = p + err
        vel = pdot + e0 * omega * sh + de0 * ch
        acc = omega * omega * err
        if t.ndim == 0:
            return pos[0], vel[0], acc[0]
        return pos, vel, acc

    def com_path(self, dt_s: float = 0.02) -> tuple[FloatArray, FloatArray]:
        """Sample the planned CoM for drawing: ``(times_s (T,), com_xy_m (T, 2))``."""
        dt = max(float(dt_s), 1e-4) if math.isfinite(dt_s) else 0.02
        n = max(int(math.ceil((self.t_end_s - self.t_start_s) / dt)), 1)
        times = np.linspace(self.t_start_s, self.t_end_s, n + 1)
        return times, self.com_at(times)[0]


# ---------------------------------------------------------------- polygon helpers


def polygon_area(polygon: ArrayLike) -> float:
    """Signed area [m^2] of a polygon (positive when counter-clockwise)."""
    v = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(v) < 3:
        return 0.0
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def polygon_centroid(polygon: ArrayLike) -> FloatArray:
    """Area centroid [m] of a simple polygon; vertex mean for degenerate (zero-area) input, NaN if empty."""
    v = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(v) == 0:
        return np.full(2, np.nan)
    if len(v) < 3:
        return v.mean(axis=0)
    origin = v.mean(axis=0)
    w = v - origin
    x, y = w[:, 0], w[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area2 = float(cross.sum())
    if abs(area2) < 1e-14:
        return origin
    cx = float(np.dot(x + xn, cross)) / (3.0 * area2)
    cy = float(np.dot(y + yn, cross)) / (3.0 * area2)
    return origin + np.array([cx, cy])


def convex_hull(points: ArrayLike) -> FloatArray:
    """Counter-clockwise convex hull (Andrew's monotone chain) without collinear points."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    pts = np.unique(pts, axis=0)  # lexicographically sorted
    if len(pts) < 3:
        return pts

    def cross(o: FloatArray, a: FloatArray, b: FloatArray) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    lower: list[FloatArray] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-15:
            lower.pop()
        lower.append(p)
    upper: list[FloatArray] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-15:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def polygon_halfplanes(polygon: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Half-planes ``A x <= b`` (unit outward normals ``A`` (H, 2), offsets ``b`` (H,) [m]).

    ``polygon`` must be convex; it may be given in either orientation.  Edges shorter
    than 1e-9 m are skipped.
    """
    v = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(v) < 3:
        return np.zeros((0, 2)), np.zeros(0)
    if polygon_area(v) < 0.0:
        v = v[::-1]
    edges = np.roll(v, -1, axis=0) - v
    length = np.hypot(edges[:, 0], edges[:, 1])
    keep = length > 1e-9
    normals = np.stack([edges[keep, 1], -edges[keep, 0]], axis=1) / length[keep, None]
    offsets = np.einsum("ij,ij->i", normals, v[keep])
    return normals, offsets


def clip_convex_polygons(subject: ArrayLike, clip: ArrayLike, tol_m: float = 1e-9) -> FloatArray:
    """Intersection of two convex polygons (Sutherland-Hodgman); (0, 2) if empty.

    Touching polygons yield a degenerate (zero-area) intersection, which is returned.
    """
    out = np.asarray(subject, dtype=float).reshape(-1, 2)
    if polygon_area(out) < 0.0:
        out = out[::-1]
    normals, offsets = polygon_halfplanes(clip)
    if len(normals) == 0:
        return np.zeros((0, 2))
    for normal, offset in zip(normals, offsets):
        if len(out) == 0:
            break
        d = out @ normal - offset
        inside = d <= tol_m
        if inside.all():
            continue
        nxt_pts = np.roll(out, -1, axis=0)
        nxt_d = np.roll(d, -1)
        nxt_in = np.roll(inside, -1)
        new_pts: list[FloatArray] = []
        for i in range(len(out)):
            if inside[i]:
                new_pts.append(out[i])
            if inside[i] != nxt_in[i]:
                lam = d[i] / (d[i] - nxt_d[i])
                new_pts.append(out[i] + lam * (nxt_pts[i] - out[i]))
        out = np.array(new_pts).reshape(-1, 2)
    return out


@dataclass(frozen=True)
class _Region:
    """Cached geometry of one support polygon."""

    valid: bool
    normals: FloatArray  # (H, 2)
    offsets: FloatArray  # (H,)
    centroid: FloatArray  # (2,)
    hull: FloatArray  # (M, 2)
    serial: int  # unique id, used as cache key


_REGION_SERIAL = itertools.count()


def _make_region(polygon: np.ndarray) -> _Region:
    try:
        v = np.asarray(polygon, dtype=float)
    except (TypeError, ValueError):
        v = np.zeros((0, 2))
    serial = next(_REGION_SERIAL)
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3 or not np.isfinite(v).all():
        return _Region(False, np.zeros((0, 2)), np.zeros(0), np.zeros(2), np.zeros((0, 2)), serial)
    hull = convex_hull(v)
    if len(hull) < 3 or polygon_area(hull) < MIN_POLYGON_AREA_M2:
        return _Region(False, np.zeros((0, 2)), np.zeros(0), np.zeros(2), hull, serial)
    normals, offsets = polygon_halfplanes(hull)
    return _Region(True, normals, offsets, polygon_centroid(hull), hull, serial)


# ------------------------------------------------------------------ LIP dynamics


@dataclass(frozen=True)
class _Segments:
    """Exact LIP coefficients of the segments between waypoint times ``t_0 .. t_N``.

    Per segment ``j`` (duration ``h``): ``E = exp(-omega h)``, ``r = (1 - E) / (omega h)``,
    ``a = 1 - r``, ``b = r - E``; ``grow[n] = exp(omega (t_n - t_0))``.
    """

    omega: float
    h: FloatArray  # (N,)
    a: FloatArray  # (N,)
    b: FloatArray  # (N,)
    grow: FloatArray  # (N+1,)

    @staticmethod
    def build(times_s: FloatArray, omega: float) -> _Segments:
        h = times_s[1:] - times_s[:-1]
        wh = omega * h
        one_minus_e = -np.expm1(-wh)
        r = np.where(wh > 1e-9, one_minus_e / np.maximum(wh, 1e-9), 1.0 - 0.5 * wh)  # -> 1 as h -> 0
        grow = np.exp(omega * (times_s - times_s[0]))
        return _Segments(omega, h, 1.0 - r, r - (1.0 - one_minus_e), grow)

    def propagate(
        self, cop_xy_m: FloatArray, com_xy_m: FloatArray, com_vel_xy_mps: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """CoM position and velocity at every waypoint time (closed form, see module docstring)."""
        w = self.omega
        a, b, grow = self.a[:, None], self.b[:, None], self.grow[:, None]
        p0, p1 = cop_xy_m[:-1], cop_xy_m[1:]
        # zeta_n = e^{w t_n} (zeta_0 - sum_{j<n} e^{-w t_j} (a_j p_j + b_j p_j+1))
        zeta = np.zeros_like(cop_xy_m)
        np.cumsum((a * p0 + b * p1) / grow[:-1], axis=0, out=zeta[1:])
        zeta = grow * ((com_xy_m + com_vel_xy_mps / w) - zeta)
        # eta_n = e^{-w t_n} (eta_0 + sum_{j<n} e^{w t_j+1} (b_j p_j + a_j p_j+1))
        eta = np.zeros_like(cop_xy_m)
        np.cumsum((b * p0 + a * p1) * grow[1:], axis=0, out=eta[1:])
        eta = ((com_xy_m - com_vel_xy_mps / w) + eta) / grow
        return 0.5 * (zeta + eta), (0.5 * w) * (zeta - eta)


def propagate_lip(
    times_s: ArrayLike, cop_xy_m: ArrayLike, com_xy_m: ArrayLike, com_vel_xy_mps: ArrayLike, omega_rps: float
) -> tuple[FloatArray, FloatArray]:
    """Exact CoM states at ``times_s`` (N+1,) for a CoP linear between ``cop_xy_m`` (N+1, 2) waypoints.

    Returns ``(pos (N+1, 2), vel (N+1, 2))`` starting from the given state at ``times_s[0]``.
    """
    seg = _Segments.build(np.asarray(times_s, dtype=float), float(omega_rps))
    return seg.propagate(
        np.asarray(cop_xy_m, dtype=float), np.asarray(com_xy_m, dtype=float), np.asarray(com_vel_xy_mps, dtype=float)
    )


# ------------------------------------------------------------------------- MPC


@dataclass(frozen=True)
class _Block:
    """Padded constraint rows of one support interval: H rows (midpoint) + 2H rows (end)."""

    normals: FloatArray  # (3H, 2), zero rows for padding
    offsets: FloatArray  # (3H,), +inf for padding
    end_centroid: FloatArray  # (2,) centroid of the end waypoint's region
    empty_intersection: bool


@dataclass
class _Problem:
    """One call's support schedule (world frame)."""

    times_s: FloatArray  # (N+1,) waypoint times
    ends_s: FloatArray  # (K,) interval ends (truncated to the window)
    normals: FloatArray  # (K * 3H, 2) stacked block rows
    offsets: FloatArray  # (K * 3H,)
    centroids: FloatArray  # (N+1, 2) centroid targets (row 0: first region's centroid)
    final_centroid: FloatArray  # (2,) c_T
    empty_intersection: bool


class ComMpc:
    """CoM/CoP MPC over a preview window, solved with OSQP on a fixed sparsity pattern.

    Parameters
    ----------
    preview_s : float
        Preview window ``T`` [s].
    weights : ComMpcWeights, optional
        Objective weights.
    max_intervals, max_halfplanes : int
        Initial padding (support intervals per window, half-planes per polygon); grown on demand.
    max_interval_s : float
        Supports longer than this are split into equal pieces (same polygon) [s].
    min_velocity_dt_s : float
        Lower bound on the waypoint spacing used in the CoP velocity cost [s]; keeps the
        cost bounded when an interval has almost elapsed.
    min_interval_s : float
        Intervals (or truncated remainders) shorter than this are skipped [s].
    eps_abs, eps_rel, max_iter, time_limit_s, polish
        OSQP settings (``time_limit_s=None``: no limit).  The QP is posed in metres around
        the current capture point, so ``eps_abs`` is about the CoP constraint tolerance [m].
        ``max_iter`` bounds the solve time (~3 us per iteration): capturable states need
        tens of iterations, hopeless (falling) states thousands; those return a fallback.

    Attributes
    ----------
    setup_count : int
        Number of OSQP ``setup`` calls so far (1 + the number of padding growths).

    Notes
    -----
    ``supports`` must be in chronological order and are treated as contiguous: interval
    ``k`` spans ``[end_{k-1}, end_k]`` (the first one starts at ``t_now_s``).  Elapsed
    intervals are skipped, the last one is truncated at ``t_now_s + preview_s``; if the
    schedule ends earlier, the window ends with it.
    """

    def __init__(
        self,
        preview_s: float = 2.0,
        weights: ComMpcWeights | None = None,
        max_intervals: int = 10,
        max_halfplanes: int = 8,
        *,
        max_interval_s: float = 0.5,
        min_velocity_dt_s: float = 0.02,
        min_interval_s: float = 1e-3,
        eps_abs: float = 1e-5,
        eps_rel: float = 1e-5,
        max_iter: int = 1000,
        time_limit_s: float | None = None,
        polish: bool = True,
    ) -> None:
        if not (preview_s > 0.0 and math.isfinite(preview_s)):
            raise ValueError("preview_s must be positive")
        self.preview_s = float(preview_s)
        self.weights = weights if weights is not None else ComMpcWeights()
        w = self.weights
        if not all(math.isfinite(v) and v >= 0.0 for v in (w.final_capture_point, w.cop_centroid, w.cop_velocity)):
            raise ValueError(f"weights must be finite and non-negative: {w}")
        self.max_interval_s = float(max_interval_s) if max_interval_s > 0.0 else math.inf
        self.min_velocity_dt_s = float(min_velocity_dt_s)
        self.min_interval_s = max(float(min_interval_s), 1e-6)
        self._osqp_settings: dict[str, float | int | bool] = dict(
            eps_abs=eps_abs,
            eps_rel=eps_rel,
            max_iter=max_iter,
            time_limit=time_limit_s if time_limit_s else 1e10,
            polishing=polish,
            verbose=False,
            warm_starting=True,
            adaptive_rho_interval=50,  # fixed interval: deterministic (the default is time based)
            check_termination=5,
        )
        self._max_intervals = max(int(max_intervals), 1)
        self._max_halfplanes = max(int(max_halfplanes), 3)
        self.setup_count = 0
        self._region_cache: dict[tuple[tuple[int, ...], bytes], _Region] = {}
        self._block_cache: dict[tuple[int, int], _Block] = {}
        self._schedule_cache: dict[tuple[int, ...], tuple[FloatArray, FloatArray, FloatArray, bool]] = {}
        self._last_good: ComMpcSolution | None = None
        self._build_pattern()

    # ------------------------------------------------------------ public API

    @property
    def padded_shape(self) -> tuple[int, int]:
        """Current padding ``(max_intervals, max_halfplanes)``."""
        return self._max_intervals, self._max_halfplanes

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts cold."""
        self._last_good = None
        self._prev = None

    def solve(
        self,
        t_now_s: float,
        com_xy_m: ArrayLike,
        com_vel_xy_mps: ArrayLike,
        cop_xy_m: ArrayLike,
        com_height_m: float,
        supports: Sequence[SupportInterval],
    ) -> ComMpcSolution:
        """Plan CoP waypoints and the CoM over ``[t_now_s, t_now_s + preview_s]``.

        Never raises: invalid input or solver failure yield a fallback solution whose
        ``status`` says so (see :class:`ComMpcSolution`).
        """
        t_start = time.perf_counter()
        args = (t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m, supports)
        solution: ComMpcSolution | None = None
        try:
            solution = self._solve(*args, t_start=t_start)
        except Exception as exc:  # noqa: BLE001 - a controller must never raise
            try:
                solution = self._fallback(*args, reason="solver_failed", message=f"exception: {exc!r}", t_start=t_start)
            except Exception:  # noqa: BLE001
                solution = None
        if solution is not None and _is_finite(solution):
            return solution
        # Last resort (e.g. a diverged, overflowing state): hold the CoP, finite by construction.
        t_now, com, vel, cop, height, _ = _sanitize_state(*args[:5])
        hold = _hold_solution(t_now, com, vel, cop, height, self.preview_s)
        invalid = solution is not None and solution.status.startswith("invalid_input")
        status = "invalid_input_hold_fallback" if invalid else "solver_failed_hold_fallback"
        return _replace_status(hold, status, "non-finite plan", time.perf_counter() - t_start)

    # -------------------------------------------------------------- internals

    def _solve(
        self,
        t_now_s: float,
        com_xy_m: ArrayLike,
        com_vel_xy_mps: ArrayLike,
        cop_xy_m: ArrayLike,
        com_height_m: float,
        supports: Sequence[SupportInterval],
        *,
        t_start: float,
    ) -> ComMpcSolution:
        args = (t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m, supports)
        t_now, com, vel, cop, height, state_ok = _sanitize_state(*args[:5])
        if not state_ok:
            return self._fallback(*args, reason="invalid_input", message="non-finite or invalid state", t_start=t_start)
        problem, error = self._build_problem(t_now, supports)
        if problem is None:
            return self._fallback(*args, reason="invalid_input", message=error, t_start=t_start)

        seg = _Segments.build(problem.times_s, math.sqrt(GRAVITY_MPS2 / height))
        origin = com + vel / seg.omega  # QP frame origin: the current capture point
        self._fill(problem, seg, origin, com - origin, vel, cop - origin)
        self._warm_start(problem, origin, t_now)
        result = self._solver.solve(raise_error=False)
        accepted, violation = self._accept(result)
        if not accepted:  # keep self._prev: the last good solution is the better warm start
            return self._fallback(
                *args,
                reason="solver_failed",
                message=f"osqp: {result.info.status}"
                + (f", max constraint violation {violation:.2e} m" if math.isfinite(violation) else ""),
                t_start=t_start,
            )
        self._prev = (problem.ends_s, origin, result.x.copy(), result.y.copy())

        n_wp = len(problem.times_s)
        wps_local = result.x[: 2 * n_wp].reshape(n_wp, 2).copy()
        wps_local[0] = cop - origin  # exactly the equality-constrained value
        pos, vel_wp = seg.propagate(wps_local, com - origin, vel)
        if result.info.status_val == osqp.SolverStatus.OSQP_SOLVED_INACCURATE:
            status = "solved_inaccurate"
        elif problem.empty_intersection:
            status = "solved_empty_intersection"
        else:
            status = "solved"
        message = f"osqp: {result.info.status}"
        if problem.empty_intersection:
            message += "; empty support intersection: end waypoint constrained to the closing interval's polygon"
        solution = ComMpcSolution(
            waypoint_times_s=problem.times_s,
            waypoints_xy_m=wps_local + origin,
            waypoint_com_xy_m=pos + origin,
            waypoint_com_vel_xy_mps=vel_wp,
            com_height_m=height,
            status=status,
            solve_time_s=time.perf_counter() - t_start,
            message=message,
            osqp_iterations=int(result.info.iter),
            osqp_time_s=float(result.info.run_time),
            region_centroids_xy_m=problem.centroids,
            qp_final_state=result.x[self._ix_xi : self._ix_xi + 4] + np.concatenate([origin, np.zeros(2)]),
        )
        if not _is_finite(solution):
            return self._fallback(*args, reason="solver_failed", message="non-finite CoM", t_start=t_start)
        self._last_good = solution
        return solution

    def _region(self, polygon: object) -> _Region:
        try:
            arr = np.asarray(polygon, dtype=float)
        except (TypeError, ValueError):
            return _make_region(np.zeros((0, 2)))
        key = (arr.shape, arr.tobytes())
        region = self._region_cache.get(key)
        if region is None:
            if len(self._region_cache) >= 512:
                self._region_cache.clear()
                self._block_cache.clear()
                self._schedule_cache.clear()
            region = _make_region(arr)
            self._region_cache[key] = region
        return region

    def _block(self, r0: _Region, r1: _Region | None) -> _Block:
        key = (r0.serial, -1 if r1 is None else r1.serial)
        block = self._block_cache.get(key)
        if block is not None:
            return block
        h = self._max_halfplanes
        normals = np.zeros((3 * h, 2))
        offsets = np.full(3 * h, np.inf)
        m0 = len(r0.offsets)
        normals[:m0], offsets[:m0] = r0.normals, r0.offsets  # midpoint: C_k
        normals[h : h + m0], offsets[h : h + m0] = r0.normals, r0.offsets  # end: C_k ...
        empty = False
        end_centroid = r0.centroid
        if r1 is not None and r1 is not r0:
            inter = clip_convex_polygons(r0.hull, r1.hull)
            if len(inter) == 0:
                empty = True  # fall back to C_k alone
            else:
                m1 = len(r1.offsets)
                normals[h + m0 : h + m0 + m1], offsets[h + m0 : h + m0 + m1] = r1.normals, r1.offsets  # ... and C_k+1
                end_centroid = polygon_centroid(inter)
        block = _Block(normals, offsets, end_centroid, empty)
        if len(self._block_cache) >= 2048:
            self._block_cache.clear()
            self._schedule_cache.clear()
        self._block_cache[key] = block
        return block

    def _build_problem(self, t_now: float, supports: Sequence[SupportInterval]) -> tuple[_Problem | None, str]:
        t_horizon = t_now + self.preview_s
        ends: list[float] = []
        regions: list[_Region] = []
        prev_end = t_now
        try:
            for s in supports:
                t0, t1 = float(s.t_start_s), float(s.t_end_s)
                if not (math.isfinite(t0) and math.isfinite(t1)) or t1 < t0:
                    return None, f"invalid support interval times ({t0}, {t1})"
                if t1 <= prev_end + self.min_interval_s:
                    continue  # elapsed (or nearly elapsed)
                if prev_end >= t_horizon - self.min_interval_s:
                    break
                region = self._region(s.polygon)
                if not region.valid:
                    return None, "empty or degenerate support polygon"
                # Long supports are split into equal pieces anchored at their start time.
                n_pieces = max(1, math.ceil((t1 - t0) / self.max_interval_s - 1e-9))
                piece_s = (t1 - t0) / n_pieces
                first = max(0, int((prev_end + self.min_interval_s - t0) // piece_s))
                for j in range(first, n_pieces):
                    end = t1 if j == n_pieces - 1 else t0 + (j + 1) * piece_s
                    if end <= prev_end + self.min_interval_s:
                        continue
                    if prev_end >= t_horizon - self.min_interval_s:
                        break
                    prev_end = min(end, t_horizon)
                    ends.append(prev_end)
                    regions.append(region)
        except (TypeError, ValueError, AttributeError) as exc:
            return None, f"malformed supports: {exc!r}"
        if not regions:
            return None, "no support interval covers the preview window"

        n_int = len(regions)
        max_h = max(len(r.offsets) for r in regions)
        if n_int > self._max_intervals or max_h > self._max_halfplanes:
            # Grow with some headroom so that the window's usual fluctuation does not re-grow it.
            self._max_intervals = max(self._max_intervals, n_int + 2)
            self._max_halfplanes = max(self._max_halfplanes, max_h)
            self._build_pattern()
        blocks = [self._block(regions[k], regions[k + 1] if k + 1 < n_int else None) for k in range(n_int)]

        ends_arr = np.array(ends)
        times = np.empty(2 * n_int + 1)
        times[0] = t_now
        times[2::2] = ends_arr
        times[1::2] = 0.5 * (times[0:-1:2] + ends_arr)
        key = tuple(map(id, blocks))  # blocks live in _block_cache; both caches are cleared together
        cached = self._schedule_cache.get(key)
        if cached is None:
            centroids = np.empty((2 * n_int + 1, 2))
            centroids[0] = regions[0].centroid
            centroids[1::2] = [r.centroid for r in regions]
            centroids[2::2] = [b.end_centroid for b in blocks]
            normals = np.concatenate([blk.normals for blk in blocks])
            offsets = np.concatenate([blk.offsets for blk in blocks])
            empty = any(b.empty_intersection for b in blocks)
            if len(self._schedule_cache) >= 256:
                self._schedule_cache.clear()
            cached = self._schedule_cache[key] = (normals, offsets, centroids, empty)
        normals, offsets, centroids, empty = cached
        return _Problem(times, ends_arr, normals, offsets, centroids, regions[-1].centroid, empty), ""

    def _build_pattern(self) -> None:
        """Create the padded sparsity pattern and run OSQP setup (only when the shape grows)."""
        k_max, h_max = self._max_intervals, self._max_halfplanes
        self._n_wp_max = n_wp = 2 * k_max + 1
        self._n_var = n_var = 2 * n_wp + 4
        self._ix_xi = ix = 2 * n_wp  # x_T, y_T at ix, ix+1; vx_T, vy_T at ix+2, ix+3
        self._rows_per_interval = 3 * h_max
        self._n_con = n_con = 6 + k_max * 3 * h_max
        self._block_cache.clear()
        self._schedule_cache.clear()

        # A, canonical order: initial CoP (2 rows), dynamics (4 rows), polygon rows.
        # Polygon rows of interval k: h_max for waypoint 2k+1, then 2 h_max for waypoint 2k+2.
        rows: list[np.ndarray] = [np.array([0, 1])]
        cols: list[np.ndarray] = [np.array([0, 1])]
        for d in range(2):
            for row in (2 + 2 * d, 3 + 2 * d):
                c = np.concatenate([2 * np.arange(n_wp) + d, [ix + d, ix + 2 + d]])
                rows.append(np.full(len(c), row))
                cols.append(c)
        self._poly_wp = np.tile(np.repeat([1, 2], [h_max, 2 * h_max]), k_max) + np.repeat(
            2 * np.arange(k_max), 3 * h_max
        )
        rows.append(np.repeat(6 + np.arange(n_con - 6), 2))
        cols.append(np.stack([2 * self._poly_wp, 2 * self._poly_wp + 1], axis=1).ravel())
        a_rows, a_cols = np.concatenate(rows), np.concatenate(cols)
        self._a_val = np.zeros(len(a_rows))
        self._a_val[:2] = 1.0
        n_dyn = 4 * (n_wp + 2)
        self._a_dyn = self._a_val[2 : 2 + n_dyn].reshape(2, 2, n_wp + 2)  # [axis, (dcm, ccm), column]
        self._a_poly = self._a_val[2 + n_dyn :].reshape(-1, 2)  # (polygon rows, 2)
        self._a_perm, a_mat = _csc_pattern(a_rows, a_cols, (n_con, n_var))

        # P (upper triangle): waypoint diagonal, consecutive-waypoint coupling, xi_T 2x2 blocks.
        diag = np.arange(2 * n_wp)
        off = np.arange(2 * (n_wp - 1))
        xi_r = [ix + d for d in (0, 0, 2, 1, 1, 3)]
        xi_c = [ix + d for d in (0, 2, 2, 1, 3, 3)]
        p_rows = np.concatenate([diag, off, xi_r])
        p_cols = np.concatenate([diag, off + 2, xi_c])
        self._p_val = np.zeros(len(p_rows))
        self._p_diag = self._p_val[: 2 * n_wp].reshape(n_wp, 2)
        self._p_off = self._p_val[2 * n_wp : 4 * n_wp - 2].reshape(n_wp - 1, 2)
        self._p_xi = self._p_val[4 * n_wp - 2 :].reshape(2, 3)
        self._p_perm, p_mat = _csc_pattern(p_rows, p_cols, (n_var, n_var))

        self._q = np.zeros(n_var)
        self._l = np.full(n_con, -np.inf)
        self._u = np.full(n_con, np.inf)
        self._l[:6] = self._u[:6] = 0.0
        self._p_diag[:] = 1.0  # placeholder values; every solve overwrites them
        self._p_xi[:] = (1.0, 0.0, 1.0)
        a_mat.data[:] = self._a_val[self._a_perm]
        p_mat.data[:] = self._p_val[self._p_perm]
        self._solver = osqp.OSQP()
        self._solver.setup(p_mat, self._q, a_mat, self._l, self._u, **self._osqp_settings)
        self.setup_count += 1
        self._rows_in_use = len(self._a_poly)  # force a full clear on the first fill
        self._prev: tuple[FloatArray, FloatArray, FloatArray, FloatArray] | None = None

    def _fill(
        self, pb: _Problem, seg: _Segments, origin: FloatArray, com: FloatArray, vel: FloatArray, cop: FloatArray
    ) -> None:
        """Write this problem's numbers (QP frame: positions relative to ``origin``) and update OSQP."""
        omega = seg.omega
        n_wp = len(pb.times_s)

        # Dynamics rows (modal form of Eq. 14's initial-state equalities, exact LIP):
        #   zeta_T + sum_n g_n p_n = e^{w T} zeta_0,   eta_T - sum_n c_n p_n = e^{-w T} eta_0
        # The DCM row is scaled by e^{-w T / 2}, between the forward (coefficients up to
        # e^{w T}) and the backward form (zeta_T coefficient e^{-w T}); this balanced form
        # gave the fewest ADMM iterations.
        to_end = seg.grow[-1] / seg.grow  # e^{w (t_N - t_n)}
        dcm_scale = 1.0 / math.sqrt(to_end[0])
        ga, gb = (dcm_scale * to_end[:-1]) * seg.a, (dcm_scale * to_end[:-1]) * seg.b
        ca, cb = seg.a / to_end[1:], seg.b / to_end[1:]
        dyn = self._a_dyn
        dyn[:, 0, :n_wp] = np.append(ga, 0.0)
        dyn[:, 0, 1:n_wp] += gb
        dyn[:, 1, :n_wp] = np.append(-cb, 0.0)
        dyn[:, 1, 1:n_wp] -= ca
        if n_wp < self._n_wp_max:
            dyn[:, :, n_wp:-2] = 0.0
        dyn[:, 0, -2:] = (dcm_scale, dcm_scale / omega)
        dyn[:, 1, -2:] = (1.0, -1.0 / omega)
        lo, up = self._l, self._u
        lo[0:2] = up[0:2] = cop
        lo[2:6:2] = up[2:6:2] = (dcm_scale * to_end[0]) * (com + vel / omega)  # zeta_0 = 0 up to rounding
        lo[3:6:2] = up[3:6:2] = (com - vel / omega) / to_end[0]

        # Polygon rows: A (x + o) <= b  ->  A x <= b - A o.  Unused rows: 0 <= +inf.
        poly = self._a_poly
        n_rows = len(pb.ends_s) * self._rows_per_interval
        poly[:n_rows] = pb.normals
        up[6 : 6 + n_rows] = pb.offsets - pb.normals @ origin
        if n_rows < self._rows_in_use:
            poly[n_rows : self._rows_in_use] = 0.0
            up[6 + n_rows : 6 + self._rows_in_use] = np.inf
        self._rows_in_use = n_rows

        # Cost: W_c |z_n - c_n|^2 + W_v |(z_n+1 - z_n) / dt_n|^2 + W_T |x_T + v_T / w - c_T|^2.
        w = self.weights
        wv = (w.cop_velocity / np.maximum(seg.h, self.min_velocity_dt_s) ** 2)[:, None]
        diag = self._p_diag
        diag[0] = 0.0
        diag[1:n_wp] = w.cop_centroid
        diag[: n_wp - 1] += wv
        diag[1:n_wp] += wv
        diag[n_wp:] = 1.0  # padded waypoints: decoupled, pinned to 0
        self._p_off[: n_wp - 1] = -wv
        self._p_off[n_wp - 1 :] = 0.0
        wt = w.final_capture_point
        self._p_xi[:] = (wt, wt / omega, wt / (omega * omega))
        q = self._q
        q[2 : 2 * n_wp] = (-w.cop_centroid) * (pb.centroids[1:] - origin).ravel()
        q[2 * n_wp :] = 0.0
        c_t = pb.final_centroid - origin
        q[self._ix_xi : self._ix_xi + 2] = -wt * c_t
        q[self._ix_xi + 2 : self._ix_xi + 4] = (-wt / omega) * c_t
        self._solver.update(q=q, l=lo, u=up, Px=self._p_val[self._p_perm], Ax=self._a_val[self._a_perm])

    def _warm_start(self, pb: _Problem, origin: FloatArray, t_now: float) -> None:
        """Warm start from the previous primal/dual solution, shifted by the elapsed intervals."""
        if self._prev is None:
            self._solver.warm_start(x=np.zeros(self._n_var), y=np.zeros(self._n_con))
            return
        prev_ends, prev_origin, x_prev, y_prev = self._prev
        dropped = int(np.searchsorted(prev_ends, t_now + self.min_interval_s, side="right"))
        dropped = min(dropped, len(prev_ends))
        ix = self._ix_xi
        x = np.zeros(self._n_var)
        y = np.zeros(self._n_con)
        shift = prev_origin - origin
        # Surviving waypoints keep their values; waypoints new to the window start at their centroid.
        n_wp_now = len(pb.times_s)
        keep = min(len(prev_ends) * 2 + 1 - 2 * dropped, n_wp_now)
        x[: 2 * keep] = (x_prev[4 * dropped : 4 * dropped + 2 * keep].reshape(-1, 2) + shift).ravel()
        x[2 * keep : 2 * n_wp_now] = (pb.centroids[keep:] - origin).ravel()
        x[ix : ix + 2] = x_prev[ix : ix + 2] + shift
        x[ix + 2 : ix + 4] = x_prev[ix + 2 : ix + 4]
        y[:6] = y_prev[:6]
        rows = self._rows_per_interval * dropped
        y[6 : self._n_con - rows] = y_prev[6 + rows :]
        self._solver.warm_start(x=x, y=y)

    def _accept(self, result) -> tuple[bool, float]:  # noqa: ANN001 - osqp result namespace
        """Accept solved / solved-inaccurate results whose CoP constraints hold within tolerance."""
        status = result.info.status_val
        if status not in (osqp.SolverStatus.OSQP_SOLVED, osqp.SolverStatus.OSQP_SOLVED_INACCURATE):
            return False, math.inf
        x = result.x
        if x is None or not np.isfinite(x).all():
            return False, math.inf
        n_rows = self._rows_in_use
        wps = x[: 2 * self._n_wp_max].reshape(-1, 2)[self._poly_wp[:n_rows]]
        slack = (self._a_poly[:n_rows] * wps).sum(axis=1) - self._u[6 : 6 + n_rows]
        violation = max(float(slack.max()), 0.0) if n_rows else 0.0
        tol = CONSTRAINT_TOL_M if status == osqp.SolverStatus.OSQP_SOLVED else 10 * CONSTRAINT_TOL_M
        return violation <= tol, violation

    def _fallback(
        self,
        t_now_s: float,
        com_xy_m: ArrayLike,
        com_vel_xy_mps: ArrayLike,
        cop_xy_m: ArrayLike,
        com_height_m: float,
        supports: Sequence[SupportInterval],
        *,
        reason: str,
        message: str,
        t_start: float,
    ) -> ComMpcSolution:
        """Previous good plan (if consistent with the state) or CoP at the region centroids, CoM integrated."""
        t_now, com, vel, cop, height, state_ok = _sanitize_state(
            t_now_s, com_xy_m, com_vel_xy_mps, cop_xy_m, com_height_m
        )
        prev = self._last_good
        if prev is not None and (not state_ok or _plan_matches_state(prev, t_now, com, vel, cop)):
            return _replace_status(prev, f"{reason}_previous_solution", message, time.perf_counter() - t_start)
        try:
            solution = self._centroid_plan(t_now, com, vel, cop, height, state_ok, supports)
        except Exception as exc:  # noqa: BLE001
            message += f"; centroid fallback failed: {exc!r}"
            solution = _hold_solution(t_now, com, vel, cop, height, self.preview_s)
        return _replace_status(solution, f"{reason}_centroid_fallback", message, time.perf_counter() - t_start)

    def _centroid_plan(
        self,
        t_now: float,
        com: FloatArray,
        vel: FloatArray,
        cop: FloatArray,
        height: float,
        state_ok: bool,
        supports: Sequence[SupportInterval],
    ) -> ComMpcSolution:
        """Safe plan: CoP waypoints at their regions' centroids (from the current CoP), CoM integrated exactly."""
        t_horizon = t_now + self.preview_s
        times = [t_now]
        regions: list[_Region] = []
        prev_end = t_now
        for s in supports:
            try:
                t1 = float(s.t_end_s)
            except (TypeError, ValueError, AttributeError):
                continue
            if not math.isfinite(t1) or t1 <= prev_end + self.min_interval_s:
                continue
            if prev_end >= t_horizon - self.min_interval_s:
                break
            end = min(t1, t_horizon)
            regions.append(self._region(getattr(s, "polygon", None)))
            times += [0.5 * (prev_end + end), end]
            prev_end = end
        if not state_ok:
            first_valid = next((r for r in regions if r.valid), None)
            if first_valid is not None:  # no usable state: start at rest over the support
                cop = first_valid.centroid.copy()
                com, vel = cop.copy(), np.zeros(2)
        if not regions:
            return _hold_solution(t_now, com, vel, cop, height, self.preview_s)
        points = [cop]
        for k, region in enumerate(regions):
            mid = region.centroid if region.valid else points[-1]
            end = mid
            nxt = regions[k + 1] if k + 1 < len(regions) else None
            if region.valid and nxt is not None and nxt.valid:
                inter = clip_convex_polygons(region.hull, nxt.hull)
                end = polygon_centroid(inter) if len(inter) else mid
            points += [mid, end]
        wps = np.array(points)
        t_arr = np.array(times)
        pos, vel_wp = propagate_lip(t_arr, wps - com, np.zeros(2), vel, math.sqrt(GRAVITY_MPS2 / height))
        return ComMpcSolution(t_arr, wps, pos + com, vel_wp, height, "", 0.0)


# ------------------------------------------------------------------ utilities


def _csc_pattern(rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> tuple[np.ndarray, sp.csc_matrix]:
    """CSC matrix with explicit (zero) entries at (rows, cols) and the canonical->CSC permutation."""
    perm = np.lexsort((rows, cols))
    r, c = rows[perm], cols[perm]
    if len(r) > 1 and np.any((np.diff(r) == 0) & (np.diff(c) == 0)):
        raise RuntimeError("duplicate entries in sparsity pattern")
    indptr = np.concatenate([[0], np.cumsum(np.bincount(c, minlength=shape[1]))])
    mat = sp.csc_matrix((np.zeros(len(r)), r.astype(np.int64), indptr.astype(np.int64)), shape=shape)
    return perm, mat


def _sanitize_state(
    t_now_s: float, com_xy_m: ArrayLike, com_vel_xy_mps: ArrayLike, cop_xy_m: ArrayLike, com_height_m: float
) -> tuple[float, FloatArray, FloatArray, FloatArray, float, bool]:
    """Finite versions of the inputs and whether the originals were all valid."""

    def vec2(v: ArrayLike) -> tuple[FloatArray, bool]:
        try:
            arr = np.asarray(v, dtype=float).reshape(2)
        except (TypeError, ValueError):
            return np.zeros(2), False
        ok = bool(np.isfinite(arr).all())
        return (arr.copy() if ok else np.nan_to_num(arr, nan=0.0, posinf=0.0, neginf=0.0)), ok

    try:
        t_now = float(t_now_s)
    except (TypeError, ValueError):
        t_now = math.nan
    t_ok = math.isfinite(t_now)
    com, com_ok = vec2(com_xy_m)
    vel, vel_ok = vec2(com_vel_xy_mps)
    cop, cop_ok = vec2(cop_xy_m)
    try:
        height = float(com_height_m)
    except (TypeError, ValueError):
        height = math.nan
    h_ok = math.isfinite(height) and height > 1e-3
    if not cop_ok and com_ok:
        cop = com.copy()
    if not com_ok and cop_ok:
        com = cop.copy()
    ok = t_ok and com_ok and vel_ok and cop_ok and h_ok
    return (t_now if t_ok else 0.0), com, vel, cop, (height if h_ok else FALLBACK_COM_HEIGHT_M), ok


def _plan_matches_state(plan: ComMpcSolution, t_now: float, com: FloatArray, vel: FloatArray, cop: FloatArray) -> bool:
    if not (plan.t_start_s <= t_now < plan.t_end_s):
        return False
    pos_p, vel_p, _ = plan.com_at(t_now)
    return bool(
        np.linalg.norm(pos_p - com) < 0.01
        and np.linalg.norm(vel_p - vel) < 0.05
        and np.linalg.norm(plan.cop_at(t_now) - cop) < 0.01
    )


def _hold_solution(
    t_now: float, com: FloatArray, vel: FloatArray, cop: FloatArray, height: float, preview_s: float
) -> ComMpcSolution:
    times = np.array([t_now, t_now + preview_s])
    wps = np.vstack([cop, cop])
    pos, vel_wp = propagate_lip(times, wps - com, np.zeros(2), vel, math.sqrt(GRAVITY_MPS2 / height))
    if not (np.isfinite(pos).all() and np.isfinite(vel_wp).all()):
        pos, vel_wp = np.zeros((2, 2)), np.zeros((2, 2))
    return ComMpcSolution(times, wps, pos + com, vel_wp, height, "", 0.0)


def _is_finite(sol: ComMpcSolution) -> bool:
    return bool(
        np.isfinite(sol.waypoint_times_s).all()
        and np.isfinite(sol.waypoints_xy_m).all()
        and np.isfinite(sol.waypoint_com_xy_m).all()
        and np.isfinite(sol.waypoint_com_vel_xy_mps).all()
        and np.isfinite(sol.qp_final_state).all()
        and math.isfinite(sol.com_height_m)
    )


def _replace_status(sol: ComMpcSolution, status: str, message: str, solve_time_s: float) -> ComMpcSolution:
    final_state = sol.qp_final_state
    if not np.isfinite(final_state).all():  # fallback plans: the propagated final state
        final_state = np.concatenate([sol.waypoint_com_xy_m[-1], sol.waypoint_com_vel_xy_mps[-1]])
    return dataclasses.replace(
        sol, status=status, message=message, solve_time_s=solve_time_s, qp_final_state=final_state
    )


# ------------------------------------------------------------- demo / benchmark


def _foot_rectangle(center_xy_m: FloatArray, yaw_rad: float, length_m: float, width_m: float) -> FloatArray:
    half = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]]) * [0.5 * length_m, 0.5 * width_m]
    rot = np.array([[math.cos(yaw_rad), -math.sin(yaw_rad)], [math.sin(yaw_rad), math.cos(yaw_rad)]])
    return (half[[2, 3, 0, 1]] @ rot.T) + center_xy_m  # counter-clockwise


def example_walking_supports(
    n_steps: int = 8,
    step_length_m: float = 0.25,
    step_width_m: float = 0.2,
    single_support_s: float = 0.4,
    double_support_s: float = 0.1,
    initial_double_support_s: float = 0.5,
    final_double_support_s: float = 3.0,
    foot_length_m: float = 0.2,
    foot_width_m: float = 0.08,
    t0_s: float = 0.0,
    yaw_rad: float = 0.0,
) -> list[SupportInterval]:
    """Straight walk (first step with the right foot) as alternating double/single supports.

    Feet are rectangles; double support is the convex hull of both feet.  The walk
    starts and ends in double support (the final one models stopping).
    """
    rot = np.array([[math.cos(yaw_rad), -math.sin(yaw_rad)], [math.sin(yaw_rad), math.cos(yaw_rad)]])

    def foot(x_m: float, side: float) -> FloatArray:
        return _foot_rectangle(rot @ np.array([x_m, 0.5 * side * step_width_m]), yaw_rad, foot_length_m, foot_width_m)

    feet = {1.0: foot(0.0, 1.0), -1.0: foot(0.0, -1.0)}  # left (+y), right (-y)
    t = t0_s
    out = [SupportInterval(t, t + initial_double_support_s, convex_hull(np.vstack(list(feet.values()))))]
    t += initial_double_support_s
    for i in range(n_steps):
        swing = -1.0 if i % 2 == 0 else 1.0
        out.append(SupportInterval(t, t + single_support_s, feet[-swing]))
        t += single_support_s
        feet[swing] = foot((i + 1) * step_length_m, swing)
        ds = final_double_support_s if i == n_steps - 1 else double_support_s
        out.append(SupportInterval(t, t + ds, convex_hull(np.vstack(list(feet.values())))))
        t += ds
    return out


def benchmark_solve(n: int = 500, dt_s: float = 0.008, com_height_m: float = 0.8) -> dict[str, float]:
    """Receding-horizon solve timing on a representative walk (125 Hz re-planning).

    Walks 0.25 m steps (0.4 s single / 0.1 s double support, 8-10 intervals per 2 s
    window).  Each call advances ``dt_s`` along the previous plan and re-solves (warm
    start); the supports overlapping the window are selected outside the timing, as
    the gait planner would pass them.  Returns wall-time statistics of ``ComMpc.solve``
    in microseconds (median, p99, max, OSQP-only median), the median OSQP iteration
    count, the fraction of ``"solved"`` results and the number of OSQP setups.
    """
    mpc = ComMpc()
    n_steps = int(math.ceil((n + 20) * dt_s / 0.5)) + 6
    supports = example_walking_supports(n_steps=n_steps, single_support_s=0.4, double_support_s=0.1)
    t = 0.0
    com = polygon_centroid(supports[0].polygon)
    vel = np.zeros(2)
    cop = com.copy()
    wall_us: list[float] = []
    osqp_us: list[float] = []
    iterations: list[int] = []
    n_solved = 0
    for i in range(n + 20):
        window = [s for s in supports if s.t_end_s > t and s.t_start_s < t + mpc.preview_s]
        sol = mpc.solve(t, com, vel, cop, com_height_m, window)
        if i >= 20:  # skip the start-up transient
            wall_us.append(sol.solve_time_s * 1e6)
            osqp_us.append(sol.osqp_time_s * 1e6)
            iterations.append(sol.osqp_iterations)
            n_solved += sol.status == "solved"
        t += dt_s
        com, vel, _ = sol.com_at(t)
        cop = sol.cop_at(t)
    wall = np.array(wall_us)
    return {
        "n": float(n),
        "median_us": float(np.median(wall)),
        "p99_us": float(np.percentile(wall, 99)),
        "max_us": float(wall.max()),
        "osqp_median_us": float(np.median(osqp_us)),
        "median_iterations": float(np.median(iterations)),
        "solved_fraction": n_solved / n,
        "setup_count": float(mpc.setup_count),
    }


if __name__ == "__main__":
    for key, value in benchmark_solve().items():
        print(f"{key:>20s}: {value:.1f}")
