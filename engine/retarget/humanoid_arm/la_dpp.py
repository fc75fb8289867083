"""LA-DPP: locally approximated determinantal-point-process subset sampling (§IV-D, Eqs. 9–13).

With a squared-exponential kernel k(x, x') = exp(−β d(x, x')²) and β ≫ 1 the DPP's greedy step
x* = argmax (1 − kᵀK⁻¹k) det K reduces to x* = argmin Σ_i k(x, x_i) over the points already chosen
(Eq. 13): each new point is the one least covered by the chosen ones. Above ``chunk`` points the set is
divided (divide and conquer): a random chunk is drawn and the greedy selection runs inside it.
"""

from __future__ import annotations

import numpy as np

BETA = 100.0
CHUNK = 10_000


def la_dpp_indices(features: np.ndarray, m: int, rng: np.random.Generator, beta: float = BETA,
                   chunk: int = CHUNK) -> np.ndarray:
    """Indices of ``m`` well-spread points of ``features`` (N, D), chosen greedily by Eq. 13."""
    n = len(features)
    if m >= n:
        return rng.permutation(n)
    pool = rng.choice(n, size=chunk, replace=False) if n > chunk else np.arange(n)
    x = np.asarray(features[pool], dtype=np.float64)
    sq = np.einsum("ij,ij->i", x, x)
    # tiny jitter breaks ties between equally uncovered points at random
    score = rng.uniform(0.0, 1e-12, size=len(pool))
    chosen = np.empty(m, dtype=np.int64)
    j = int(rng.integers(len(pool)))
    for k in range(m):
        chosen[k] = j
        d2 = np.maximum(sq + sq[j] - 2.0 * (x @ x[j]), 0.0)
        score += np.exp(-beta * d2)
        score[j] = np.inf
        if k + 1 < m:
            j = int(np.argmin(score))
    return pool[chosen]


class BatchSampler:
    """Mini-batches for training: LA-DPP (``la_dpp=True``) or uniform at random."""

    def __init__(self, features: np.ndarray, batch_size: int, rng: np.random.Generator, la_dpp: bool = True,
                 beta: float = BETA, chunk: int = CHUNK):
        self.features, self.batch_size, self.rng = features, batch_size, rng
        self.la_dpp, self.beta, self.chunk = la_dpp, beta, chunk

    def __call__(self) -> np.ndarray:
        n = len(self.features)
        if not self.la_dpp:
            return self.rng.integers(n, size=self.batch_size)
        return la_dpp_indices(self.features, self.batch_size, self.rng, self.beta, self.chunk)


__all__ = ["la_dpp_indices", "BatchSampler", "BETA", "CHUNK"]
