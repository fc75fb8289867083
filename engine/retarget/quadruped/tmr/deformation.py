"""Temporal deformation s_α(t) (STMR §IV-B, Fig. 3a) and the linearly interpolated control targets LI(s_α(t_k)).

The source motion (duration T_s) is split into S equal segments; segment i lasts α_i · T_s / S seconds of
control time (α_i > 1 slows it down, α_i < 1 speeds it up). ``s_α`` maps control time to source time,
piecewise linearly; the bounds are on log2 α (default [−1, 1]: at most twice as fast or as slow).

Re-timing a flight phase changes how long the body is in the air, so the kinematic base arc (ballistic at the
source's timing, from SMR's flight stage) is no longer one gravity can make: a 1 s flight has a 1.2 m apex,
the same arc flown in 0.5 s would need 4 g. ``ballistic_flights`` re-makes the base position of every
flight of the deformed target (no foot in contact between a take-off and a landing) as the ballistic arc
between the take-off and landing positions in the deformed time — the kinematic analogue of what α does to
a real jump (apex height ∝ flight time²).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from engine.constants import GRAVITY_MPS2

DEFAULT_LOG2_BOUND = 1.0
MAX_LOG2_BOUND = 2.0


class DeformationError(ValueError):
    """Bad temporal parameters (one line: what was expected)."""


@dataclass(frozen=True)
class TemporalDeformation:
    """s_α over ``len(alpha)`` equal segments of a source lasting ``source_duration_s``."""

    alpha: tuple[float, ...]
    source_duration_s: float

    def __post_init__(self) -> None:
        a = np.asarray(self.alpha, dtype=float)
        if a.ndim != 1 or a.size < 1:
            raise DeformationError(f"alpha: expected S ≥ 1 segment scales, got shape {a.shape}")
        if not np.all(np.isfinite(a)) or np.any(a <= 0):
            raise DeformationError(f"alpha: expected positive finite scales, got {a.tolist()}")
        if not (np.isfinite(self.source_duration_s) and self.source_duration_s > 0):
            raise DeformationError(f"source_duration_s: expected > 0, got {self.source_duration_s}")

    @classmethod
    def from_log2(cls, log2_alpha, source_duration_s: float) -> "TemporalDeformation":
        return cls(tuple(float(2.0 ** b) for b in np.atleast_1d(log2_alpha)), float(source_duration_s))

    @property
    def segments(self) -> int:
        return len(self.alpha)

    @property
    def source_knots_s(self) -> np.ndarray:
        """Segment boundaries in source time (S + 1,)."""
        return np.linspace(0.0, self.source_duration_s, self.segments + 1)

    @property
    def control_knots_s(self) -> np.ndarray:
        """Segment boundaries in control time (S + 1,)."""
        seg = self.source_duration_s / self.segments
        return np.concatenate([[0.0], np.cumsum(np.asarray(self.alpha) * seg)])

    @property
    def duration_s(self) -> float:
        """Deformed duration T_α (seconds of control time)."""
        return float(self.control_knots_s[-1])

    def __call__(self, t_control_s) -> np.ndarray:
        """s_α(t): control time → source time (clamped to the motion)."""
        t = np.clip(np.asarray(t_control_s, dtype=float), 0.0, self.duration_s)
        return np.interp(t, self.control_knots_s, self.source_knots_s)

    def control_times(self, dt_s: float) -> np.ndarray:
        """Control instants t_k = k·dt covering [0, T_α] (the last one clamped onto T_α)."""
        n = int(np.floor(self.duration_s / dt_s + 1e-9))
        t = np.arange(n + 1) * dt_s
        if self.duration_s - t[-1] > 1e-9:
            t = np.append(t, self.duration_s)
        return t


def check_log2_bound(bound: float) -> float:
    """A bound B of log2 α ∈ [−B, B]; the studio allows 0 < B ≤ 2 (α between ¼ and 4)."""
    if not (np.isfinite(bound) and 0 < bound <= MAX_LOG2_BOUND):
        raise DeformationError(f"expected a log2 α bound in (0, {MAX_LOG2_BOUND:g}], got {bound:g}")
    return float(bound)


def check_segments(segments: int, frames: int, fps: float) -> int:
    """S ≥ 1, and every segment at least two source frames long."""
    if segments < 1:
        raise DeformationError(f"expected at least one segment, got {segments}")
    if frames < 2 * segments:
        raise DeformationError(
            f"expected a clip of at least two frames per segment ({2 * segments} frames for S = {segments}), "
            f"got {frames} frames ({frames / fps:.3f} s)")
    return int(segments)


def interpolate_qpos(qpos: np.ndarray, fps: float, t_source_s: np.ndarray) -> np.ndarray:
    """LI(t; q^{0:T}) for MuJoCo free-base configurations: linear in position and joints, slerp for the base
    quaternion (w,x,y,z). ``qpos`` (T, 7+n) sampled at ``fps`` from t = 0."""
    qpos = np.asarray(qpos, dtype=float)
    T = qpos.shape[0]
    x = np.clip(np.asarray(t_source_s, dtype=float) * fps, 0.0, T - 1)
    i0 = np.minimum(np.floor(x).astype(int), T - 1)
    i1 = np.minimum(i0 + 1, T - 1)
    w = (x - i0)[:, None]
    out = (1.0 - w) * qpos[i0] + w * qpos[i1]
    for k in range(len(x)):
        q0, q1 = qpos[i0[k], 3:7], qpos[i1[k], 3:7]
        out[k, 3:7] = _slerp(q0, q1, float(w[k, 0]))
    return out


def interpolate_points(points: np.ndarray, fps: float, t_source_s: np.ndarray) -> np.ndarray:
    """LI(t; p^{0:T}) of any (T, ...) array (keypoints), linear between frames."""
    points = np.asarray(points, dtype=float)
    T = points.shape[0]
    x = np.clip(np.asarray(t_source_s, dtype=float) * fps, 0.0, T - 1)
    i0 = np.minimum(np.floor(x).astype(int), T - 1)
    i1 = np.minimum(i0 + 1, T - 1)
    w = (x - i0).reshape((-1,) + (1,) * (points.ndim - 1))
    return (1.0 - w) * points[i0] + w * points[i1]


def sample_contact(contact: np.ndarray, fps: float, t_source_s: np.ndarray) -> np.ndarray:
    """Contact schedule at source times: each foot from the nearest frame, except that a sample lying strictly
    between a frame with a foot on the ground and a frame with none is airborne. Such a sample's configuration is
    interpolated towards the flight (LI), so its base is already in the air: calling it stance made a take-off
    (or landing) sample from which ``ballistic_flights`` started the arc — HopTurn on go1 at α = 0.5 had its base
    target jump 0.33 → 0.53 m in 20 ms at take-off and land 0.5 → 0.3 m in 20 ms, ahead of the robot. With this
    rule a flight runs from the source's last stance frame to its first stance frame after, as the source has it."""
    contact = np.asarray(contact, dtype=bool)
    T = contact.shape[0]
    x = np.clip(np.asarray(t_source_s, dtype=float) * fps, 0.0, T - 1)
    out = contact[np.clip(np.rint(x).astype(int), 0, T - 1)].copy()
    air = np.asarray(~contact.any(axis=1), dtype=bool)
    i0 = np.minimum(np.floor(x).astype(int), T - 1)
    i1 = np.minimum(i0 + 1, T - 1)
    between = (x - i0) > 1e-9
    out[between & (air[i0] | air[i1])] = False
    return out




def flight_intervals(contact: np.ndarray) -> list[tuple[int, int]]:
    """(take-off, landing) sample pairs around every run of samples with no foot in contact; the take-off is the
    last sample with contact before the run, the landing the first after it (runs at either end are skipped)."""
    air = np.asarray(~np.asarray(contact, dtype=bool).any(axis=1))
    out = []
    k = 0
    n = len(air)
    while k < n:
        if not air[k]:
            k += 1
            continue
        k1 = k
        while k1 < n and air[k1]:
            k1 += 1
        if k > 0 and k1 < n:
            out.append((k - 1, k1))
        k = k1
    return out


def ballistic_flights(qpos: np.ndarray, contact: np.ndarray, dt_s: float, gravity_mps2: float = GRAVITY_MPS2) -> np.ndarray:
    """The base position of each flight replaced by the ballistic arc from take-off to landing in ``dt_s``-spaced
    samples: x, y at constant velocity, z(τ) = z_a + v τ − g τ²/2 with v such that z reaches z_b at landing."""
    q = np.array(qpos, dtype=float)
    for a, b in flight_intervals(contact):
        T = (b - a) * dt_s
        tau = (np.arange(a, b + 1) - a) * dt_s
        p0, p1 = q[a, 0:3], q[b, 0:3]
        q[a: b + 1, 0:2] = p0[0:2] + np.outer(tau / T, p1[0:2] - p0[0:2])
        vz = (p1[2] - p0[2]) / T + 0.5 * gravity_mps2 * T
        q[a: b + 1, 2] = p0[2] + vz * tau - 0.5 * gravity_mps2 * tau**2
    return q


def finite_difference_qvel(model: mujoco.MjModel, qpos: np.ndarray, dt_s: float) -> np.ndarray:
    """MuJoCo qvel (T, nv) of a configuration sequence by central differences (one-sided at the ends)."""
    T = qpos.shape[0]
    qvel = np.zeros((T, model.nv))
    if T < 2:
        return qvel
    for k in range(T):
        a, b = max(k - 1, 0), min(k + 1, T - 1)
        mujoco.mj_differentiatePos(model, qvel[k], (b - a) * dt_s, qpos[a], qpos[b])
    return qvel


def _slerp(q0: np.ndarray, q1: np.ndarray, w: float) -> np.ndarray:
    if w <= 0.0:
        return q0 / np.linalg.norm(q0)
    if w >= 1.0:
        return q1 / np.linalg.norm(q1)
    d = float(np.dot(q0, q1))
    if d < 0.0:
        q1, d = -q1, -d
    if d > 0.9995:
        q = q0 + w * (q1 - q0)
        return q / np.linalg.norm(q)
    th = np.arccos(d)
    q = (np.sin((1 - w) * th) * q0 + np.sin(w * th) * q1) / np.sin(th)
    return q / np.linalg.norm(q)
