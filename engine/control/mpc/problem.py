"""One call's QP: the support schedule as constraint rows, and the condensed QP (final state eliminated,
Sherman–Morrison on the stiff stability term; Eqs. 12–14)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.control.mpc.regions import _CONTAIN_TOL_M
from engine.control.mpc.warm_start import WARM_KIND_OFFSET_S
from engine.control.qp_backends import QpProblem
from engine.geometry.polygon import clip_convex_polygons, convex_hull, polygon_centroid

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


# ------------------------------------------------------- rows, reference path

_ROW_WAYPOINTS: dict[tuple[int, int], NDArray[np.intp]] = {}


def _row_waypoints(n_int: int, n_v: int) -> NDArray[np.intp]:
    """Waypoint index of each row slot: per interval ``n_v`` midpoint slots, ``2 n_v`` end slots."""
    key = (n_int, n_v)
    out = _ROW_WAYPOINTS.get(key)
    if out is None:
        out = (2 * np.arange(n_int)[:, None] + np.repeat([1, 2], [n_v, 2 * n_v])[None, :]).ravel()
        _ROW_WAYPOINTS[key] = out
    return out


def problem_numpy(geom, own, n_sup, ends_arr, t_now):  # noqa: ANN001, ANN202
    """The rows of one call's QP from its supports' geometry (numpy; :func:`problem_rows` computes the same
    numbers compiled and hands the calls whose end waypoints need a general intersection to this)."""
    n_int = len(own)
    # End waypoints: C_k ∩ C_k+1.  Consecutive supports nest in walking (a foot inside
    # the double-support hull): the intersection is the inner polygon.  Otherwise both
    # polygons' rows are stacked (clipped only for the centroid and the empty check).
    nrm, off, hull, cent = geom.normals, geom.offsets, geom.hull, geom.centroids
    nxt = np.append(own[1:], own[-1])
    switch = nxt != own  # the interval closes its support
    if n_sup > 1:
        # max over (half-plane of one polygon, vertex of the other) of the signed distance
        inner_b = ((nrm[:-1, :, None].conj() * hull[1:, None, :]).real - off[:-1, :, None]).max(axis=(1, 2))
        inner_a = ((nrm[1:, :, None].conj() * hull[:-1, None, :]).real - off[1:, :, None]).max(axis=(1, 2))
        pair = np.minimum(own, n_sup - 2)
        in_a = inner_a[pair] <= _CONTAIN_TOL_M  # C_k ⊂ C_k+1: the intersection is C_k
        in_b = inner_b[pair] <= _CONTAIN_TOL_M  # C_k+1 ⊂ C_k: it is C_k+1
        use_b = switch & ~in_a
        use_a = ~(use_b & in_b)
    else:
        use_a, use_b = np.ones(n_int, bool), np.zeros(n_int, bool)
    end_centroids = np.where(use_a, cent[own], cent[nxt])
    empty = False
    for i in np.flatnonzero(use_a & use_b):  # general overlap (rare)
        k = own[i]
        hull_a = convex_hull(np.stack([hull[k].real, hull[k].imag], axis=1))
        hull_b = convex_hull(np.stack([hull[k + 1].real, hull[k + 1].imag], axis=1))
        inter = clip_convex_polygons(hull_a, hull_b)
        if len(inter) == 0:  # fall back to C_k alone
            use_b[i] = False
            empty = True
        else:
            c = polygon_centroid(inter)
            end_centroids[i] = c[0] + 1j * c[1]

    # Rows, per interval: V midpoint slots (C_k), then 2V end slots (C_k, C_k+1);
    # unused slots (+inf offsets) are dropped.
    n_v = off.shape[1]
    off_all = np.concatenate(
        [off[own], np.where(use_a[:, None], off[own], np.inf), np.where(use_b[:, None], off[nxt], np.inf)], axis=1
    ).ravel()
    nrm_all = np.concatenate([nrm[own], nrm[own], nrm[nxt]], axis=1).ravel()
    keep = off_all < np.inf
    wp_all = _row_waypoints(n_int, n_v)

    times = np.empty(2 * n_int + 1)
    times[0] = t_now
    times[2::2] = ends_arr
    times[1::2] = 0.5 * (times[0:-1:2] + ends_arr)
    centroids = np.empty(2 * n_int + 1, np.complex128)
    centroids[0] = cent[own[0]]
    centroids[1::2] = cent[own]
    centroids[2::2] = end_centroids
    final = cent[own[-1]]
    nrm_c = nrm_all[keep]
    row_wp = wp_all[keep]
    problem = _Problem(
        times,
        ends_arr,
        nrm_c.view(np.float64).reshape(-1, 2),
        nrm_c,
        times[row_wp] + WARM_KIND_OFFSET_S * (row_wp & 1),
        off_all[keep],
        row_wp,
        centroids.view(np.float64).reshape(-1, 2),
        np.array([final.real, final.imag]),
        empty,
    )
    return problem
