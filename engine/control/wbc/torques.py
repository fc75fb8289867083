"""Joint torques of a solved whole-body QP (Eq. 15), in numpy.

The QP's q̈ and ρ satisfy the centroidal equality (Eq. 21); the floating base's six rows of Eq. 15 are then
solved exactly for q̈_base (6×6, in place in q̈), so that q̈ is consistent with the rigid-body dynamics, and
the joint rows give τ = M_j q̈ + h_j − Σ J_c,jᵀ f_c, plus the model's viscous joint damping (MuJoCo applies
it too). The compiled tick does the same in :func:`engine.control.wbc.kernels.finish_tick`; these are its
reference and its fallback when the base block is not positive definite (LU instead of Cholesky).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.linalg.lapack import dposv as _dposv

from engine.control.wbc.tasks import DynamicsSnapshot

FloatArray = NDArray[np.float64]


def joint_torques(snap: DynamicsSnapshot, tau_map: FloatArray, qdd: FloatArray, rho: FloatArray,
                  joint_damping: FloatArray | None) -> FloatArray:
    """Eq. 15: the base rows solved for q̈_base (written into ``qdd[:6]``), then the joint torques.
    ``tau_map``: (nv, 32) the generalised force −Σ J_cᵀ B_c per unit ρ (numpy: the reference of
    :func:`engine.control.wbc.kernels.finish_tick`)."""
    m = snap.mass_matrix
    contact_gen = tau_map @ rho  # −Σ J_cᵀ f_c
    rhs = -(m[:6, 6:] @ qdd[6:]) - snap.nonlinear_effects[:6] - contact_gen[:6]
    _, base, info = _dposv(m[:6, :6], rhs)  # the base block of M is symmetric positive definite
    qdd[:6] = base if info == 0 else np.linalg.solve(m[:6, :6], rhs)
    tau = m[6:] @ qdd + snap.nonlinear_effects[6:] + contact_gen[6:]
    if joint_damping is not None:  # the model's viscous joint damping (MuJoCo applies it too)
        tau += joint_damping * snap.v[6:]
    return tau


def joint_torques_lu(snap: DynamicsSnapshot, qdd: FloatArray, base_rhs: FloatArray, contact_gen: FloatArray,
                     joint_damping: FloatArray | None) -> FloatArray:
    """Eq. 15 after :func:`engine.control.wbc.kernels.finish_tick` found the base block not positive definite:
    q̈_base by LU from its right-hand side ``base_rhs`` (written into ``qdd[:6]``), then the joint torques
    (``contact_gen``: −Σ J_cᵀ f_c, all nv rows, as the kernel returned it)."""
    m = snap.mass_matrix
    qdd[:6] = np.linalg.solve(m[:6, :6], base_rhs)
    return m[6:] @ qdd + snap.nonlinear_effects[6:] + contact_gen[6:] + (
        np.zeros(m.shape[0] - 6) if joint_damping is None else joint_damping * snap.v[6:])
