"""External force observer: the horizontal push the robot is under, from its momentum.

The horizontal linear momentum obeys ``d(m v_com)/dt = f_ground + f_ext``. With the ground
force the whole-body controller applied (its contact forces) and the measured CoM velocity,
a momentum observer (no differentiation of velocities)::

    r = K (m v_com − m v_com(0) − ∫ (f_ground + r) dt)

converges to ``f_ext`` with the time constant ``1/K``. A deadband keeps model errors (the
applied forces are the QP's, not measured ones) from showing up as phantom pushes. The CoM
MPC plans with the estimate (a constant force shifts the LIP's equilibrium: the CoM leans
into the push), and the whole-body QP's momentum equation includes it.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class ExternalForceObserver:
    """Horizontal external force (N) on the robot, estimated at the control rate."""

    def __init__(self, mass_kg: float, time_constant_s: float = 0.08, deadband_n_per_kg: float = 0.25,
                 max_n_per_kg: float = 4.0):
        self.mass_kg = float(mass_kg)
        self.gain = 1.0 / time_constant_s
        self.deadband_n = deadband_n_per_kg * mass_kg
        self.max_n = max_n_per_kg * mass_kg
        self.reset()

    def reset(self, com_vel_xy: FloatArray | None = None) -> None:
        if com_vel_xy is None:
            self._p0: tuple[float, float] | None = None
        else:
            p0 = self.mass_kg * np.asarray(com_vel_xy, dtype=float)
            self._p0 = (float(p0[0]), float(p0[1]))
        # The momentum integral and the residual on floats (x, y): the same operations, in the same
        # order, as on 2-vectors, at a fraction of numpy's per-call cost (500 Hz).
        self._integral = (0.0, 0.0)
        self._residual = (0.0, 0.0)
        self.force_n = np.zeros(2)

    def update(self, dt_s: float, com_vel_xy: FloatArray, ground_force_xy_n: FloatArray | None) -> FloatArray:
        """Advance by ``dt_s`` with the measured CoM velocity and the ground force applied over
        the last step (None: unknown, the estimate holds and the observer re-bases on it).
        Returns the deadbanded estimate."""
        m = self.mass_kg
        px, py = m * float(com_vel_xy[0]), m * float(com_vel_xy[1])
        if not (math.isfinite(px) and math.isfinite(py)):
            return self.force_n
        if self._p0 is None:
            self._p0 = (px, py)
            return self.force_n
        p0x, p0y = self._p0
        rx, ry = self._residual
        gain = self.gain
        if ground_force_xy_n is None:
            finite = False
        else:
            gx, gy = float(ground_force_xy_n[0]), float(ground_force_xy_n[1])
            finite = math.isfinite(gx) and math.isfinite(gy)
        if not finite:
            # Unknown ground force (a landing impact the QP did not plan): hold the estimate and
            # re-base the momentum integral on it, so the momentum change while holding does not
            # show up as a push when the updates resume.
            self._integral = (px - p0x - rx / gain, py - p0y - ry / gain)
            return self.force_n
        ix, iy = self._integral
        ix += (gx + rx) * dt_s
        iy += (gy + ry) * dt_s
        self._integral = (ix, iy)
        rx, ry = gain * (px - p0x - ix), gain * (py - p0y - iy)
        norm = math.sqrt(rx * rx + ry * ry)  # = np.linalg.norm of the 2-vector, bit for bit
        if norm > self.max_n:  # a fall or a collision, not a push to plan around
            scale = self.max_n / norm
            rx, ry = rx * scale, ry * scale
            norm = self.max_n
        self._residual = (rx, ry)
        if norm > self.deadband_n:
            shrink = 1.0 - self.deadband_n / norm
            self.force_n = np.array([rx * shrink, ry * shrink])
        else:
            self.force_n = np.zeros(2)
        return self.force_n

    @property
    def magnitude_n(self) -> float:
        return float(math.hypot(*self.force_n))
