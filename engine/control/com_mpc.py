"""Centre-of-mass model predictive controller (paper Sec. 7.1 and Appendix "MPC").

Plans the horizontal CoM and the Centre of Pressure (CoP) over a preview window
(default T = 2 s) given the upcoming convex support polygons and their timing.

Model (Eq. 11 with constant CoM height ``z`` and constant angular momentum)::

    x'' = omega^2 (x - p(t)),   omega^2 = g / z

Decision variables (Eq. 12): CoP waypoints ``p_0 .. p_N`` (``N = 2K``: one at the
midpoint and one at the end of each of the ``K`` support intervals, the CoP being
linear in between).  ``p_0`` equals the current CoP, midpoints lie in their polygon
``C_k``, end points in ``C_k ∩ C_k+1`` (the last one in ``C_K``).

Cost (Eq. 14)::

    W_T |CP_T - c_T|^2 + sum_n W_c |p_n - c_n|^2 + sum_n W_v |(p_n+1 - p_n) / dt_n|^2

with ``CP_T = x_T + v_T / omega`` the final capture point, ``c_n`` the centroid of
waypoint ``n``'s region (the intersection polygon for end points) and ``c_T`` the
last polygon's.

Well-conditioned, condensed form
--------------------------------
The paper optimises the final CoM state ``xi_T`` too, tied to the initial state by
reverse-time integration (Eq. 14's equalities).  Their coefficients, and those of
the capture-point cost expressed in the CoP, grow like ``exp(omega T)`` (~3000 for
z = 0.6 m, T = 2 s), which made the ADMM solver need hundreds to thousands of
iterations on closed-loop problems.  Here the final state is eliminated: with the
divergent component of motion ``zeta = x + v / omega`` and the exact LIP solution for
a piecewise-linear CoP (segment ``j`` of duration ``h_j``, ``E_j = exp(-omega h_j)``,
``r_j = (1 - E_j) / (omega h_j)``, ``a_j = 1 - r_j``, ``b_j = r_j - E_j``)::

    CP_T - c_T = exp(omega T) * r,
    r = zeta_0 - exp(-omega T) c_T - sum_n beta_n p_n,
    beta_n = exp(-omega tau_n) a_n + exp(-omega tau_n-1) b_n-1      (tau_n = t_n - t_0)

The "stability residual" ``r`` (IS-MPC's boundedness condition, Scianca et al. 2020)
has coefficients ``0 <= beta_n <= 1`` summing to ``1 - exp(-omega T)``, and the
capture-point term becomes ``W_s |r|^2`` with ``W_s = W_T exp(2 omega T)`` -- the
*same* objective as Eq. 14, so the optimum is unchanged (``ComMpcWeights.stability``
may set another ``W_s``; note that a residual ``r`` moves the final capture point by
``exp(omega T) r``, so "moderate" weights such as 1e4 let it drift by decimetres to
metres on walking problems).  The Hessian per axis is ``D + W_s beta beta^T`` (``D``
tridiagonal, eigenvalues within ``[W_c, W_c + 4 W_v / dt^2]``); the stiff rank-one
term is handled exactly with the Sherman-Morrison formula
(``H^-1 = D^-1 - kappa u u^T``, ``u = D^-1 beta``, ``kappa = W_s / (1 + W_s beta.u)``),
so ``W_s`` never enters a factorisation.  The CoM trajectory follows in closed form
from the initial state and the CoP (exact LIP integration), so ``com_at`` is
consistent with ``cop_at`` and the initial state by construction.

QP solver
---------
After elimination the QP has ``2N`` variables (~16-26 waypoints x 2 axes) and ~100
polygon rows (4-6 per waypoint), each touching one waypoint.  It is solved by a dense
dual active-set method (Goldfarb-Idnani, as in ``quadprog``): start from the
unconstrained optimum and add the most violated polygon row until none is violated,
dropping rows whose multiplier would turn negative (see :func:`_dual_active_set`).
Columns of the dual Hessian ``G = A H^-1 A^T`` are computed on demand from ``H^-1``.
Calls warm start from the active sets of the previous two solutions (rows matched by
waypoint time, kind and edge normal, so that shifted timings and moved footholds keep
them; two, because the controller alternates between plan continuations and
restarts from the measured state after a failed solve), and large changes of the
active set are made in blocks.  Closed-loop problems need 0-3 steps, restarts after
large pushes up to ~70.  The result is exact up to rounding (no tolerance-driven
polishing).  An iteration cap (``max_iter``) or time limit returns the current
iterate with its waypoints pulled into their regions (``"solved_inaccurate"``)
instead of a fallback.  ``solver="osqp"`` solves the same condensed QP with OSQP
(kept for cross-checking: ADMM still needs hundreds to thousands of iterations with
the exact ``W_s``).

Long supports (e.g. standing) are split into equal pieces of at most
``max_interval_s`` (anchored at the support's start, same polygon), each with its
two waypoints.  Without this a 2 s stance is steered by a single CoP ramp per second,
which cannot stabilise the capture point in closed loop; ``max_interval_s=inf``
gives the paper's literal two waypoints per support.

Polygon geometry (half-planes, centroids, intersections of consecutive supports) is
computed vectorised for all polygons of a call (footholds move a little every call,
so caching by contents rarely hits); in walking the intersection of consecutive
supports is one of them (a foot inside the double-support hull), which a containment
test detects without clipping.
"""

from __future__ import annotations

import bisect
import dataclasses
import itertools
import math
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import osqp
import scipy.sparse as sp
from scipy.linalg.lapack import dgetrf as _dgetrf
from scipy.linalg.lapack import dgetri as _dgetri
from scipy.linalg.lapack import dpotrf as _dpotrf
from scipy.linalg.lapack import dpotrs as _dpotrs
from scipy.linalg.lapack import dtrtrs as _dtrtrs
from numpy.typing import ArrayLike, NDArray

from engine.control import qp_backends
from engine.control.qp_backends import QpProblem

__all__ = [
    "GRAVITY_MPS2",
    "ComMpc",
    "ComMpcSolution",
    "ComMpcWeights",
    "SupportInterval",
    "clip_convex_polygons",
    "convex_hull",
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
#: Tolerance used to accept a QP solution's polygon constraints.
CONSTRAINT_TOL_M = 1e-4
#: Upper bound on the stability weight W_s (the default W_T exp(2 omega T) overflows for tiny heights).
MAX_STABILITY_WEIGHT = 1e12

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
    stability : float or None
        ``W_s`` on the stability residual ``r = exp(-omega T) (CP_T - c_T)`` [1/m^2].
        ``None`` (default): ``W_T exp(2 omega T)``, i.e. exactly Eq. 14's capture-point
        term.  A smaller value softens the final capture-point target.
    """

    final_capture_point: float = 100.0
    cop_centroid: float = 1.0
    cop_velocity: float = 0.01
    stability: float | None = None


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
    ``"solved_inaccurate"`` is also returned when the iteration cap or time limit
    stopped the solver: the waypoints are then its last iterate pulled into their regions.
    ``region_centroids_xy_m`` holds the centroid target of each waypoint's region and
    ``qp_final_state`` the final CoM state ``xi_T = [x_T, y_T, vx_T, vy_T]`` (the
    condensed QP eliminates it: it is the exactly propagated final state).
    ``osqp_iterations`` counts the QP solver's iterations (active-set steps for the
    default solver, ADMM iterations for ``solver="osqp"``) and ``osqp_time_s`` the
    time spent in the QP solver proper; the names are kept for compatibility.
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
        if isinstance(t_s, (float, int)):
            return self._com_at_scalar(float(t_s))
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

    def _com_at_scalar(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:meth:`com_at` for one time, on floats (the controller asks several times a tick)."""
        times, wps = self.waypoint_times_s, self.waypoints_xy_m
        n_seg = len(times) - 1
        t_first, t_last = float(times[0]), float(times[-1])
        j = min(max(bisect.bisect_right(times, t) - 1, 0), n_seg - 1)
        if t > t_last:
            anchor, sx, sy = n_seg, 0.0, 0.0
        else:
            anchor = j
            if t < t_first:
                sx = sy = 0.0
            else:
                h = max(float(times[j + 1] - times[j]), 1e-12)
                sx = float(wps[j + 1, 0] - wps[j, 0]) / h
                sy = float(wps[j + 1, 1] - wps[j, 1]) / h
        s = t - float(times[anchor])
        omega = self.omega_rps
        ch, sh = math.cosh(omega * s), math.sinh(omega * s)
        px, py = float(wps[anchor, 0]), float(wps[anchor, 1])
        cx, cy = self.waypoint_com_xy_m[anchor]
        vx, vy = self.waypoint_com_vel_xy_mps[anchor]
        ex, ey = float(cx) - px, float(cy) - py
        dex, dey = float(vx) - sx, float(vy) - sy
        errx, erry = ex * ch + dex * sh / omega, ey * ch + dey * sh / omega
        pos = np.array([px + sx * s + errx, py + sy * s + erry])
        vel = np.array([sx + ex * omega * sh + dex * ch, sy + ey * omega * sh + dey * ch])
        acc = np.array([omega * omega * errx, omega * omega * erry])
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



#: Tolerance of the containment test between consecutive supports [m].
_CONTAIN_TOL_M = 1e-9


@dataclass(frozen=True)
class _Region:
    """Geometry of one support polygon (reference path; used by the fallback plan)."""

    valid: bool
    normals: FloatArray  # (H, 2)
    offsets: FloatArray  # (H,)
    centroid: FloatArray  # (2,)
    hull: FloatArray  # (M, 2)


def _make_region(polygon: np.ndarray) -> _Region:
    """Reference (slow) path: convex hull, half-planes, centroid."""
    try:
        v = np.asarray(polygon, dtype=float)
    except (TypeError, ValueError):
        v = np.zeros((0, 2))
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3 or not np.isfinite(v).all():
        return _Region(False, np.zeros((0, 2)), np.zeros(0), np.zeros(2), np.zeros((0, 2)))
    hull = convex_hull(v)
    if len(hull) < 3 or polygon_area(hull) < MIN_POLYGON_AREA_M2:
        return _Region(False, np.zeros((0, 2)), np.zeros(0), np.zeros(2), hull)
    normals, offsets = polygon_halfplanes(hull)
    return _Region(True, normals, offsets, polygon_centroid(hull), hull)


@dataclass
class _SupportGeometry:
    """Half-planes and centroids of a call's support polygons, padded to ``V`` slots.

    Points are complex numbers ``x + iy``.  ``hull`` (S, V) vertices (padded with the
    first one), ``normals`` (S, V) unit outward normals (zero for padding and for an
    edge that continues the previous one), ``offsets`` (S, V) (+inf for those),
    ``centroids`` (S,).
    """

    hull: NDArray[np.complex128]
    normals: NDArray[np.complex128]
    offsets: FloatArray
    centroids: NDArray[np.complex128]


def _support_geometry(polygons: list[object]) -> _SupportGeometry | None:
    """Geometry of all polygons at once; None if one is empty or degenerate.

    Convex polygons (either orientation, collinear vertices allowed) are processed
    vectorised; others (non-convex, repeated vertices, non-finite) are replaced by their
    convex hull first (reference path: :func:`_make_region`).
    """
    arrays: list[FloatArray] = []
    for poly in polygons:
        if type(poly) is np.ndarray and poly.dtype == np.float64 and poly.ndim == 2 and poly.shape[1] == 2:
            v = poly
        else:
            try:
                v = np.asarray(poly, dtype=float)
            except (TypeError, ValueError):
                return None
            if v.ndim != 2 or v.shape[1] != 2:
                return None
        if len(v) < 3:
            return None
        arrays.append(v)
    geom = _geometry_padded(arrays)
    bad = geom[-1]
    if bad.any():  # non-convex, repeated vertices or non-finite: use the hull (reference path)
        for k in np.flatnonzero(bad):
            region = _make_region(arrays[k])
            if not region.valid:
                return None
            arrays[k] = region.hull
        geom = _geometry_padded(arrays)
        if geom[-1].any():
            return None
    if not (geom[4] >= MIN_POLYGON_AREA_M2).all():
        return None
    return _SupportGeometry(*geom[:4])


#: Index arrays of the padded layout, per tuple of vertex counts (few distinct ones occur).
_PAD_LAYOUTS: dict[tuple[int, ...], tuple] = {}


def _pad_layout(lens: tuple[int, ...]) -> tuple:
    layout = _PAD_LAYOUTS.get(lens)
    if layout is None:
        n = np.array(lens)
        n_v = int(n.max())
        starts = np.cumsum(n) - n
        slot = np.arange(n_v)
        real = slot < n[:, None]
        nxt = np.where(slot + 1 < n[:, None], slot + 1, 0)  # next real vertex (padding: vertex 0)
        prv = np.where(slot > 0, slot - 1, n[:, None] - 1)  # previous edge (for real slots)
        row = np.arange(len(n))[:, None] * n_v
        idx = starts[:, None] + np.where(real, slot, 0)  # vertices, padded with vertex 0
        layout = (idx, starts[:, None] + nxt, row + prv, real)
        if len(_PAD_LAYOUTS) > 256:
            _PAD_LAYOUTS.clear()
        _PAD_LAYOUTS[lens] = layout
    return layout


def _geometry_padded(arrays: list[FloatArray]) -> tuple:
    """Vectorised geometry of polygons (n_k, 2), with complex numbers ``x + iy``.

    Returns ``(hull (S, V), normals (S, V) complex, offsets (S, V), centroids (S,)
    complex, area (S,), not-convex mask (S,))``; vertices are padded with the first
    one, so padded edges have zero length (no half-plane, no area).
    """
    idx, idx_next, flat_prev, real = _pad_layout(tuple(len(a) for a in arrays))
    zf = np.concatenate(arrays).view(np.complex128)[:, 0]
    if not np.isfinite(zf).all():
        bad = np.array([not np.isfinite(a).all() for a in arrays])
        return None, None, None, None, None, bad
    z = zf[idx]
    zn = zf[idx_next]
    z0 = z[:, :1]
    w, wn = z - z0, zn - z0
    cross = (w.conj() * wn).imag  # shoelace terms about vertex 0 (padding: zero)
    area2 = cross.sum(axis=1)
    orient = np.where(area2 < 0.0, -1.0, 1.0)[:, None]
    edges = zn - z
    length = np.abs(edges)
    normals = edges * (-1j * orient) / np.maximum(length, 1e-300)  # outward: -i e (CCW), +i e (CW)
    # Convex: the outward normal turns the way of the orientation at every vertex (no
    # repeated vertex); an edge continuing the previous one (collinear vertex) repeats
    # its half-plane, which is dropped.
    rel = normals.ravel()[flat_prev].conj() * normals  # rotation from the previous edge's normal
    bad = ((length <= 1e-9) & real).any(axis=1) | (rel.imag * orient < -1e-9).any(axis=1)
    use = (length > 1e-9) & (rel.real < 1.0 - 1e-12)
    normals = np.where(use, normals, 0.0)
    offsets = np.where(use, (normals.conj() * z).real, np.inf)
    centroids = z0[:, 0] + ((w + wn) * cross).sum(axis=1) / (3.0 * np.where(area2 == 0.0, 1.0, area2))
    return z, normals, offsets, centroids, 0.5 * np.abs(area2), bad


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


@dataclass
class _Problem:
    """One call's support schedule (world frame)."""

    times_s: FloatArray  # (N+1,) waypoint times
    ends_s: FloatArray  # (K,) interval ends (truncated to the window)
    normals: FloatArray  # (m, 2) polygon rows, grouped by waypoint
    normals_c: NDArray[np.complex128]  # (m,) the same as complex numbers (shared memory)
    row_key: FloatArray  # (m,) waypoint time + 1000 s for midpoints (warm-start matching)
    offsets: FloatArray  # (m,)
    row_wp: NDArray[np.intp]  # (m,) waypoint index 1..N of each row
    centroids: FloatArray  # (N+1, 2) centroid targets (row 0: first region's centroid)
    final_centroid: FloatArray  # (2,) c_T
    empty_intersection: bool


@dataclass
class _Condensed:
    """Condensed QP of one axis pair, in a frame centred on ``origin`` (the current CoP).

    Per axis: ``min 1/2 p^T (D + W_s beta beta^T) p - (g + W_s r0 beta)^T p`` over the
    waypoints ``p_1..p_N``; ``H^-1 = D^-1 - kappa u u^T`` (Sherman-Morrison, ``u = D^-1 beta``).
    Rows: ``normals[i] . p[row_var[i]] <= rhs[i]``.
    """

    origin: FloatArray  # (2,) world position of the frame origin
    d_mat: FloatArray  # (N, N) tridiagonal D
    d_inv: FloatArray  # (N, N)
    g: FloatArray  # (N, 2) linear term (W_c-weighted centroids)
    stability_weight: float  # W_s
    beta: FloatArray  # (N,)
    u: FloatArray  # (N,)
    kappa: float
    r0: FloatArray  # (2,) stability residual with p_1..p_N = 0
    p_free: FloatArray  # (N, 2) unconstrained optimum
    hess_inv: FloatArray  # (N, N) H^-1 = D^-1 - kappa u u^T
    normals: FloatArray  # (m, 2)
    rhs: FloatArray  # (m,)
    row_var: NDArray[np.intp]  # (m,) waypoint variable index 0..N-1

    def standard_form(self) -> QpProblem:
        """The same QP over x = p.ravel() (waypoints 1..N, x and y interleaved) for the maintained
        backends. Note its Hessian carries W_s β βᵀ explicitly (condition number ~W_s)."""
        n = self.d_mat.shape[0]
        h_axis = self.d_mat + self.stability_weight * np.outer(self.beta, self.beta)
        h = np.zeros((2 * n, 2 * n))
        h[0::2, 0::2] = h_axis
        h[1::2, 1::2] = h_axis
        f = -(self.g + self.stability_weight * self.r0[None, :] * self.beta[:, None]).ravel()
        c = np.zeros((len(self.rhs), 2 * n))
        rows = np.arange(len(self.rhs))
        c[rows, 2 * self.row_var] = self.normals[:, 0]
        c[rows, 2 * self.row_var + 1] = self.normals[:, 1]
        return QpProblem(h, f, c=c, c_lo=np.full(len(self.rhs), -np.inf), c_up=self.rhs.copy())

    def h_inv(self, g: FloatArray) -> FloatArray:
        """``H^-1 g`` for ``g`` (N, 2)."""
        return self.hess_inv @ g

    def row_values(self, p: FloatArray) -> FloatArray:
        return np.einsum("ij,ij->i", self.normals, p[self.row_var])

    def dual_columns(self) -> Callable[[Sequence[int]], FloatArray]:
        """``cols(J) = G[:, J]`` of the dual Hessian ``G = A H^-1 A^T`` (m, len(J)).

        ``G_ij = (n_i . n_j) H^-1[v_i, v_j]`` (``v_i``: waypoint of row ``i``; the same
        ``H^-1`` for both axes); columns are computed on demand (only rows that enter
        the active set need them).
        """
        rv, nrm = self.row_var, self.normals
        h_rows = self.hess_inv[rv]  # (m, N)

        def cols(j: Sequence[int]) -> FloatArray:
            return h_rows[:, rv[j]] * (nrm @ nrm[j].T)

        return cols


#: Active-set outcomes.
_AS_OPTIMAL, _AS_CAPPED, _AS_INFEASIBLE = 0, 1, 2


def _inverse(mat: FloatArray) -> FloatArray:
    """Inverse of a small well-conditioned matrix (LAPACK getrf/getri: less overhead than numpy)."""
    lu, piv, info = _dgetrf(mat)
    if info == 0:
        inv, info = _dgetri(lu, piv)
        if info == 0:
            return inv
    return np.linalg.inv(mat)


def _chol(mat: FloatArray) -> FloatArray | None:
    """Lower Cholesky factor of a symmetric matrix, None unless it is safely positive definite."""
    if len(mat) == 0:
        return mat
    c, info = _dpotrf(mat, lower=1, clean=1)
    if info != 0 or c.diagonal().min() ** 2 <= 1e-13 * mat.diagonal().max():  # (nearly) dependent rows
        return None
    return c


def _dual_active_set(
    cols: Callable[[Sequence[int]], FloatArray],
    s: FloatArray,
    warm_sets: Iterable[Sequence[int]],
    row_var: NDArray[np.intp],
    tol: float,
    max_iter: int,
    deadline: float,
    block_rounds: int = 4,
) -> tuple[list[int], FloatArray, int, int]:
    """Dual active-set QP solver on ``min 1/2 x'Hx + q'x s.t. A x <= b``.

    Works on the dual data only: columns ``cols(J) = G[:, J]`` of ``G = A H^-1 A^T``
    and the slacks ``s = b - A x_free`` of the unconstrained optimum; the slacks of the
    iterate ``x = x_free - H^-1 A_W' lam`` are ``s + G[:, W] lam``.  Phases (each
    factorisation / step counts as one iteration):

    1. Warm start: each candidate set of rows guessed active (e.g. the previous two
       solutions' active rows) is solved as equalities; an exact guess ends here, else
       the candidate with the fewest violated rows and negative multipliers is kept.
    2. Block steps (primal-dual active set, Hintermüller et al. 2002): keep the rows
       with positive multipliers, add the violated ones (at most two per waypoint
       ``row_var``, most violated first); many rows change per step.
    3. Dual-feasible start: drop rows with negative multipliers until none is left.
    4. Goldfarb-Idnani (as in ``quadprog``): add the most violated row, dropping rows
       whose multiplier reaches zero on the way, until no row is violated by more than
       ``tol``.  Finite; the Cholesky factor of ``G_WW`` is extended by one row per
       added row (two triangular solves) and refactored when a row is dropped.

    Returns ``(W, lam, iterations, outcome)``.
    """
    n_var = int(row_var.max()) + 1 if len(row_var) else 0
    it = 0

    def evaluate(rows: list[int]) -> tuple | None:
        gw = cols(rows)
        c = _chol(gw[rows])
        if c is None:
            return None
        lam = _dpotrs(c, -s[rows], lower=1)[0] if rows else np.zeros(0)
        slack = s + gw @ lam if rows else s
        viol = np.flatnonzero(slack < -tol)
        positive = lam > 0.0
        return rows, gw, lam, slack, viol, positive, len(viol) + len(lam) - int(positive.sum())

    best = None
    for cand in itertools.chain(warm_sets, [[]]):
        rows = list(dict.fromkeys(cand))
        if best is not None and not rows:
            break
        it += 1
        ev = evaluate(rows)
        if ev is None:
            continue
        if ev[-1] == 0:
            return ev[0], ev[2], it, _AS_OPTIMAL
        if best is None or ev[-1] < best[-1]:
            best = ev
    assert best is not None  # the empty set always evaluates
    W, gw, lam, slack, viol, positive, _ = best
    for _ in range(block_rounds):
        if it >= max_iter or time.perf_counter() > deadline:
            break
        kept = [j for j, k in zip(W, positive) if k]
        count = np.bincount(row_var[kept], minlength=n_var) if kept else np.zeros(n_var, int)
        added: list[int] = []
        for i in viol[np.argsort(slack[viol])]:
            v = row_var[i]
            if count[v] < 2:
                count[v] += 1
                added.append(int(i))
        if not added and len(kept) == len(W):
            break
        it += 1
        ev = evaluate(kept + added)
        if ev is None:
            break
        W, gw, lam, slack, viol, positive, score = ev
        if score == 0:
            return W, lam, it, _AS_OPTIMAL
    # Dual-feasible start: positive multipliers on W, slack 0 on W.
    chol = _chol(gw[W])
    while W:
        if chol is None:
            W, gw, lam = [], gw[:, :0], np.zeros(0)
            break
        lam = _dpotrs(chol, -s[W], lower=1)[0]
        keep = lam > 0.0
        if keep.all():
            break
        it += 1
        W = [j for j, k in zip(W, keep) if k]
        gw = gw[:, keep]
        chol = _chol(gw[W])
    if not W:
        lam, chol = np.zeros(0), np.zeros((0, 0))
    while True:
        if W:
            slack = s + gw @ lam
            slack[W] = np.inf  # active rows hold with equality (up to rounding)
        else:
            slack = s
        p = int(np.argmin(slack))
        wp = float(slack[p])
        if wp >= -tol:
            return W, lam, it, _AS_OPTIMAL
        if it >= max_iter or time.perf_counter() > deadline:
            return W, lam, it, _AS_CAPPED
        lam_p = 0.0
        gp = cols([p])[:, 0]
        gpp = gp[p]
        while True:  # add row p, dropping rows whose multiplier reaches zero on the way
            it += 1
            k = len(W)
            if k:
                gwp = gp[W]
                ell = _dtrtrs(chol, gwp, lower=1)[0]
                d = -_dtrtrs(chol, ell, lower=1, trans=1)[0]
                z = gpp - float(ell @ ell)
            else:
                ell = d = lam
                z = gpp
            t_full = -wp / z if z > 1e-12 * gpp else math.inf
            t_part, j_block = math.inf, -1
            if k:
                neg = np.flatnonzero(d < 0.0)
                if len(neg):
                    ratios = lam[neg] / -d[neg]
                    jj = int(np.argmin(ratios))
                    t_part, j_block = float(ratios[jj]), int(neg[jj])
            if t_full == math.inf and t_part == math.inf:
                return W, lam, it, _AS_INFEASIBLE
            if t_full <= t_part:
                lam = np.append(lam + t_full * d, lam_p + t_full) if k else np.array([lam_p + t_full])
                grown = np.zeros((k + 1, k + 1))
                grown[:k, :k] = chol
                grown[k, :k] = ell
                grown[k, k] = math.sqrt(z)
                chol = grown
                W.append(p)
                gw = np.column_stack([gw, gp])
                break
            lam = lam + t_part * d
            lam_p += t_part
            wp += t_part * z
            del W[j_block]
            lam = np.delete(lam, j_block)
            gw = np.delete(gw, j_block, axis=1)
            chol = _chol(gw[W]) if W else np.zeros((0, 0))
            if chol is None:  # numerically dependent after all: restart from this row set
                return W, lam, it, _AS_CAPPED
            if it >= max_iter or time.perf_counter() > deadline:
                W.append(p)
                lam = np.append(lam, lam_p)
                return W, lam, it, _AS_CAPPED


_ROW_WAYPOINTS: dict[tuple[int, int], NDArray[np.intp]] = {}


def _row_waypoints(n_int: int, n_v: int) -> NDArray[np.intp]:
    """Waypoint index of each row slot: per interval ``n_v`` midpoint slots, ``2 n_v`` end slots."""
    key = (n_int, n_v)
    out = _ROW_WAYPOINTS.get(key)
    if out is None:
        out = (2 * np.arange(n_int)[:, None] + np.repeat([1, 2], [n_v, 2 * n_v])[None, :]).ravel()
        _ROW_WAYPOINTS[key] = out
    return out


class ComMpc:
    """CoM/CoP MPC over a preview window (condensed, well-conditioned QP; dense dual active set).

    Parameters
    ----------
    preview_s : float
        Preview window ``T`` [s].
    weights : ComMpcWeights, optional
        Objective weights.
    max_intervals, max_halfplanes : int
        Initial workspace size (support intervals per window, half-planes per polygon);
        grown on demand.  For ``solver="osqp"`` this is the padded sparsity pattern.
    max_interval_s : float
        Supports longer than this are split into equal pieces (same polygon) [s].
    min_velocity_dt_s : float
        Lower bound on the waypoint spacing used in the CoP velocity cost [s]; keeps the
        cost bounded when an interval has almost elapsed.
    min_interval_s : float
        Intervals (or truncated remainders) shorter than this are skipped [s].
    eps_abs, eps_rel, polish
        OSQP settings, used by ``solver="osqp"`` only (the active-set solution is exact).
    max_iter : int or None
        Iteration cap (``None``: 100 active-set steps -- closed-loop problems need 0-3,
        cold starts after large pushes up to ~70, ~40 us each --, 4000 OSQP
        iterations).  When it is reached the current iterate, pulled into the polygons,
        is returned as ``"solved_inaccurate"`` (a finite, feasible, CoM-consistent plan)
        instead of a fallback.
    time_limit_s : float or None
        Same, as a wall-time limit on the QP solve [s] (``None``: no limit).
    solver : {"active_set", "osqp", "daqp", "proxsuite", "quadprog"}
        QP solver of the condensed problem.

    Attributes
    ----------
    setup_count : int
        Number of solver workspace setups so far (1 + the number of workspace growths;
        for OSQP the ``setup`` calls).

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
        eps_abs: float = 1e-6,
        eps_rel: float = 1e-6,
        max_iter: int | None = None,
        time_limit_s: float | None = None,
        polish: bool = True,
        solver: str = "active_set",
    ) -> None:
        if not (preview_s > 0.0 and math.isfinite(preview_s)):
            raise ValueError("preview_s must be positive")
        choices = ("active_set", "osqp", *(b for b in qp_backends.BACKENDS if b != "osqp"))
        if solver not in choices:
            raise ValueError(f"solver: expected one of {', '.join(choices)}, got {solver!r}")
        self.preview_s = float(preview_s)
        self.weights = weights if weights is not None else ComMpcWeights()
        w = self.weights
        values = [w.final_capture_point, w.cop_centroid, w.cop_velocity]
        if w.stability is not None:
            values.append(w.stability)
        if not all(math.isfinite(v) and v >= 0.0 for v in values):
            raise ValueError(f"weights must be finite and non-negative: {w}")
        self.solver = solver
        self.max_interval_s = float(max_interval_s) if max_interval_s > 0.0 else math.inf
        self.min_velocity_dt_s = float(min_velocity_dt_s)
        self.min_interval_s = max(float(min_interval_s), 1e-6)
        default_iter = 100 if solver == "active_set" else 4000
        self.max_iter = max(int(max_iter), 1) if max_iter is not None else default_iter
        self.time_limit_s = float(time_limit_s) if time_limit_s else math.inf
        self._osqp_settings: dict[str, float | int | bool] = dict(
            eps_abs=eps_abs,
            eps_rel=eps_rel,
            max_iter=self.max_iter,
            time_limit=self.time_limit_s if math.isfinite(self.time_limit_s) else 1e10,
            polishing=polish,
            verbose=False,
            warm_starting=True,
            adaptive_rho_interval=25,  # fixed interval: deterministic (the default is time based)
            check_termination=5,
        )
        self._max_intervals = max(int(max_intervals), 1)
        self._max_halfplanes = max(int(max_halfplanes), 3)
        self.setup_count = 0
        self._last_good: ComMpcSolution | None = None
        self._warm_history: list[tuple[FloatArray, NDArray[np.complex128]]] = []
        self._setup()

    # ------------------------------------------------------------ public API

    @property
    def padded_shape(self) -> tuple[int, int]:
        """Current workspace size ``(max_intervals, max_halfplanes)``."""
        return self._max_intervals, self._max_halfplanes

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts cold."""
        self._last_good = None
        self._warm_history = []

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
        try:
            supports = list(supports)  # iterated more than once (problem, fallback)
        except TypeError:
            pass
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
        origin = cop  # QP frame: centred on the current CoP, so p_0 = 0
        qp = self._condense(problem, seg, origin, com + vel / seg.omega - origin)
        t_qp = time.perf_counter()
        deadline = t_qp + self.time_limit_s
        if self.solver == "osqp":
            wps, iterations, outcome, message = self._solve_osqp(problem, qp, deadline)
        elif self.solver != "active_set":  # a maintained backend on the standard form
            result = qp_backends.solve(qp.standard_form(), self.solver)
            wps = result.x.reshape(-1, 2) if result.ok else qp.p_free
            iterations, outcome, message = 0, (_AS_OPTIMAL if result.ok else _AS_INFEASIBLE), result.status
        else:
            wps, iterations, outcome, message = self._solve_active_set(problem, qp, deadline)
        qp_time = time.perf_counter() - t_qp
        if outcome == _AS_CAPPED:  # best iterate: pull each waypoint into its region
            wps = _pull_into_regions(wps, qp, problem.centroids[1:] - origin)
        violation = 0.0
        if len(qp.rhs):
            violation = max(float((qp.row_values(wps) - qp.rhs).max()), 0.0) if np.isfinite(wps).all() else math.inf
        if outcome == _AS_INFEASIBLE or not violation <= CONSTRAINT_TOL_M:
            self._warm_history = []
            return self._fallback(
                *args,
                reason="solver_failed",
                message=message + (f", max constraint violation {violation:.2e} m" if math.isfinite(violation) else ""),
                t_start=t_start,
            )

        n_wp = len(problem.times_s)
        wps_local = np.zeros((n_wp, 2))
        wps_local[1:] = wps  # wps_local[0] = 0: exactly the current CoP
        pos, vel_wp = seg.propagate(wps_local, com - origin, vel)
        if outcome == _AS_CAPPED:
            status = "solved_inaccurate"
        elif problem.empty_intersection:
            status = "solved_empty_intersection"
        else:
            status = "solved"
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
            osqp_iterations=int(iterations),
            osqp_time_s=qp_time,
            region_centroids_xy_m=problem.centroids,
            qp_final_state=np.concatenate([pos[-1] + origin, vel_wp[-1]]),
        )
        if not math.isfinite(float(pos.sum() + vel_wp.sum())):
            return self._fallback(*args, reason="solver_failed", message="non-finite CoM", t_start=t_start)
        self._last_good = solution
        return solution

    # ------------------------------------------------------------ geometry

    def _region(self, polygon: object) -> _Region:
        """Geometry of one polygon (reference path, used by the fallback plan)."""
        return _make_region(polygon)  # type: ignore[arg-type]

    def _build_problem(self, t_now: float, supports: Sequence[SupportInterval]) -> tuple[_Problem | None, str]:
        t_horizon = t_now + self.preview_s
        min_int = self.min_interval_s
        try:
            t_start = np.array([s.t_start_s for s in supports], dtype=float)
            t_end = np.array([s.t_end_s for s in supports], dtype=float)
        except (TypeError, ValueError, AttributeError) as exc:
            return None, f"malformed supports: {exc!r}"
        if t_start.ndim != 1 or t_end.shape != t_start.shape:
            return None, "malformed supports: support times must be scalars"
        invalid = ~(np.isfinite(t_start) & np.isfinite(t_end) & (t_end >= t_start))
        # Supports in use: not elapsed, starting before the window ends (chronological order).
        used: list[int] = []
        prev_end = t_now
        ends_list = t_end.tolist()
        for k, t1 in enumerate(ends_list):
            if invalid[k]:
                return None, f"invalid support interval times ({t_start[k]}, {t1})"
            if t1 <= prev_end + min_int:
                continue  # elapsed (or nearly elapsed)
            if prev_end >= t_horizon - min_int:
                break
            used.append(k)
            prev_end = t1 if t1 < t_horizon else t_horizon
        if not used:
            return None, "no support interval covers the preview window"
        try:
            polygons = [supports[k].polygon for k in used]
        except (TypeError, AttributeError, IndexError) as exc:
            return None, f"malformed supports: {exc!r}"
        geom = _support_geometry(polygons)
        if geom is None:
            return None, "empty or degenerate support polygon"

        # Intervals: the supports, long ones split into equal pieces anchored at their start.
        t0_used, t1_used = t_start[used], t_end[used]
        n_pieces = np.maximum(np.ceil((t1_used - t0_used) / self.max_interval_s - 1e-9), 1.0)
        if (n_pieces == 1.0).all():
            ends_arr = np.minimum(t1_used, t_horizon)
            own = np.arange(len(used))
        else:
            ends: list[float] = []
            owner: list[int] = []
            prev_end = t_now
            for k, (t0, t1, n_k) in enumerate(zip(t0_used.tolist(), t1_used.tolist(), n_pieces.astype(int).tolist())):
                piece_s = (t1 - t0) / n_k
                first = max(0, int((prev_end + min_int - t0) // piece_s)) if n_k > 1 else 0
                for j in range(first, n_k):
                    end = t1 if j == n_k - 1 else t0 + (j + 1) * piece_s
                    if end <= prev_end + min_int:
                        continue
                    if prev_end >= t_horizon - min_int:
                        break
                    prev_end = min(end, t_horizon)
                    ends.append(prev_end)
                    owner.append(k)
            ends_arr = np.array(ends)
            own = np.array(owner)
        n_int = len(own)
        max_h = int((geom.offsets < np.inf).sum(axis=1).max())
        if n_int > self._max_intervals or max_h > self._max_halfplanes:
            # Grow with some headroom so that the window's usual fluctuation does not re-grow it.
            self._max_intervals = max(self._max_intervals, n_int + 2)
            self._max_halfplanes = max(self._max_halfplanes, max_h)
            self._setup()

        # End waypoints: C_k ∩ C_k+1.  Consecutive supports nest in walking (a foot inside
        # the double-support hull): the intersection is the inner polygon.  Otherwise both
        # polygons' rows are stacked (clipped only for the centroid and the empty check).
        n_sup = len(used)
        nrm, off, hull, cent = geom.normals, geom.offsets, geom.hull, geom.centroids
        nxt = np.append(own[1:], own[-1])
        switch = nxt != own  # the interval closes its support
        if n_sup > 1:
            # max over (half-plane of one polygon, vertex of the other) of the signed distance
            inner_b = ((nrm[:-1, :, None].conj() * hull[1:, None, :]).real - off[:-1, :, None]).max(axis=(1, 2))
            inner_a = ((nrm[1:, :, None].conj() * hull[:-1, None, :]).real - off[1:, :, None]).max(axis=(1, 2))
            pair = np.minimum(own, n_sup - 2)
            in_a = inner_a[pair] <= _CONTAIN_TOL_M  # C_k ⊂ C_k+1: the intersection is C_k
            in_b = inner_b[pair] <= _CONTAIN_TOL_M  # C_k+1 ⊂ C_k: it is C_k+1
            use_b = switch & ~in_a
            use_a = ~(use_b & in_b)
        else:
            use_a, use_b = np.ones(n_int, bool), np.zeros(n_int, bool)
        end_centroids = np.where(use_a, cent[own], cent[nxt])
        empty = False
        for i in np.flatnonzero(use_a & use_b):  # general overlap (rare)
            k = own[i]
            hull_a = convex_hull(np.stack([hull[k].real, hull[k].imag], axis=1))
            hull_b = convex_hull(np.stack([hull[k + 1].real, hull[k + 1].imag], axis=1))
            inter = clip_convex_polygons(hull_a, hull_b)
            if len(inter) == 0:  # fall back to C_k alone
                use_b[i] = False
                empty = True
            else:
                c = polygon_centroid(inter)
                end_centroids[i] = c[0] + 1j * c[1]

        # Rows, per interval: V midpoint slots (C_k), then 2V end slots (C_k, C_k+1);
        # unused slots (+inf offsets) are dropped.
        n_v = off.shape[1]
        off_all = np.concatenate(
            [off[own], np.where(use_a[:, None], off[own], np.inf), np.where(use_b[:, None], off[nxt], np.inf)], axis=1
        ).ravel()
        nrm_all = np.concatenate([nrm[own], nrm[own], nrm[nxt]], axis=1).ravel()
        keep = off_all < np.inf
        wp_all = _row_waypoints(n_int, n_v)

        times = np.empty(2 * n_int + 1)
        times[0] = t_now
        times[2::2] = ends_arr
        times[1::2] = 0.5 * (times[0:-1:2] + ends_arr)
        centroids = np.empty(2 * n_int + 1, np.complex128)
        centroids[0] = cent[own[0]]
        centroids[1::2] = cent[own]
        centroids[2::2] = end_centroids
        final = cent[own[-1]]
        nrm_c = nrm_all[keep]
        row_wp = wp_all[keep]
        problem = _Problem(
            times,
            ends_arr,
            nrm_c.view(np.float64).reshape(-1, 2),
            nrm_c,
            times[row_wp] + _WARM_KIND_OFFSET_S * (row_wp & 1),
            off_all[keep],
            row_wp,
            centroids.view(np.float64).reshape(-1, 2),
            np.array([final.real, final.imag]),
            empty,
        )
        return problem, ""

    # ---------------------------------------------------------- condensed QP

    def _setup(self) -> None:
        """(Re)size the solver workspace for the current ``padded_shape``."""
        self.setup_count += 1
        self._warm_history = []
        if self.solver == "osqp":
            self._build_osqp_pattern()

    def _stability_weight(self, omega: float, horizon_s: float) -> float:
        w = self.weights
        if w.stability is not None:
            return min(float(w.stability), MAX_STABILITY_WEIGHT)
        return min(w.final_capture_point * math.exp(min(2.0 * omega * horizon_s, 700.0)), MAX_STABILITY_WEIGHT)

    def _condense(self, pb: _Problem, seg: _Segments, origin: FloatArray, zeta0: FloatArray) -> _Condensed:
        """Eliminate the final state: cost and rows in the waypoints ``p_1..p_N`` (frame at ``origin``)."""
        w = self.weights
        n = len(pb.times_s) - 1
        decay = 1.0 / seg.grow  # exp(-omega tau_n)
        beta = decay[:-1] * seg.b  # b_{n-1} term of p_n, n = 1..N
        beta[:-1] += decay[1:-1] * seg.a[1:]  # a_n term, n = 1..N-1 (p_0 = 0 in this frame)
        wv = w.cop_velocity / np.maximum(seg.h, self.min_velocity_dt_s) ** 2
        diag = (w.cop_centroid + 1e-9) + wv  # tiny regularisation: D stays definite for zero weights
        diag[:-1] += wv[1:]
        d_mat = np.zeros((n, n))
        d_mat.flat[:: n + 1] = diag
        d_mat.flat[1 :: n + 1] = -wv[1:]
        d_mat.flat[n :: n + 1] = -wv[1:]
        d_inv = _inverse(d_mat)
        u = d_inv @ beta
        ws = self._stability_weight(seg.omega, float(pb.times_s[-1] - pb.times_s[0]))
        kappa = ws / (1.0 + ws * float(beta @ u))
        g = w.cop_centroid * (pb.centroids[1:] - origin)  # (the p_0 term of the velocity cost vanishes: p_0 = 0)
        r0 = zeta0 - decay[-1] * (pb.final_centroid - origin)
        y = d_inv @ g
        p_free = y + np.outer(u, kappa * (r0 - beta @ y))
        rhs = pb.offsets - pb.normals @ origin
        hess_inv = d_inv - np.outer(kappa * u, u)
        return _Condensed(
            origin, d_mat, d_inv, g, ws, beta, u, kappa, r0, p_free, hess_inv, pb.normals, rhs, pb.row_wp - 1
        )

    def _solve_active_set(
        self, pb: _Problem, qp: _Condensed, deadline: float
    ) -> tuple[FloatArray, int, int, str]:
        s = qp.rhs - qp.row_values(qp.p_free)
        if len(s) == 0 or s.min() >= -_AS_TOL_M:
            self._store_warm(pb, [])
            return qp.p_free, 0, _AS_OPTIMAL, "active set: unconstrained optimum"
        warm = (self._match_warm(pb, entry) for entry in self._warm_history)  # matched lazily
        active, lam, iterations, outcome = _dual_active_set(
            qp.dual_columns(), s, warm, qp.row_var, _AS_TOL_M, self.max_iter, deadline
        )
        if outcome == _AS_INFEASIBLE:
            return qp.p_free, iterations, outcome, "active set: infeasible"
        g = np.zeros_like(qp.p_free)
        if active:
            rows = np.asarray(active)
            rv, n = qp.row_var[rows], len(g)
            g[:, 0] = np.bincount(rv, qp.normals[rows, 0] * lam, n)
            g[:, 1] = np.bincount(rv, qp.normals[rows, 1] * lam, n)
        wps = qp.p_free - qp.h_inv(g)
        if outcome == _AS_OPTIMAL:
            self._store_warm(pb, active)
            return wps, iterations, outcome, f"active set: optimal, {len(active)} active rows"
        return wps, iterations, outcome, "active set: iteration cap or time limit reached"

    def _store_warm(self, pb: _Problem, active: list[int]) -> None:
        """Remember the active rows by waypoint time and kind (encoded together) and normal."""
        rows = np.asarray(active, dtype=np.intp)
        entry = (pb.row_key[rows], pb.normals_c[rows])
        self._warm_history = [entry] + self._warm_history[: _WARM_HISTORY - 1]

    def _match_warm(self, pb: _Problem, entry: tuple[FloatArray, NDArray[np.complex128]]) -> list[int]:
        """Rows of this problem matching a remembered solution's active rows.

        A row matches an active row of the same waypoint kind (midpoint / end) within
        ``_WARM_TIME_TOL_S`` and with a parallel edge normal, so that shifted timings
        and moved footholds keep the warm start.
        """
        key_prev, n_prev = entry
        if len(key_prev) == 0:
            return []
        match = (np.abs(pb.row_key[:, None] - key_prev) < _WARM_TIME_TOL_S) & (
            (pb.normals_c[:, None].conj() * n_prev).real > _WARM_NORMAL_COS
        )
        return match.argmax(axis=0)[match.any(axis=0)].tolist()

    # ------------------------------------------------------------ OSQP backend

    def _build_osqp_pattern(self) -> None:
        """Padded sparsity pattern of the condensed QP for OSQP, and ``setup``.

        Variables ``[p_x (N_max), p_y (N_max), r_x, r_y]``; rows: the two stability
        residual equalities ``beta . p + r = r0`` then ``3 max_halfplanes`` polygon rows
        per interval (midpoint, then end waypoint).  Unused waypoints are pinned to 0 by
        a unit cost, unused rows are ``0 <= +inf``.
        """
        k_max, h_max = self._max_intervals, self._max_halfplanes
        nw = 2 * k_max
        n_var = 2 * nw + 2
        n_con = 2 + k_max * 3 * h_max
        self._osqp_nw = nw
        slot_wp = np.tile(np.repeat([0, 1], [h_max, 2 * h_max]), k_max) + np.repeat(2 * np.arange(k_max), 3 * h_max)
        self._osqp_slot_base = np.concatenate([[0], np.cumsum(np.bincount(slot_wp, minlength=nw))[:-1]])
        a_rows = np.concatenate(
            [np.zeros(nw + 1, int), np.ones(nw + 1, int), np.repeat(2 + np.arange(n_con - 2), 2)]
        )
        a_cols = np.concatenate(
            [np.r_[0:nw, 2 * nw], np.r_[nw : 2 * nw, 2 * nw + 1], np.stack([slot_wp, nw + slot_wp], axis=1).ravel()]
        )
        self._osqp_a_val = np.zeros(len(a_rows))
        self._osqp_a_perm, a_mat = _csc_pattern(a_rows, a_cols, (n_con, n_var))
        off = np.concatenate([np.arange(nw - 1), nw + np.arange(nw - 1)])
        p_rows = np.concatenate([np.arange(n_var), off])
        p_cols = np.concatenate([np.arange(n_var), off + 1])
        self._osqp_p_val = np.zeros(len(p_rows))
        self._osqp_p_perm, p_mat = _csc_pattern(p_rows, p_cols, (n_var, n_var))
        self._osqp_p_val[:n_var] = 1.0
        p_mat.data[:] = self._osqp_p_val[self._osqp_p_perm]
        self._osqp_a_val[:] = 1.0
        a_mat.data[:] = self._osqp_a_val[self._osqp_a_perm]
        self._osqp_l = np.full(n_con, -np.inf)
        self._osqp_u = np.full(n_con, np.inf)
        self._osqp_l[:2] = self._osqp_u[:2] = 0.0
        self._osqp = osqp.OSQP()
        self._osqp.setup(p_mat, np.zeros(n_var), a_mat, self._osqp_l, self._osqp_u, **self._osqp_settings)

    def _solve_osqp(self, pb: _Problem, qp: _Condensed, deadline: float) -> tuple[FloatArray, int, int, str]:
        nw = self._osqp_nw
        n = len(qp.beta)
        n_var = 2 * nw + 2
        # P: per axis D (diagonal, super-diagonal), W_s on r; padded waypoints pinned by a unit cost.
        d_mat = qp.d_mat
        pv = self._osqp_p_val
        pv[:] = 0.0
        pv[: 2 * nw] = 1.0
        for ax in (0, nw):
            pv[ax : ax + n] = np.diag(d_mat)
            pv[n_var + (ax // nw) * (nw - 1) + np.arange(n - 1)] = np.diag(d_mat, 1)
        pv[2 * nw : 2 * nw + 2] = qp.stability_weight
        q = np.zeros(n_var)
        q[:n] = -qp.g[:, 0]
        q[nw : nw + n] = -qp.g[:, 1]
        # A: residual rows then polygon rows in their padded slots.
        av = self._osqp_a_val
        av[:] = 0.0
        av[:n] = qp.beta
        av[nw] = 1.0
        av[nw + 1 : nw + 1 + n] = qp.beta
        av[2 * nw + 1] = 1.0
        lo, up = self._osqp_l, self._osqp_u
        lo[:2] = up[:2] = qp.r0
        up[2:] = np.inf
        rv = qp.row_var
        ordinal = np.arange(len(rv)) - np.searchsorted(rv, rv)
        slots = self._osqp_slot_base[rv] + ordinal
        poly = av[2 * nw + 2 :].reshape(-1, 2)
        poly[slots] = qp.normals
        up[2 + slots] = qp.rhs
        self._osqp.update(q=q, l=lo, u=up, Px=pv[self._osqp_p_perm], Ax=av[self._osqp_a_perm])
        time_left = deadline - time.perf_counter()
        if math.isfinite(time_left):
            self._osqp.update_settings(time_limit=max(time_left, 1e-6))
        # Warm start: the previous plan's CoP at the new waypoint times (duals from zero).
        x0 = np.zeros(n_var)
        prev = self._last_good
        if prev is not None and prev.t_start_s <= pb.times_s[0] < prev.t_end_s:
            p_prev = prev.cop_at(pb.times_s[1:]) - qp.origin
            x0[:n] = p_prev[:, 0]
            x0[nw : nw + n] = p_prev[:, 1]
            x0[2 * nw : 2 * nw + 2] = qp.r0 - qp.beta @ p_prev
        self._osqp.warm_start(x=x0, y=np.zeros(len(lo)))
        res = self._osqp.solve(raise_error=False)
        status = res.info.status_val
        it = int(res.info.iter)
        msg = f"osqp: {res.info.status}"
        if res.x is None or not np.isfinite(res.x).all():
            return qp.p_free, it, _AS_INFEASIBLE, msg
        wps = np.stack([res.x[:n], res.x[nw : nw + n]], axis=1)
        if status == osqp.SolverStatus.OSQP_SOLVED:
            return wps, it, _AS_OPTIMAL, msg
        if status in (
            osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
            osqp.SolverStatus.OSQP_MAX_ITER_REACHED,
            osqp.SolverStatus.OSQP_TIME_LIMIT_REACHED,
        ):
            return wps, it, _AS_CAPPED, msg
        return wps, it, _AS_INFEASIBLE, msg

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

#: Active-set feasibility tolerance on the polygon rows [m].
_AS_TOL_M = 1e-9
#: Warm start: a previous active row matches a row of a waypoint of the same kind
#: (midpoint / end) within this time [s] and with an edge normal this parallel.
_WARM_TIME_TOL_S = 0.03
_WARM_KIND_OFFSET_S = 1e3  # separates midpoints from end points in the matching key
#: Number of previous solutions whose active rows are tried as warm starts.
_WARM_HISTORY = 2
_WARM_NORMAL_COS = 0.999


def _pull_into_regions(wps: FloatArray, qp: _Condensed, centroids: FloatArray) -> FloatArray:
    """Move each waypoint (N, 2) along the segment to its centroid target until its rows hold."""
    rv = qp.row_var
    c = centroids[rv]
    num = np.maximum(qp.rhs - np.einsum("ij,ij->i", qp.normals, c), 0.0)
    den = np.einsum("ij,ij->i", qp.normals, wps[rv] - c)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(den > 0.0, num / den, np.inf)
    scale = np.ones(len(wps))
    np.minimum.at(scale, rv, ratio)
    scale = np.clip(scale, 0.0, 1.0)
    return centroids + scale[:, None] * (wps - centroids)


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
    # A sum is finite iff all its terms are (barring overflow, which also means "not usable").
    with np.errstate(over="ignore", invalid="ignore"):
        total = (
            sol.waypoint_times_s.sum()
            + sol.waypoints_xy_m.sum()
            + sol.waypoint_com_xy_m.sum()
            + sol.waypoint_com_vel_xy_mps.sum()
            + sol.qp_final_state.sum()
            + sol.com_height_m
        )
    return math.isfinite(float(total))


def _replace_status(sol: ComMpcSolution, status: str, message: str, solve_time_s: float) -> ComMpcSolution:
    final_state = sol.qp_final_state
    if not np.isfinite(final_state).all():  # fallback plans: the propagated final state
        final_state = np.concatenate([sol.waypoint_com_xy_m[-1], sol.waypoint_com_vel_xy_mps[-1]])
    return dataclasses.replace(
        sol, status=status, message=message, solve_time_s=solve_time_s, qp_final_state=final_state
    )
