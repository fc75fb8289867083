"""The outer loop of TMR (STMR §VI, Eqs. 15–18): Bayesian optimisation of the temporal parameters.

A Gaussian process with a Matérn kernel (ν = 5/2) is fitted to the scores seen so far and the next α maximises
expected improvement — both from the maintained ``bayesian-optimization`` library. The kernel's length scale is
kept ≥ ``length_scale_min_log2`` (0.1 in log2 α, a 7 % change of duration): TMR's scores are a step (a replay
that stands scores about −0.1, one that falls −1 to −3), and on four or five such points the library's
maximum-likelihood fit drove the length scale to its floor of 10⁻⁵ — a GP that is white noise, flat mean and
unit spread everywhere between the data, so EI's suggestion was a random point of the box (go1 HopTurn: α = 1.68,
a 3.7 s solve that fell, beside the one α that stood, 0.5). With the floor the GP interpolates and EI looks
beside the best point first. The search runs in log2 α
(bounds [−B, B] per segment) and stops when the budget is spent or when the suggestions have settled on the best
point (convergence).

The warm start (``initial_design``) is the identity α = 1, then the lower bound in every segment (log2 α = −B:
the motion shortened to 2^−B of its duration, played faster, its ballistic flights lower) and the upper bound
(+B: lengthened), then the uniform probes inside the bounds (every segment at −B/2, then +B/2), then random
samples (the paper's random warm start). The bounds come first because EI rarely proposes them from a few
interior points, and the bound is where the motions that are too much for the robot are solved: go1 HopTurn /
SideSteps track at α = 0.5 and fall at α ≈ 0.59, and a warm start of α = 1, 0.73, 1.21 with three EI proposals
never got there (issue 10, third round). The inner probes give the GP a point between the identity and each
bound on the uniform diagonal, which random samples in S > 1 dimensions seldom come near.

A suggestion within ``duplicate_log2`` (max-norm) of a point already evaluated is not evaluated (the inner solve is
deterministic, and a re-timing that close — 2^0.02 − 1 = 1.4 % of a segment's duration — differs in the score's α
term by under 0.002: such a solve would cost a whole tracking and could not improve the result by more than its
noise); it counts as a settled step, so a search whose acquisition keeps returning to the best point's
neighbourhood converges instead of spending its budget there. (With 10⁻³ the search of go1 HopTurn spent its
fourth evaluation on α = 0.5035 beside the best α = 0.5: a 1.34 s solve that fell, issue 10 fourth round.)

Evaluations run in parallel batches on an executor (``engine.retarget.quadruped.tmr.ray_jobs``): while a batch
is out, the pending points are registered with a constant lie (the median score so far — the worst one, with
falls scoring −1 to −3 against ~0 for a standing replay, sent the next proposals far away) so that the next
suggestions spread out instead of repeating. Every evaluation reports progress (k of N, best score, current α)
and the search can be cancelled between evaluations.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from engine.retarget.quadruped.tmr.ddp import Cancelled


@dataclass
class BOSettings:
    budget: int = 10  # evaluations at most
    init_points: int = 3  # warm start: the identity, log2 α = −B, +B, −B/2, +B/2 in every segment, then random points
    parallel: int = 1  # evaluations in flight at once
    xi: float = 0.05  # exploration of expected improvement (Eq. 18)
    noise: float = 1e-3  # GP observation noise (normalised scores): tracking scores are not smooth in α
    convergence_log2: float = 0.05  # suggestions within this of the best point count as "settled"
    patience: int = 3  # settled suggestions in a row without improvement → converged
    length_scale_min_log2: float = 0.1  # the Matérn length scale's lower bound (log2 α units; the library's: 1e-5)
    duplicate_log2: float = 0.02  # a suggestion this close (max-norm) to an evaluated point is not evaluated
    seed: int = 0


@dataclass
class BOProgress:
    evaluation: int  # evaluations finished
    budget: int
    best_score: float
    best_log2_alpha: np.ndarray
    current_log2_alpha: np.ndarray  # the point just evaluated
    stage: str = ""  # "widened": TMR's second search over a wider bound (tmr.temporal_retarget)


@dataclass
class BOResult:
    best_log2_alpha: np.ndarray
    best_score: float
    best_payload: Any
    history: list[tuple[np.ndarray, float]] = field(default_factory=list)
    converged: bool = False
    payloads: list[Any] = field(default_factory=list)  # one per history entry

    @property
    def evaluations(self) -> int:
        return len(self.history)


def _keys(dims: int) -> list[str]:
    return [f"b{i:02d}" for i in range(dims)]


def _suggest(dims: int, bound: float, observed: list[tuple[np.ndarray, float]], pending: list[np.ndarray],
             settings: BOSettings, rng: np.random.Generator) -> np.ndarray:
    from bayes_opt import BayesianOptimization, acquisition
    from sklearn.gaussian_process.kernels import Matern

    keys = _keys(dims)
    opt = BayesianOptimization(
        f=None, pbounds={k: (-bound, bound) for k in keys},
        acquisition_function=acquisition.ExpectedImprovement(xi=settings.xi),
        random_state=int(rng.integers(2**31)), verbose=0, allow_duplicate_points=True)
    opt.set_gp_params(alpha=settings.noise, kernel=Matern(
        nu=2.5, length_scale=max(1.0, settings.length_scale_min_log2),
        length_scale_bounds=(settings.length_scale_min_log2, 1e5)))
    lie = float(np.median([s for _, s in observed]))
    for x, s in observed:
        opt.register(params=dict(zip(keys, map(float, x))), target=float(s))
    for x in pending:
        opt.register(params=dict(zip(keys, map(float, x))), target=float(lie))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # sklearn's GP convergence notes on tiny data sets
        params = opt.suggest()
    return np.array([params[k] for k in keys], dtype=float)


def initial_design(dims: int, bound: float, points: int, rng: np.random.Generator) -> list[np.ndarray]:
    """The warm start: the identity, every segment at −bound (shortened), at +bound (lengthened), at −bound/2, at
    +bound/2 (the uniform probes on and inside the bounds), then uniform random points."""
    b = float(bound)
    probes = [np.zeros(dims), np.full(dims, -b), np.full(dims, b), np.full(dims, -b / 2), np.full(dims, b / 2)]
    n = max(int(points), 1)
    return probes[:n] + [rng.uniform(-b, b, dims) for _ in range(n - len(probes))]


def bayes_optimise(evaluate_submit: Callable[[np.ndarray], Any], collect: Callable[[list[Any]], list[tuple[Any, float, Any]]],
                   dims: int, bound: float, settings: BOSettings | None = None,
                   progress: Callable[[BOProgress], None] | None = None,
                   cancel: Callable[[], bool] | None = None, abort: Callable[[list[Any]], None] | None = None,
                   known: Sequence[tuple[np.ndarray, float, Any]] = (),
                   warm_start: Sequence[np.ndarray] | None = None) -> BOResult:
    """Maximise a score of log2 α ∈ [−bound, bound]^dims.

    ``evaluate_submit(x)`` starts an evaluation and returns a handle; ``collect(handles)`` blocks until at least one
    is done and returns ``(handle, score, payload)`` for each finished one; ``abort(handles)`` cancels running ones.
    ``known``: evaluations already made (``(x, score, payload)``, e.g. a search over a narrower bound), which the GP
    starts from and the result includes; ``settings.budget`` then counts the new evaluations. ``warm_start``: the
    first points to evaluate instead of :func:`initial_design`'s.
    """
    settings = settings or BOSettings()
    if settings.budget < 1:
        raise ValueError("budget must be ≥ 1")
    rng = np.random.default_rng(settings.seed)
    warm = (list(warm_start) if warm_start is not None
            else initial_design(dims, bound, settings.init_points, rng))
    observed: list[tuple[np.ndarray, float]] = [(np.asarray(x, float), float(s)) for x, s, _ in known]
    payloads: list[Any] = [p for _, _, p in known]
    total = len(observed) + settings.budget  # what the progress reports count to
    running: dict[Any, np.ndarray] = {}
    submitted = 0
    settled = 0
    converged = False
    repeats = 0  # suggestions that duplicated an evaluated point (not evaluated again)

    def next_point() -> np.ndarray:
        if submitted < len(warm):
            return warm[submitted]
        if not observed:  # still waiting for the warm start: spread at random
            return rng.uniform(-bound, bound, dims)
        return _suggest(dims, bound, observed, list(running.values()), settings, rng)

    try:
        while True:
            if cancel is not None and cancel():
                raise Cancelled()
            while not converged and submitted < settings.budget and len(running) < max(settings.parallel, 1):
                x = np.clip(next_point(), -bound, bound)
                if observed and submitted >= len(warm):
                    best_x = observed[int(np.argmax([s for _, s in observed]))][0]
                    settled = settled + 1 if np.max(np.abs(x - best_x)) < settings.convergence_log2 else 0
                    near = [y for y in [*(y for y, _ in observed), *running.values()]
                            if np.max(np.abs(x - y)) < settings.duplicate_log2]
                    if near:  # already evaluated (or under way): no second solve of the same α
                        repeats += 1
                        settled = max(settled, repeats)
                        if settled >= settings.patience:
                            converged = True
                        elif running:
                            break  # wait for the running evaluations: the GP learns something new first
                        continue
                running[evaluate_submit(x)] = x
                submitted += 1
            if not running:
                break
            for handle, score, payload in collect(list(running)):
                x = running.pop(handle)
                score = float(score) if np.isfinite(score) else -1e9
                observed.append((x, score))
                payloads.append(payload)
                best_i = int(np.argmax([s for _, s in observed]))
                if progress is not None:
                    progress(BOProgress(len(observed), total, observed[best_i][1], observed[best_i][0].copy(), x.copy()))
            if settled >= settings.patience:
                converged = True
    except BaseException:
        if abort is not None and running:
            abort(list(running))
        raise
    best_i = int(np.argmax([s for _, s in observed]))
    return BOResult(observed[best_i][0], observed[best_i][1], payloads[best_i], observed, converged, payloads)
