"""The outer Bayesian optimisation (STMR Eqs. 15–18) on known functions, serial and in parallel batches."""

from __future__ import annotations

import numpy as np
import pytest

from engine.retarget.quadruped.tmr.bayes_opt import BOSettings, bayes_optimise
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


def test_two_segments_and_progress_reports() -> None:
    seen = []
    res = _run(lambda x: float(-np.sum((x - np.array([-0.5, 0.4])) ** 2)), 2, 1.0,
               BOSettings(budget=20, init_points=4, seed=0), progress=seen.append)
    assert np.max(np.abs(res.best_log2_alpha - np.array([-0.5, 0.4]))) < 0.15
    assert [p.evaluation for p in seen] == list(range(1, len(seen) + 1))
    assert all(p.budget == 20 for p in seen)
    assert seen[-1].best_score == pytest.approx(res.best_score)
    assert np.all(np.abs(np.array([p.current_log2_alpha for p in seen])) <= 1.0)


def test_warm_start_begins_with_the_identity_and_cancel_stops() -> None:
    calls = []

    def f(x: np.ndarray) -> float:
        calls.append(x.copy())
        return 0.0

    with pytest.raises(Cancelled):
        _run(f, 1, 1.0, BOSettings(budget=10), cancel=lambda: len(calls) >= 2)
    assert len(calls) == 2 and calls[0][0] == 0.0
