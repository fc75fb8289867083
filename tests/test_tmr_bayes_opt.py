"""The outer Bayesian optimisation (STMR Eqs. 15–18) on known functions, serial and in parallel batches."""

from __future__ import annotations

import numpy as np
import pytest

from hypothesis import given, settings
from hypothesis import strategies as st

from engine.retarget.quadruped.tmr.bayes_opt import BOSettings, bayes_optimise, initial_design
from engine.retarget.quadruped.tmr.ddp import Cancelled
from engine.retarget.quadruped.tmr.ray_jobs import LocalExecutor


def _run(f, dims: int, bound: float, settings: BOSettings, progress=None, cancel=None):  # noqa: ANN001, ANN202
    ex = LocalExecutor()

    def submit(x: np.ndarray):  # noqa: ANN202
        return ex.submit(lambda y: (f(y), y.copy()), x)

    def collect(handles):  # noqa: ANN001, ANN202
        return [(h, v[0], v[1]) for h, v in ex.collect(handles)]

    return bayes_optimise(submit, collect, dims, bound, settings, progress=progress, cancel=cancel, abort=ex.cancel)


@pytest.mark.parametrize("parallel", [1, 3])
def test_finds_the_optimum_of_a_known_1d_function_within_budget(parallel: int) -> None:
    optimum = 0.37

    def f(x: np.ndarray) -> float:
        return float(-(x[0] - optimum) ** 2 + 0.05 * np.cos(9 * x[0]))

    grid = np.linspace(-1, 1, 20001)
    true_best = grid[np.argmax([f(np.array([g])) for g in grid])]
    res = _run(f, 1, 1.0, BOSettings(budget=12, init_points=3, parallel=parallel, seed=1))
    assert res.evaluations <= 12
    assert abs(res.best_log2_alpha[0] - true_best) < 0.05
    assert res.best_payload[0] == pytest.approx(res.best_log2_alpha[0])


@pytest.mark.slow  # a 20-evaluation 2-D search; progress reports: test_progress_reports_count_the_evaluations
def test_two_segments_and_progress_reports() -> None:
    seen = []
    res = _run(lambda x: float(-np.sum((x - np.array([-0.5, 0.4])) ** 2)), 2, 1.0,
               BOSettings(budget=20, init_points=4, seed=0), progress=seen.append)
    assert np.max(np.abs(res.best_log2_alpha - np.array([-0.5, 0.4]))) < 0.15
    assert [p.evaluation for p in seen] == list(range(1, len(seen) + 1))
    assert all(p.budget == 20 for p in seen)
    assert seen[-1].best_score == pytest.approx(res.best_score)
    assert np.all(np.abs(np.array([p.current_log2_alpha for p in seen])) <= 1.0)


def test_progress_reports_count_the_evaluations() -> None:
    """Every evaluation reports k of N, the best score so far and the point just evaluated (a 4-evaluation 2-D
    search: the fast tier's check of what test_two_segments_and_progress_reports checks on a 20-evaluation one)."""
    seen = []
    evaluated = []

    def f(x: np.ndarray) -> float:
        evaluated.append(x.copy())
        return score(x)

    def score(x: np.ndarray) -> float:
        return float(-np.sum((x - np.array([-0.5, 0.4])) ** 2))

    res = _run(f, 2, 1.0, BOSettings(budget=4, init_points=3, seed=0), progress=seen.append)  # 3 designed, 1 suggested
    assert [p.evaluation for p in seen] == [1, 2, 3, 4] and res.evaluations == 4
    assert all(p.budget == 4 for p in seen)
    for k, p in enumerate(seen):
        np.testing.assert_array_equal(p.current_log2_alpha, evaluated[k])
        assert p.best_score == pytest.approx(max(score(x) for x in evaluated[:k + 1]))
    assert seen[-1].best_score == pytest.approx(res.best_score)
    np.testing.assert_array_equal(seen[-1].best_log2_alpha, res.best_log2_alpha)
    assert np.all(np.abs(np.array([p.current_log2_alpha for p in seen])) <= 1.0)


def test_a_search_goes_on_from_known_evaluations_over_a_wider_bound() -> None:
    """What TMR's widened search does: the narrow search's evaluations are known to the GP and kept in the result,
    the first new point is the given warm start, the budget counts the new evaluations, and the search finds an
    optimum only the wider bound holds."""
    ex = LocalExecutor()
    f = lambda x: float(-np.sum((x + 1.4) ** 2))  # noqa: E731 - the optimum at log2 α = −1.4, outside ±1
    seen, evaluated = [], []

    def submit(x: np.ndarray):  # noqa: ANN202
        evaluated.append(x.copy())
        return ex.submit(lambda y: (f(y), y.copy()), x)

    def collect(handles):  # noqa: ANN001, ANN202
        return [(h, v[0], v[1]) for h, v in ex.collect(handles)]

    narrow = bayes_optimise(submit, collect, 1, 1.0, BOSettings(budget=3, init_points=3, seed=0))
    assert abs(narrow.best_log2_alpha[0] + 1.0) < 1e-9, "the narrow search ends on its bound"
    known = [(x, s, p) for (x, s), p in zip(narrow.history, narrow.payloads)]
    wide = bayes_optimise(submit, collect, 1, 1.6, BOSettings(budget=4, seed=0), progress=seen.append,
                          known=known, warm_start=[np.array([-1.6])])
    assert 3 + 2 <= wide.evaluations <= 3 + 4 and len(evaluated) == wide.evaluations  # (it may converge early)
    assert [float(x[0]) for x, _ in wide.history[:3]] == [float(x[0]) for x, _ in narrow.history]
    assert evaluated[3][0] == -1.6, "the widened search starts at its warm start"
    assert [p.evaluation for p in seen] == list(range(4, wide.evaluations + 1)) and all(p.budget == 7 for p in seen)
    assert abs(wide.best_log2_alpha[0] + 1.4) < 0.1 and wide.best_score > narrow.best_score
    assert all(abs(x[0]) <= 1.6 for x in evaluated)


def test_warm_start_begins_with_the_identity_and_cancel_stops() -> None:
    calls = []

    def f(x: np.ndarray) -> float:
        calls.append(x.copy())
        return 0.0

    with pytest.raises(Cancelled):
        _run(f, 1, 1.0, BOSettings(budget=10), cancel=lambda: len(calls) >= 2)
    assert len(calls) == 2 and calls[0][0] == 0.0


@settings(max_examples=30, deadline=None)
@given(dims=st.integers(1, 3), bound=st.floats(0.1, 2.0), points=st.integers(1, 8), seed=st.integers(0, 99))
def test_initial_design_starts_with_the_identity_the_bounds_then_the_inner_probes(dims, bound, points, seed) -> None:  # noqa: ANN001
    design = initial_design(dims, bound, points, np.random.default_rng(seed))
    assert len(design) == points
    probes = [np.zeros(dims), np.full(dims, -bound), np.full(dims, bound), np.full(dims, -bound / 2),
              np.full(dims, bound / 2)]
    for got, want in zip(design, probes):
        np.testing.assert_array_equal(got, want)
    assert all(np.all(np.abs(x) <= bound) for x in design)
    randoms = design[len(probes):]  # the random warm start after the probes: not on the uniform diagonal
    assert all(np.ptp(x) > 0 for x in randoms if dims > 1)


def test_finds_an_optimum_on_the_bound_that_interior_points_miss() -> None:
    """The TMR case of issue 10: only the motion shortened to the lower bound stands (score ≈ 0), every other α
    falls, later the nearer it is to the bound (scores −1.x) — BO finds the bound with the second evaluation and stops soon after."""
    calls = []

    def f(x: np.ndarray) -> float:
        calls.append(float(x[0]))
        if x[0] <= -0.95:
            return -0.05 * x[0] ** 2
        return -1.0 - 2.0 * (1.0 - (0.5 - 0.5 * x[0]) * 0.6)

    res = _run(f, 1, 1.0, BOSettings(budget=6, init_points=3, seed=0))
    assert calls[:2] == [0.0, -1.0]
    assert res.best_log2_alpha[0] <= -0.95 and res.best_score > -0.1


@pytest.mark.slow  # a 30-evaluation search
def test_a_suggestion_already_evaluated_is_not_evaluated_again() -> None:
    """A flat score: EI has nothing to go on and returns to known points; each α is evaluated once at most and
    the search converges before the budget."""
    calls = []

    def f(x: np.ndarray) -> float:
        calls.append(float(x[0]))
        return 0.0 if x[0] <= -0.99 else -1.0

    res = _run(f, 1, 1.0, BOSettings(budget=30, init_points=3, seed=0))
    xs = np.array(calls)
    assert np.min(np.abs(xs[:, None] - xs[None, :]) + np.eye(len(xs)) * 9, initial=9) >= 1e-3
    assert res.evaluations == len(calls) <= 30
    assert res.best_log2_alpha[0] == -1.0


def test_reaches_an_optimum_on_a_bound_that_no_designed_point_holds() -> None:
    """A known 2-D function whose maximum lies on the upper bound of one segment and inside the other,
    (+1, −0.3): none of the designed points (the uniform diagonal) is there; BO gets within 0.1 of it."""
    optimum = np.array([1.0, -0.3])

    def f(x: np.ndarray) -> float:
        return float(-np.sum(np.array([0.5, 1.0]) * (x - np.array([1.6, -0.3])) ** 2))

    res = _run(f, 2, 1.0, BOSettings(budget=14, init_points=4, seed=0))
    assert res.evaluations <= 14
    assert not any(np.max(np.abs(x - optimum)) < 0.1 for x in initial_design(2, 1.0, 4, np.random.default_rng(0)))
    assert np.max(np.abs(res.best_log2_alpha - optimum)) < 0.1


def test_no_evaluation_beside_a_known_point_on_an_isolated_bound_optimum() -> None:
    """The knife edge of go1 HopTurn: only the lower bound stands, every other α falls (later the nearer the
    bound). BO keeps the bound and no two evaluations are within ``duplicate_log2`` of each other (EI's pull
    towards the best point is answered by what is known there)."""
    calls = []

    def f(x: np.ndarray) -> float:
        calls.append(float(x[0]))
        if x[0] <= -0.995:
            return -0.05 * x[0] ** 2
        return -1.0 - 2.0 * (1.0 - 0.8 * (0.5 - 0.5 * x[0]))

    s = BOSettings(budget=8, init_points=4, seed=0)
    res = _run(f, 1, 1.0, s)
    xs = np.array(calls)
    gaps = np.abs(xs[:, None] - xs[None, :]) + np.eye(len(xs)) * 9
    assert np.min(gaps) >= s.duplicate_log2
    assert res.best_log2_alpha[0] == -1.0 and res.evaluations <= 8


# go1 HopTurn's first four evaluations (log2 α, score): α = 1, 0.5, 2, 0.71 — only the bound stands
STEP_SCORES = [(0.0, -2.54), (-1.0, -0.15), (1.0, -2.65), (-0.5, -2.52)]


@pytest.mark.parametrize("seed", range(4))
def test_the_gp_interpolates_a_step_and_ei_looks_beside_the_standing_point(seed: int) -> None:
    """On a step (one α stands, the rest fall) the library's own length-scale bound (10⁻⁵) lets the GP fit white
    noise and EI's suggestion is any point of the box; with the floor the suggestion is beside the standing α,
    the same whatever the random state — and without the floor it is not (the control)."""
    from engine.retarget.quadruped.tmr.bayes_opt import _suggest

    observed = [(np.array([x]), s) for x, s in STEP_SCORES]
    floor = _suggest(1, 1.0, observed, [], BOSettings(), np.random.default_rng(seed))
    assert -1.0 < floor[0] <= -0.85
    first = _suggest(1, 1.0, observed, [], BOSettings(), np.random.default_rng(99))
    np.testing.assert_allclose(floor, first, atol=1e-3)
    raw = [_suggest(1, 1.0, observed, [], BOSettings(length_scale_min_log2=1e-5), np.random.default_rng(k))[0]
           for k in range(5)]
    assert not all(-1.0 < x <= -0.85 for x in raw)
