"""Velocity-based interpolation weights of the 9 gait samples (paper Sec. 5.3).

Given a body-frame velocity command ``v = (vx, vy, wz)`` the three-step
process of the paper produces one weight per sample (Table 3, Eqs. 8-10):

1. blend the two nearest forward / reverse / in-place samples by ``vx``
   (Eq. 8, ``vx`` clipped to ``[-x_max, x_max]``);
2. blend the two neighbouring turn / strafe samples by the polar angle
   ``β = atan2(vy / y_max, wz / yaw_max)`` ∈ [0, 2π) (Eq. 9); the samples
   sit at β = 0 (left turn), π/2 (left strafe), π (right turn) and 3π/2
   (right strafe), and the blend wraps from 3π/2 to 2π ≡ 0;
3. mix both with ``α_ts = f_soft(ρn (1 − η f_soft(|ẋn|)))`` (Eq. 10),
   ``ρn = min(‖(ẏn, θ̇n)‖, 1)``, ``ẋn = vx / x_max``.

The final weights are ``(1 − α_ts) w_fr + α_ts w_ts``: non-negative, sum to
1, at most 4 non-zero, and 1 on a sample at its own velocity.

Notes
-----
The weights are C1 in ``v`` everywhere (including vx = 0, the β wrap and
ρn → 0) except across the circle ρn = 1 while ``vx ≠ 0``: the ``min(·, 1)``
clip of ρn is only smoothed by ``f_soft`` when its argument reaches 1, i.e.
for ``vx = 0``.  This is inherent to Eq. (10) as published; the command
filter of the planner should keep that in mind (or clip commands to ρn ≤ 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "SAMPLE_NAMES",
    "SAMPLE_DISPLAY_NAMES",
    "SAMPLE_INDEX",
    "FORWARD_REVERSE_NAMES",
    "TURN_STRAFE_NAMES",
    "TURN_STRAFE_ANGLES_RAD",
    "SampleVelocities",
    "SampleBlend",
    "f_soft",
    "sample_weights",
    "sample_weight_list",
    "sample_blend",
]

SAMPLE_NAMES: tuple[str, ...] = (
    "forward_fast",
    "forward_slow",
    "in_place",
    "reverse_slow",
    "reverse_fast",
    "left_strafe",
    "right_strafe",
    "left_turn",
    "right_turn",
)
#: UI names, same order as :data:`SAMPLE_NAMES` (Table 3 of the paper).
SAMPLE_DISPLAY_NAMES: tuple[str, ...] = (
    "Forward Fast",
    "Forward Slow",
    "Step In Place",
    "Reverse Slow",
    "Reverse Fast",
    "Left Strafe",
    "Right Strafe",
    "Left Turn",
    "Right Turn",
)
SAMPLE_INDEX: dict[str, int] = {name: i for i, name in enumerate(SAMPLE_NAMES)}

#: Forward / reverse samples in increasing ``vx`` order (step 1).
FORWARD_REVERSE_NAMES: tuple[str, ...] = (
    "reverse_fast",
    "reverse_slow",
    "in_place",
    "forward_slow",
    "forward_fast",
)
#: Turn / strafe samples in increasing polar angle β (step 2).
TURN_STRAFE_NAMES: tuple[str, ...] = ("left_turn", "left_strafe", "right_turn", "right_strafe")
TURN_STRAFE_ANGLES_RAD: tuple[float, ...] = (0.0, 0.5 * math.pi, math.pi, 1.5 * math.pi)

_HALF_PI = 0.5 * math.pi
_FR_IDX = tuple(SAMPLE_INDEX[n] for n in FORWARD_REVERSE_NAMES)
_TS_IDX = tuple(SAMPLE_INDEX[n] for n in TURN_STRAFE_NAMES)


RHO_CLIP_BAND = 0.05


def soft_unit_clip(r: float) -> float:
    """min(r, 1) with the corner rounded over [1 − h, 1 + h] (h = RHO_CLIP_BAND).

    The paper clips ρn to the unit circle; the hard clip makes Eq. (10) lose C1 where a
    command crosses the circle. The quadratic blend keeps weights C1 and equals the paper's
    clip outside the band.
    """
    h = RHO_CLIP_BAND
    if r <= 1.0 - h:
        return r
    if r >= 1.0 + h:
        return 1.0
    return r - (r - (1.0 - h)) ** 2 / (4.0 * h)


def f_soft(a: float | np.ndarray) -> float | np.ndarray:
    """Smoothstep ``-2a³ + 3a²`` on [0, 1] (input clipped), zero slope at both ends."""
    if isinstance(a, (float, int)):
        return _f_soft_float(float(a))
    x = np.clip(np.asarray(a, dtype=float), 0.0, 1.0)
    out = x * x * (3.0 - 2.0 * x)
    return out if out.ndim else float(out)


def _f_soft_float(a: float) -> float:
    """:func:`f_soft` of a float (its float branch; the sampler's weights call it without the type test)."""
    a = 0.0 if a <= 0.0 else 1.0 if a >= 1.0 else a
    return a * a * (3.0 - 2.0 * a)


@dataclass(frozen=True)
class SampleVelocities:
    """Key walking velocities of a style (Table 3).

    Parameters
    ----------
    x_max_mps : float
        Forward / reverse fast speed [m/s].
    x_slow_mps : float
        Forward / reverse slow speed [m/s], ``0 < x_slow_mps < x_max_mps``.
    y_max_mps : float
        Strafe speed [m/s], > 0.
    yaw_max_radps : float
        Turn rate [rad/s], > 0.
    """

    x_max_mps: float
    x_slow_mps: float
    y_max_mps: float
    yaw_max_radps: float

    def __post_init__(self) -> None:
        vals = (self.x_max_mps, self.x_slow_mps, self.y_max_mps, self.yaw_max_radps)
        if not all(math.isfinite(float(v)) for v in vals):
            raise ValueError(f"sample velocities must be finite, got {vals!r}")
        if not 0.0 < self.x_slow_mps < self.x_max_mps:
            raise ValueError(
                f"need 0 < x_slow_mps < x_max_mps, got x_slow_mps={self.x_slow_mps!r}, "
                f"x_max_mps={self.x_max_mps!r}"
            )
        if not self.y_max_mps > 0.0:
            raise ValueError(f"y_max_mps must be > 0, got {self.y_max_mps!r}")
        if not self.yaw_max_radps > 0.0:
            raise ValueError(f"yaw_max_radps must be > 0, got {self.yaw_max_radps!r}")

    def velocity_of(self, name: str) -> tuple[float, float, float]:
        """``(vx_mps, vy_mps, wz_radps)`` of sample ``name`` (Table 3)."""
        xm, xs, ym, wm = self.x_max_mps, self.x_slow_mps, self.y_max_mps, self.yaw_max_radps
        table = {
            "forward_fast": (xm, 0.0, 0.0),
            "forward_slow": (xs, 0.0, 0.0),
            "in_place": (0.0, 0.0, 0.0),
            "reverse_slow": (-xs, 0.0, 0.0),
            "reverse_fast": (-xm, 0.0, 0.0),
            "left_strafe": (0.0, ym, 0.0),
            "right_strafe": (0.0, -ym, 0.0),
            "left_turn": (0.0, 0.0, wm),
            "right_turn": (0.0, 0.0, -wm),
        }
        try:
            vx, vy, wz = table[name]
        except KeyError:
            raise ValueError(f"unknown sample {name!r}; expected one of {SAMPLE_NAMES}") from None
        return float(vx), float(vy), float(wz)

    def as_array(self) -> np.ndarray:
        """``(9, 3)`` array of sample velocities in :data:`SAMPLE_NAMES` order."""
        return np.array([self.velocity_of(n) for n in SAMPLE_NAMES], dtype=float)

    def to_dict(self) -> dict[str, float]:
        """JSON-friendly dict of the four key velocities."""
        return {
            "x_max_mps": float(self.x_max_mps),
            "x_slow_mps": float(self.x_slow_mps),
            "y_max_mps": float(self.y_max_mps),
            "yaw_max_radps": float(self.yaw_max_radps),
        }


@dataclass(frozen=True)
class SampleBlend:
    """Step-by-step result of the 9-sample interpolation (for the UI).

    Attributes
    ----------
    weights : np.ndarray
        ``(9,)`` final weights in :data:`SAMPLE_NAMES` order.
    forward_reverse_pair : tuple[str, str]
        Samples (A, B) blended in step 1, ``vx_A <= vx_B``.
    alpha_x : float
        Eq. (8) ratio: weight of B in step 1.
    turn_strafe_pair : tuple[str, str]
        Samples (A, B) blended in step 2, ``β_A < β_B`` (β_B = 2π for the
        right strafe → left turn wrap).
    alpha_beta : float
        Eq. (9) ratio: weight of B in step 2.
    alpha_ts : float
        Eq. (10) ratio: weight of the turn/strafe blend in step 3.
    x_n, y_n, yaw_n : float
        Normalised velocities ẋn (after clipping), ẏn, θ̇n.
    beta_rad : float
        Polar angle β ∈ [0, 2π) (0 when ρn = 0).
    rho_n : float
        Clipped polar radius ρn ∈ [0, 1].
    """

    weights: np.ndarray = field(repr=False)
    forward_reverse_pair: tuple[str, str]
    alpha_x: float
    turn_strafe_pair: tuple[str, str]
    alpha_beta: float
    alpha_ts: float
    x_n: float
    y_n: float
    yaw_n: float
    beta_rad: float
    rho_n: float

    def weight_of(self, name: str) -> float:
        """Final weight of sample ``name``."""
        return float(self.weights[SAMPLE_INDEX[name]])

    def nonzero(self) -> dict[str, float]:
        """``{name: weight}`` of the samples with non-zero weight."""
        return {n: float(w) for n, w in zip(SAMPLE_NAMES, self.weights) if w != 0.0}

    def to_dict(self) -> dict[str, Any]:
        """JSON-friendly representation."""
        return {
            "weights": {n: float(w) for n, w in zip(SAMPLE_NAMES, self.weights)},
            "forward_reverse_pair": list(self.forward_reverse_pair),
            "alpha_x": self.alpha_x,
            "turn_strafe_pair": list(self.turn_strafe_pair),
            "alpha_beta": self.alpha_beta,
            "alpha_ts": self.alpha_ts,
            "x_n": self.x_n,
            "y_n": self.y_n,
            "yaw_n": self.yaw_n,
            "beta_rad": self.beta_rad,
            "rho_n": self.rho_n,
        }


def _check_eta(eta: float) -> float:
    eta = float(eta)
    if not 0.0 <= eta <= 1.0:
        raise ValueError(f"eta must be in [0, 1], got {eta!r}")
    return eta


def _blend_terms(v: Any, vel: SampleVelocities, eta: float) -> tuple:
    """Core scalar computation shared by :func:`sample_weights` and :func:`sample_blend`.

    Returns ``(i_fr, alpha_x, q, alpha_beta, alpha_ts, x_n, y_n, yaw_n, local, rho_n)``
    where ``i_fr`` indexes the lower sample of the step-1 pair in
    :data:`FORWARD_REVERSE_NAMES` and ``q`` the quadrant in
    :data:`TURN_STRAFE_NAMES`.
    """
    vx, vy, wz = v
    vx, vy, wz = float(vx), float(vy), float(wz)
    if not (math.isfinite(vx) and math.isfinite(vy) and math.isfinite(wz)):
        raise ValueError(f"velocity must be finite, got {(vx, vy, wz)!r}")
    xm, xs = float(vel.x_max_mps), float(vel.x_slow_mps)

    # Step 1 (Eq. 8): nearest forward/reverse pair by vx.
    x = -xm if vx < -xm else xm if vx > xm else vx
    if x < -xs:
        i_fr, xa, xb = 0, -xm, -xs
    elif x < 0.0:
        i_fr, xa, xb = 1, -xs, 0.0
    elif x < xs:
        i_fr, xa, xb = 2, 0.0, xs
    else:
        i_fr, xa, xb = 3, xs, xm
    alpha_x = _f_soft_float((x - xa) / (xb - xa))

    # Step 2 (Eq. 9): polar angle in the normalised (yaw, y) plane.  The angle
    # within the quadrant is measured from the quadrant's start axis so that
    # samples land exactly on α_β ∈ {0, 1} and the mirror (vy, wz) -> (-vy, -wz)
    # (β -> β + π) is exact.
    y_n = vy / float(vel.y_max_mps)
    yaw_n = wz / float(vel.yaw_max_radps)
    r = math.hypot(y_n, yaw_n)
    rho_n = soft_unit_clip(r)
    if r == 0.0:
        q, local = 0, 0.0
    elif yaw_n > 0.0 and y_n >= 0.0:
        q, local = 0, math.atan2(y_n, yaw_n)
    elif y_n > 0.0 and yaw_n <= 0.0:
        q, local = 1, math.atan2(-yaw_n, y_n)
    elif yaw_n < 0.0 and y_n <= 0.0:
        q, local = 2, math.atan2(-y_n, -yaw_n)
    else:
        q, local = 3, math.atan2(yaw_n, -y_n)
    local = 0.0 if local < 0.0 else _HALF_PI if local > _HALF_PI else local
    alpha_beta = _f_soft_float(local / _HALF_PI)

    # Step 3 (Eq. 10).
    x_n = x / xm
    alpha_ts = _f_soft_float(rho_n * (1.0 - eta * _f_soft_float(abs(x_n))))
    return i_fr, alpha_x, q, alpha_beta, alpha_ts, x_n, y_n, yaw_n, local, rho_n


def sample_weights(
    v: tuple[float, float, float] | np.ndarray, velocities: SampleVelocities, eta: float = 0.5
) -> np.ndarray:
    """Interpolation weights of the 9 samples for velocity command ``v``.

    Parameters
    ----------
    v : (vx_mps, vy_mps, wz_radps)
        Body-frame velocity command.
    velocities : SampleVelocities
        Key sample velocities of the style.
    eta : float
        Eq. (10) gain in [0, 1] reducing turn/strafe influence at high ``|vx|``.

    Returns
    -------
    np.ndarray
        ``(9,)`` weights in :data:`SAMPLE_NAMES` order, ≥ 0, summing to 1.
    """
    return np.array(sample_weight_list(v, velocities, eta))


def sample_weight_list(
    v: tuple[float, float, float] | list[float] | np.ndarray, velocities: SampleVelocities, eta: float = 0.5
) -> list[float]:
    """:func:`sample_weights` as a list of floats (the planner compares them with its last ones)."""
    eta = _check_eta(eta)
    i_fr, ax, q, ab, ats, *_ = _blend_terms(v, velocities, eta)
    w = [0.0] * 9
    k = 1.0 - ats
    w[_FR_IDX[i_fr]] = k * (1.0 - ax)
    w[_FR_IDX[i_fr + 1]] += k * ax
    if ats > 0.0:
        w[_TS_IDX[q]] += ats * (1.0 - ab)
        w[_TS_IDX[(q + 1) % 4]] += ats * ab
    return w


def sample_blend(
    v: tuple[float, float, float] | np.ndarray, velocities: SampleVelocities, eta: float = 0.5
) -> SampleBlend:
    """Like :func:`sample_weights` but with the intermediate pairs and ratios.

    Returns
    -------
    SampleBlend
        Structured result; ``.weights`` equals ``sample_weights(v, velocities, eta)``.
    """
    eta = _check_eta(eta)
    i_fr, ax, q, ab, ats, x_n, y_n, yaw_n, local, rho_n = _blend_terms(v, velocities, eta)
    weights = sample_weights(v, velocities, eta)
    beta = q * _HALF_PI + local if rho_n > 0.0 else 0.0
    if beta >= 2.0 * math.pi:
        beta = 0.0
    return SampleBlend(
        weights=weights,
        forward_reverse_pair=(FORWARD_REVERSE_NAMES[i_fr], FORWARD_REVERSE_NAMES[i_fr + 1]),
        alpha_x=float(ax),
        turn_strafe_pair=(TURN_STRAFE_NAMES[q], TURN_STRAFE_NAMES[(q + 1) % 4]),
        alpha_beta=float(ab),
        alpha_ts=float(ats),
        x_n=float(x_n),
        y_n=float(y_n),
        yaw_n=float(yaw_n),
        beta_rad=float(beta),
        rho_n=float(rho_n),
    )
