"""Locally weighted regression in the shared latent space with the k → 1 feasibility fallback (§IV-B).

The table is the robot-domain set (collision-free poses) and its latent codes. A query's latent code
finds its k nearest table entries; the output is their distance-weighted mean (Gaussian weights with the
k-th neighbour's distance as bandwidth). k goes from ``k_max`` down to 1 until the capsules say the pose
is collision-free; k = 1 returns a stored pose exactly (a table look-up), which is collision-free by
construction, so the output always is.

The k-NN search is a brute-force scan compiled with numba (:func:`nearest_k`): a float32 pass over the whole
table keeps the ``k + PREFILTER_EXTRA`` closest candidates, whose distances are then recomputed exactly in
float64 and sorted — the neighbours and distances of an exact float64 search (tested against scipy's k-d tree)
unless more than ``PREFILTER_EXTRA`` codes tie with the k-th within float32 rounding. Mocap codes lie away from
the robot table, so a k-d tree prunes poorly there (≈ 60 µs per query, 170–200 µs inside the run-time loop
when its nodes have left the cache); the scan is ≈ 30 µs and its cost does not depend on the query.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numba
import numpy as np
from scipy.spatial import cKDTree

PREFILTER_EXTRA = 5  # float32 candidates kept beyond k, re-ranked exactly in float64


@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def nearest_k(latents: np.ndarray, latents_t32: np.ndarray, z: np.ndarray, k: int, m: int, d32: np.ndarray,
              out_dist: np.ndarray, out_idx: np.ndarray) -> None:
    """The ``k`` nearest rows of ``latents`` (N, D) float64 to ``z`` (D,): squared distances of all rows in
    float32 from ``latents_t32`` (D, N) into the scratch ``d32`` (N,), the ``m`` ≥ k smallest kept, their
    distances recomputed in float64 and the k nearest written (nearest first) to ``out_dist`` / ``out_idx``."""
    dims, n = latents_t32.shape
    for i in range(n):
        d32[i] = 0.0
    for c in range(dims):
        zc = np.float32(z[c])
        row = latents_t32[c]
        for i in range(n):
            t = row[i] - zc
            d32[i] += t * t
    cand_d = np.full(m, np.inf, dtype=np.float32)
    cand_i = np.full(m, -1, dtype=np.int64)
    for i in range(n):  # insertion into the m best (m is small)
        s = d32[i]
        if s < cand_d[m - 1]:
            j = m - 1
            while j > 0 and cand_d[j - 1] > s:
                cand_d[j] = cand_d[j - 1]
                cand_i[j] = cand_i[j - 1]
                j -= 1
            cand_d[j] = s
            cand_i[j] = i
    exact = np.full(m, np.inf)
    for j in range(m):
        if cand_i[j] >= 0:
            acc = 0.0
            for c in range(dims):
                t = latents[cand_i[j], c] - z[c]
                acc += t * t
            exact[j] = acc
    order = np.argsort(exact, kind="mergesort")  # stable: equal distances keep the scan's (index) order
    for j in range(k):
        out_dist[j] = np.sqrt(exact[order[j]])
        out_idx[j] = cand_i[order[j]]


@dataclass
class LwrResult:
    x: np.ndarray
    k: int  # the k that was feasible
    neighbours: np.ndarray  # table indices used


class LatentLWR:
    def __init__(self, latents: np.ndarray, poses: np.ndarray, is_free: Callable[[np.ndarray], bool], k_max: int = 3):
        if len(latents) != len(poses) or len(poses) == 0:
            raise ValueError(f"LWR table: expected as many latents as poses (> 0), got {len(latents)} and {len(poses)}")
        self.latents, self.poses, self.is_free, self.k_max = latents, poses, is_free, k_max
        self._latents = np.ascontiguousarray(latents, dtype=np.float64)
        self._latents_t32 = np.ascontiguousarray(self._latents.T, dtype=np.float32)
        self._scratch = np.empty(len(latents), dtype=np.float32)
        self._m = min(k_max + PREFILTER_EXTRA, len(latents))

    @staticmethod
    def weights(dist: np.ndarray) -> np.ndarray:
        h = max(float(dist[-1]), 1e-9)
        w = np.exp(-0.5 * (dist / h) ** 2)
        return w / w.sum()

    def neighbours(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distances, table indices) of the ``k_max`` nearest latent codes, nearest first (:func:`nearest_k`)."""
        k = min(self.k_max, len(self._latents))
        dist, idx = np.empty(k), np.empty(k, dtype=np.int64)
        nearest_k(self._latents, self._latents_t32, np.asarray(z, dtype=np.float64).ravel(), k, self._m, self._scratch,
                  dist, idx)
        return dist, idx

    def neighbours_kdtree(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The same answer from scipy's k-d tree (the reference :meth:`neighbours` is tested against)."""
        dist, idx = cKDTree(self._latents).query(np.asarray(z, dtype=float).ravel(), k=self.k_max)
        return np.atleast_1d(dist), np.atleast_1d(idx)

    def blend(self, dist: np.ndarray, idx: np.ndarray, k: int) -> np.ndarray:
        """The regression with the ``k`` nearest (k = 1: the stored pose itself), feasible or not."""
        if k <= 1:
            return self.poses[idx[0]].copy()
        return self.weights(dist[:k]) @ self.poses[idx[:k]]

    def query(self, z: np.ndarray, neighbours: tuple[np.ndarray, np.ndarray] | None = None) -> LwrResult:
        """The largest feasible k (from ``k_max`` down to 1) and its pose; ``neighbours``: reuse a
        :meth:`neighbours` answer for the same ``z``."""
        dist, idx = self.neighbours(z) if neighbours is None else neighbours
        for k in range(self.k_max, 1, -1):
            x = self.blend(dist, idx, k)
            if self.is_free(x):
                return LwrResult(x, k, idx[:k])
        return LwrResult(self.poses[idx[0]].copy(), 1, idx[:1])


__all__ = ["LatentLWR", "LwrResult"]
