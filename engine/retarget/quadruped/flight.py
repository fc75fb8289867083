"""Flight phases (§V-C): exit velocity from a polynomial fit of the base history, then ballistic flight."""

from __future__ import annotations

import numpy as np

from engine.constants import GRAVITY_MPS2

GRAVITY_VECTOR_MPS2 = np.array([0.0, 0.0, -GRAVITY_MPS2])


def exit_velocity(base_history: np.ndarray, dt: float, horizon: int = 6) -> np.ndarray:
    """Derivative at the last sample of a polynomial fitted to the last ``horizon`` base positions.

    The degree follows the available history (clipped by the horizon): 1 sample → zero velocity,
    2 → a line, ≥ 3 → a quadratic.
    """
    hist = np.asarray(base_history, dtype=float)[-horizon:]
    n = len(hist)
    if n < 2:
        return np.zeros(3)
    deg = min(n - 1, 2)
    t = (np.arange(n) - (n - 1)) * dt  # last sample at t = 0
    coeffs = np.polyfit(t, hist, deg)  # (deg+1, 3), highest power first
    return coeffs[-2].copy()  # d/dt at t = 0 is the linear coefficient


def landing_exit_velocity_z(ref_base_z: np.ndarray, dt: float, g: float = GRAVITY_MPS2) -> float:
    """Vertical exit velocity of a ballistic arc that lands when the contact schedule says it does.

    ``ref_base_z`` is the reference base height from the last contact frame to the landing frame
    (n + 1 samples); the discrete flight z_k = z_{k−1} + v_k Δt, v_{k+1} = v_k − g Δt then reaches the
    reference's height change exactly at the landing frame.
    """
    n = len(ref_base_z) - 1
    if n < 1:
        return 0.0
    dz = float(ref_base_z[-1] - ref_base_z[0])
    return (dz + g * dt * dt * n * (n - 1) / 2.0) / (n * dt)
