"""CoM MPC data: support intervals, objective weights and the solution (CoP waypoints, exact CoM)."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.constants import GRAVITY_MPS2

FloatArray = NDArray[np.float64]


#: CoM height used only to keep fallback outputs finite when the given height is invalid.
FALLBACK_COM_HEIGHT_M = 0.8
#: Polygons with a smaller (convex hull) area are considered degenerate.
MIN_POLYGON_AREA_M2 = 1e-6
#: Tolerance used to accept a QP solution's polygon constraints.
CONSTRAINT_TOL_M = 1e-4
#: Upper bound on the stability weight W_s (the default W_T exp(2 omega T) overflows for tiny heights).
MAX_STABILITY_WEIGHT = 1e12


# --------------------------------------------------------------------------- data


class SupportPhase(Protocol):
    """What :meth:`ComMpc.solve` reads of a support: :class:`SupportInterval` or anything with these
    attributes (the planner's contact phases are passed as they are, without a copy per tick)."""

    @property
    def t_start_s(self) -> float: ...

    @property
    def t_end_s(self) -> float: ...

    @property
    def polygon(self) -> np.ndarray: ...


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

    def final_capture_point_floats(self) -> tuple[float, float]:
        """:attr:`final_capture_point_xy_m` as floats (x, y): the same operations on the last waypoint's numbers."""
        _, _, coms, vels, omega = self._lists()
        (cx, cy), (vx, vy) = coms[-1], vels[-1]
        return cx + vx / omega, cy + vy / omega

    @property
    def t_start_s(self) -> float:
        return float(self.waypoint_times_s[0])

    @property
    def t_end_s(self) -> float:
        return float(self.waypoint_times_s[-1])

    def cop_at(self, t_s: ArrayLike) -> FloatArray:
        """CoP [m] at time(s) ``t_s``: shape (2,) for a scalar, (T, 2) for an array."""
        if isinstance(t_s, float) and t_s == t_s and len(self.waypoint_times_s) > 1:
            return self._cop_at_scalar(t_s)
        return self._cop_at_array(t_s)

    def _cop_at_array(self, t_s: ArrayLike) -> FloatArray:
        """:meth:`cop_at` with numpy's ``interp``."""
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

    def _lists(self) -> tuple[list, list, list, list, float]:
        """The arrays as Python floats and ω, once per solution (the same numbers)."""
        lists = self.__dict__.get("_float_lists")
        if lists is None:
            lists = (self.waypoint_times_s.tolist(), self.waypoints_xy_m.tolist(),
                     self.waypoint_com_xy_m.tolist(), self.waypoint_com_vel_xy_mps.tolist(), self.omega_rps)
            object.__setattr__(self, "_float_lists", lists)
        return lists

    def _cop_at_scalar(self, t: float) -> FloatArray:
        """:meth:`cop_at` for one (non-NaN) time, on floats: numpy's ``interp`` arithmetic (its clamping outside
        the waypoints, exact waypoint values at their times, its NaN fallbacks), the same numbers."""
        return np.array(self.cop_at_floats(t))

    def cop_at_floats(self, t: float) -> tuple[float, float]:
        """:meth:`cop_at` of one time as floats (x, y): the numbers of its array, for callers that read them as
        floats (numpy's ``interp`` on floats for a non-NaN float time and at least two waypoints, as :meth:`cop_at`)."""
        if not (isinstance(t, float) and t == t and len(self.waypoint_times_s) > 1):
            x, y = self._cop_at_array(t).tolist()
            return x, y
        times, wps, _, _, _ = self._lists()
        n = len(times)
        if t > times[-1]:
            x, y = wps[-1]
            return x, y
        if t < times[0]:
            x, y = wps[0]
            return x, y
        j = bisect.bisect_right(times, t) - 1
        if j >= n - 1 or times[j] == t:
            x, y = wps[j]
            return x, y
        h = times[j + 1] - times[j]
        out = []
        for a, b in zip(wps[j], wps[j + 1]):
            slope = (b - a) / h
            value = slope * (t - times[j]) + a
            if value != value:  # NaN: try from the other end
                value = slope * (t - times[j + 1]) + b
                if value != value and a == b:
                    value = a
            out.append(value)
        x, y = out
        return x, y

    def _com_at_scalar(self, t: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """:meth:`com_at` for one time, on floats (the controller asks several times a tick)."""
        (px, py), (vx, vy), (ax, ay) = self.com_at_floats(t)
        out = np.array([[px, py], [vx, vy], [ax, ay]])  # one array, its rows returned (disjoint views)
        return out[0], out[1], out[2]

    def com_at_floats(self, t: float) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
        """:meth:`com_at` of one time as floats, ((x, y), (ẋ, ẏ), (ẍ, ÿ)): the numbers of its arrays, for callers
        that read them as floats."""
        times, wps, coms, vels, omega = self._lists()
        n_seg = len(times) - 1
        t_first, t_last = times[0], times[-1]
        j = min(max(bisect.bisect_right(times, t) - 1, 0), n_seg - 1)
        if t > t_last:
            anchor, sx, sy = n_seg, 0.0, 0.0
        else:
            anchor = j
            if t < t_first:
                sx = sy = 0.0
            else:
                h = max(times[j + 1] - times[j], 1e-12)
                sx = (wps[j + 1][0] - wps[j][0]) / h
                sy = (wps[j + 1][1] - wps[j][1]) / h
        s = t - times[anchor]
        ch, sh = math.cosh(omega * s), math.sinh(omega * s)
        px, py = wps[anchor]
        cx, cy = coms[anchor]
        vx, vy = vels[anchor]
        ex, ey = cx - px, cy - py
        dex, dey = vx - sx, vy - sy
        errx, erry = ex * ch + dex * sh / omega, ey * ch + dey * sh / omega
        return ((px + sx * s + errx, py + sy * s + erry), (sx + ex * omega * sh + dex * ch, sy + ey * omega * sh + dey * ch),
                (omega * omega * errx, omega * omega * erry))

    def com_path(self, dt_s: float = 0.02) -> tuple[FloatArray, FloatArray]:
        """Sample the planned CoM for drawing: ``(times_s (T,), com_xy_m (T, 2))``."""
        dt = max(float(dt_s), 1e-4) if math.isfinite(dt_s) else 0.02
        n = max(int(math.ceil((self.t_end_s - self.t_start_s) / dt)), 1)
        times = np.linspace(self.t_start_s, self.t_end_s, n + 1)
        return times, self.com_at(times)[0]
