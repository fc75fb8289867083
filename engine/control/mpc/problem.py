"""One call's QP: the support schedule as constraint rows, and the condensed QP (final state eliminated,
Sherman–Morrison on the stiff stability term; Eqs. 12–14)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.control.qp_backends import QpProblem

FloatArray = NDArray[np.float64]


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
