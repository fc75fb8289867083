"""LA-DPP: locally approximated determinantal-point-process subset sampling (§IV-D, Eqs. 9–13).

With a squared-exponential kernel k(x, x') = exp(−β d(x, x')²) and β ≫ 1 the DPP's greedy step
x* = argmax (1 − kᵀK⁻¹k) det K reduces to x* = argmin Σ_i k(x, x_i) over the points already chosen
(Eq. 13): each new point is the one least covered by the chosen ones. Above ``chunk`` points the set is
divided (divide and conquer): a random chunk is drawn and the greedy selection runs inside it.

Training draws two batches per iteration (a quarter of its CPU time as plain numpy), so the greedy loop is
compiled (numba): per step one call computes the exponents −β d² to the newest point, numpy's vectorised exp takes
them, and the next call adds them to the scores and picks the next point. Exponents below −708 (results that would
be subnormal or zero, where numpy's exp takes a slow path 5–25× longer: most of the mocap domain's pairs) are kept
out of the vectorised exp: below −746 exp is +0.0 and adds nothing, in between the compiled call takes its own exp.
The random draws stay in numpy, in the same order. Dot products and exps may differ from the numpy loop it replaced
in the last bit, which can only pick another of two points whose scores agree to ~1e-16 (partly covered exact
duplicates): the chosen indices are that loop's on G1's hand/elbow features, mocap-like and underflowing features
(the loop is kept in ``tests/humanoid_arm/test_fast_kernels.py``), and ``studio train-arms`` writes bit-identical
weights for G1 and TALOS.
"""

from __future__ import annotations

import math

import numba
import numpy as np

BETA = 100.0
CHUNK = 10_000
_EXP_NORMAL_MIN = -708.0  # exp of anything above is a normal float64 (numpy's fast path)
_EXP_ZERO_BELOW = -746.0  # exp of anything below rounds to +0.0: adding it changes no score


@numba.njit(cache=True, nogil=True)
def _exponents(xt: np.ndarray, sq: np.ndarray, j: int, beta: float, a: np.ndarray, fast: np.ndarray) -> None:
    """a_i = −β max(|x_i|² + |x_j|² − 2 x_i·x_j, 0) for every column of ``xt`` (D, N); ``fast`` = a where its exp
    is a normal number, else 0 (those are taken from ``a`` by :func:`_add_and_pick`)."""
    d, n = xt.shape
    for i in range(n):
        fast[i] = 0.0
    for c in range(d):
        xj = xt[c, j]
        for i in range(n):
            fast[i] += xt[c, i] * xj
    sqj = sq[j]
    for i in range(n):
        d2 = sq[i] + sqj - 2.0 * fast[i]
        if d2 < 0.0:
            d2 = 0.0
        a[i] = -beta * d2
        fast[i] = a[i] if a[i] >= _EXP_NORMAL_MIN else 0.0


@numba.njit(cache=True, nogil=True)
def _add_and_pick(score: np.ndarray, a: np.ndarray, exp_fast: np.ndarray, j: int, xt: np.ndarray, sq: np.ndarray,
                  beta: float) -> int:
    """score_i += exp(a_i) (``exp_fast`` where a_i ≥ −708), the newest point ``j`` covered for good (inf); the next
    point is the least covered one (the first of equals, as ``np.argmin``), and its exponents go into ``a`` and
    ``exp_fast`` (to be exponentiated) for the next step."""
    best = np.inf
    best_i = 0
    for i in range(len(score)):
        ai = a[i]
        if ai >= _EXP_NORMAL_MIN:
            score[i] += exp_fast[i]
        elif ai >= _EXP_ZERO_BELOW:
            score[i] += math.exp(ai)
        if i == j:
            score[i] = np.inf
        if score[i] < best:
            best = score[i]
            best_i = i
    _exponents(xt, sq, best_i, beta, a, exp_fast)
    return best_i


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
    xt = np.ascontiguousarray(x.T)
    a, fast = np.empty(len(pool)), np.empty(len(pool))
    chosen = np.empty(m, dtype=np.int64)
    j = int(rng.integers(len(pool)))
    _exponents(xt, sq, j, float(beta), a, fast)
    for k in range(m):
        chosen[k] = j
        if k + 1 < m:
            np.exp(fast, out=fast)
            j = _add_and_pick(score, a, fast, j, xt, sq, float(beta))
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
