"""The CoM MPC's input state: the usual floats taken fast, anything else made finite and flagged."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.control.mpc.types import FALLBACK_COM_HEIGHT_M

FloatArray = NDArray[np.float64]
FLOAT64_DTYPE = np.dtype(np.float64)  # (compared by identity first: a dtype compared with a type converts it each time)


def state_floats(t_now_s: object, com_xy_m: object, com_vel_xy_mps: object, cop_xy_m: object,
                  com_height_m: object) -> tuple[float, float, float, float, float, float, float, float] | None:
    """The usual input of :meth:`ComMpc.solve` as floats ``(t, com, vel, cop, height)``: a finite time and height
    above 1 mm (Python or numpy floats) and finite float arrays (2,), the numbers :func:`sanitize_state` passes
    on; None for anything else (:func:`sanitize_state` then handles it)."""
    scalar = (float, int, np.float64, np.float32)
    if type(t_now_s) not in scalar or type(com_height_m) not in scalar:
        return None
    values = [float(t_now_s)]  # type: ignore[arg-type]
    for v in (com_xy_m, com_vel_xy_mps, cop_xy_m):
        if type(v) is not np.ndarray or (v.dtype is not FLOAT64_DTYPE and v.dtype != np.float64) or v.shape != (2,):
            return None
        values += v.tolist()
    height = float(com_height_m)  # type: ignore[arg-type]
    values.append(height)
    if not height > 1e-3:
        return None
    if not math.isfinite(sum(values)) and not all(math.isfinite(x) for x in values):  # (a finite sum can overflow)
        return None
    return tuple(values)  # type: ignore[return-value]


def sanitize_state(
    t_now_s: float, com_xy_m: ArrayLike, com_vel_xy_mps: ArrayLike, cop_xy_m: ArrayLike, com_height_m: float
) -> tuple[float, FloatArray, FloatArray, FloatArray, float, bool]:
    """Finite versions of the inputs and whether the originals were all valid."""

    def vec2(v: ArrayLike) -> tuple[FloatArray, bool]:
        if type(v) is np.ndarray and v.dtype == np.float64 and v.shape == (2,):  # the usual case, fast
            x, y = v.tolist()
            if math.isfinite(x) and math.isfinite(y):
                return v.copy(), True
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
