"""Exact linear-inverted-pendulum propagation under a piecewise-linear CoP (Eq. 11)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.control.mpc.kernels import lip_propagate, lip_segments


FloatArray = NDArray[np.float64]


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
        """Compiled (:func:`engine.control.mpc.kernels.lip_segments`); :meth:`build_numpy` is the reference."""
        h, a, b, grow = lip_segments(np.ascontiguousarray(times_s, dtype=np.float64), float(omega))
        return _Segments(omega, h, a, b, grow)

    @staticmethod
    def build_numpy(times_s: FloatArray, omega: float) -> _Segments:
        h = times_s[1:] - times_s[:-1]
        wh = omega * h
        one_minus_e = -np.expm1(-wh)
        r = np.where(wh > 1e-9, one_minus_e / np.maximum(wh, 1e-9), 1.0 - 0.5 * wh)  # -> 1 as h -> 0
        grow = np.exp(omega * (times_s - times_s[0]))
        return _Segments(omega, h, 1.0 - r, r - (1.0 - one_minus_e), grow)

    def propagate(
        self, cop_xy_m: FloatArray, com_xy_m: FloatArray, com_vel_xy_mps: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """CoM position and velocity at every waypoint time (closed form, see module docstring); compiled
        (:func:`engine.control.mpc.kernels.lip_propagate`), :meth:`propagate_numpy` is the reference."""
        return lip_propagate(float(self.omega), self.a, self.b, self.grow, np.ascontiguousarray(cop_xy_m, dtype=np.float64),
                             np.ascontiguousarray(com_xy_m, dtype=np.float64).reshape(2),
                             np.ascontiguousarray(com_vel_xy_mps, dtype=np.float64).reshape(2))

    def propagate_numpy(
        self, cop_xy_m: FloatArray, com_xy_m: FloatArray, com_vel_xy_mps: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
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
