"""The whole-body reference between planner ticks in one compiled call.

The planner runs every ``TICKS_PER_PLAN`` control ticks; the ticks in between move its reference on by the time
since (:meth:`engine.control.walking_controller.WalkingController._wbc_reference`): the CoM MPC's plan at that
time (the exact LIP solution, :meth:`engine.control.mpc.types.ComMpcSolution.com_at_floats`), the feet's positions
along their velocities, the turning feet's and the pelvis' rotations along their angular velocities (Rodrigues,
then ``r @ rot``) and the upper body along its joint rates. :func:`interpolate_reference` computes all of them in
one call, with the same operations in the same order (the rotation product is BLAS's ``dgemm``, as numpy's
``dot``): the same numbers as the Python it replaces (``tests/control/test_reference_kernels.py`` compares them).
:func:`interpolate_references` does the same for all the control ticks until the planner's next one at once (what the
controller calls, once per planner tick).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _rotate(rot, wx_rate, wy_rate, wz_rate, dt):  # noqa: ANN001, ANN201
    """``rot`` advanced by a world angular velocity for ``dt`` (what ``walking_controller._rotate`` computed): ``rot`` itself
    when ``dt`` is 0 or the angle below 1e-12."""
    if dt == 0.0:
        return rot
    wx, wy, wz = wx_rate * dt, wy_rate * dt, wz_rate * dt
    angle = math.sqrt(wx * wx + wy * wy + wz * wz)
    if angle < 1e-12:
        return rot
    kx, ky, kz = wx / angle, wy / angle, wz / angle
    s, c = math.sin(angle), 1.0 - math.cos(angle)
    r = np.empty((3, 3))
    r[0, 0] = 1.0 - c * (ky * ky + kz * kz)
    r[0, 1] = c * kx * ky - s * kz
    r[0, 2] = c * kx * kz + s * ky
    r[1, 0] = c * kx * ky + s * kz
    r[1, 1] = 1.0 - c * (kx * kx + kz * kz)
    r[1, 2] = c * ky * kz - s * kx
    r[2, 0] = c * kx * kz - s * ky
    r[2, 1] = c * ky * kz + s * kx
    r[2, 2] = 1.0 - c * (kx * kx + ky * ky)
    return np.dot(r, rot)


@njit(cache=True, nogil=True)
def _com_at(times, wps, coms, vels, omega, t, out):  # noqa: ANN001, ANN201
    """:meth:`ComMpcSolution.com_at_floats` of the plan's arrays at ``t``, written as rows (position, velocity,
    acceleration) of ``out`` (3, 2)."""
    n = times.shape[0]
    n_seg = n - 1
    lo, hi = 0, n  # bisect.bisect_right(times, t)
    while lo < hi:
        mid = (lo + hi) // 2
        if t < times[mid]:
            hi = mid
        else:
            lo = mid + 1
    j = min(max(lo - 1, 0), n_seg - 1)
    if t > times[n - 1]:
        anchor, sx, sy = n_seg, 0.0, 0.0
    else:
        anchor = j
        if t < times[0]:
            sx = sy = 0.0
        else:
            h = max(times[j + 1] - times[j], 1e-12)
            sx = (wps[j + 1, 0] - wps[j, 0]) / h
            sy = (wps[j + 1, 1] - wps[j, 1]) / h
    s = t - times[anchor]
    ch, sh = math.cosh(omega * s), math.sinh(omega * s)
    px, py = wps[anchor, 0], wps[anchor, 1]
    ex, ey = coms[anchor, 0] - px, coms[anchor, 1] - py
    dex, dey = vels[anchor, 0] - sx, vels[anchor, 1] - sy
    errx, erry = ex * ch + dex * sh / omega, ey * ch + dey * sh / omega
    out[0, 0] = px + sx * s + errx
    out[0, 1] = py + sy * s + erry
    out[1, 0] = sx + ex * omega * sh + dex * ch
    out[1, 1] = sy + ey * omega * sh + dey * ch
    out[2, 0] = omega * omega * errx
    out[2, 1] = omega * omega * erry


@njit(cache=True, nogil=True)
def interpolate_reference(dt, t, times, wps, coms, vels, omega, foot_pos, foot_lin_vel, foot_rot, foot_ang_vel,
                          pelvis_rot, pelvis_ang_vel, upper_q, upper_qd):  # noqa: ANN001, ANN201
    """The reference ``dt`` after the planner's tick: (the plan's CoM position, velocity and acceleration at ``t``
    as rows (3, 2), the feet's positions (2, 3) and rotations (2, 3, 3), the pelvis rotation (3, 3; the planner's
    own array when it does not turn) and the upper-body joints (K,)). A foot turns when any component of its
    angular velocity is non-zero."""
    com = np.empty((3, 2))
    _com_at(times, wps, coms, vels, omega, t, com)
    pos = np.empty((2, 3))
    for i in range(2):
        for k in range(3):
            pos[i, k] = foot_pos[i, k] + foot_lin_vel[i, k] * dt
    rot = foot_rot.copy()
    if dt != 0.0:
        for i in range(2):
            w = foot_ang_vel[i]
            if w[0] != 0.0 or w[1] != 0.0 or w[2] != 0.0:
                rot[i] = _rotate(rot[i], w[0], w[1], w[2], dt)
    pelvis = _rotate(pelvis_rot, pelvis_ang_vel[0], pelvis_ang_vel[1], pelvis_ang_vel[2], dt)
    upper = np.empty(upper_q.shape[0])
    for k in range(upper_q.shape[0]):
        upper[k] = upper_q[k] + upper_qd[k] * dt
    return com, pos, rot, pelvis, upper


@njit(cache=True, nogil=True)
def _rotates(wx_rate, wy_rate, wz_rate, dt):  # noqa: ANN001, ANN201
    """Whether :func:`_rotate` computes a new rotation (not ``rot`` itself): its two early returns' tests."""
    if dt == 0.0:
        return False
    wx, wy, wz = wx_rate * dt, wy_rate * dt, wz_rate * dt
    angle = math.sqrt(wx * wx + wy * wy + wz * wz)
    return not angle < 1e-12


@njit(cache=True, nogil=True)
def interpolate_references(period, t0, times, wps, coms, vels, omega, foot_pos, foot_lin_vel, foot_rot, foot_ang_vel,
                           pelvis_rot, pelvis_ang_vel, upper_q, upper_qd, com, pos, rot, pelvis, turned,
                           upper):  # noqa: ANN001, ANN201
    """:func:`interpolate_reference` at ``dt = k · period`` and ``t = t0 + dt`` for k = 0 … n − 1 (the ticks until the
    planner's next one) in one call, written into the caller's arrays, each stacked along a first axis of n: ``com``
    (n, 3, 2), ``pos`` (n, 2, 3), ``rot`` (n, 2, 3, 3), ``pelvis`` (n, 3, 3), ``turned`` (n,) whether the pelvis
    turned (where not, :func:`interpolate_reference` returns ``pelvis_rot`` itself; its row here is a copy) and
    ``upper`` (n, K). Nothing is returned (numba boxes every returned array, which costs more than the caller's
    ``np.empty``). The same operations per k as :func:`interpolate_reference`, so the same numbers."""
    n_upper = upper_q.shape[0]
    for k in range(com.shape[0]):
        dt = k * period
        t = t0 + dt
        _com_at(times, wps, coms, vels, omega, t, com[k])
        for i in range(2):
            for j in range(3):
                pos[k, i, j] = foot_pos[i, j] + foot_lin_vel[i, j] * dt
        rot[k] = foot_rot
        if dt != 0.0:
            for i in range(2):
                w = foot_ang_vel[i]
                if w[0] != 0.0 or w[1] != 0.0 or w[2] != 0.0:
                    rot[k, i] = _rotate(rot[k, i], w[0], w[1], w[2], dt)
        pelvis[k] = _rotate(pelvis_rot, pelvis_ang_vel[0], pelvis_ang_vel[1], pelvis_ang_vel[2], dt)
        turned[k] = _rotates(pelvis_ang_vel[0], pelvis_ang_vel[1], pelvis_ang_vel[2], dt)
        for j in range(n_upper):
            upper[k, j] = upper_q[j] + upper_qd[j] * dt
