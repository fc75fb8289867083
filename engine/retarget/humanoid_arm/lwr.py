"""Locally weighted regression in the shared latent space with the k → 1 feasibility fallback (§IV-B).

The table is the robot-domain set (collision-free poses) and its latent codes. A query's latent code
finds its k nearest table entries; the output is their distance-weighted mean (Gaussian weights with the
k-th neighbour's distance as bandwidth). k goes from ``k_max`` down to 1 until the capsules say the pose
is collision-free; k = 1 returns a stored pose exactly (a table look-up), which is collision-free by
construction, so the output always is.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.spatial import cKDTree


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
        self.tree = cKDTree(latents)

    @staticmethod
    def weights(dist: np.ndarray) -> np.ndarray:
        h = max(float(dist[-1]), 1e-9)
        w = np.exp(-0.5 * (dist / h) ** 2)
        return w / w.sum()

    def neighbours(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(distances, table indices) of the ``k_max`` nearest latent codes, nearest first."""
        dist, idx = self.tree.query(np.asarray(z, dtype=float).ravel(), k=self.k_max)
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
