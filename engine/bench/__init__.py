"""Benchmarks behind ``studio bench``: figures measured side by side in one run.

Each section is a function returning rows (dicts), its body in this package's module of the
same concept: ``sim`` (MuJoCo alone), ``reference`` (sampler + planner), ``mpc`` (CoM MPC
solves), ``wbc`` (our inverse dynamics against placo's), ``qp`` (the QP backends on recorded
problems), ``estimator``, ``stack`` (the full stack against MuJoCo alone), ``retarget`` (UVM/SMR beside the STMR paper's tables; named on its own, also UVM / SMR / STMR tracked in MuJoCo side by side), ``tmr`` (the temporal stage's costs; ``tmr-clips``, only when asked for: an alias of retarget's UVM / SMR / STMR comparison), ``arms``
(LWL2 against per-frame IK and a feed-forward baseline) and ``puppet`` (LWL2 driving a standing robot's arms
live at 60 Hz in physics; only when asked for). The studio
adds ``edit`` (edit-to-robot latency, :mod:`studio.bench_edit`), ``engine`` (the engine process's pacing
and restart through the studio's link, :mod:`studio.bench_engine`) ``soak`` (:mod:`studio.bench_soak`) and ``render`` (a browser tab's frame rate with and without shadows,
:mod:`studio.bench_render`), the last two not in the default run: the engine never imports the studio.
"""

from __future__ import annotations

from typing import Callable

from engine.bench.stats import percentiles_us

__all__ = ["SECTIONS", "TEXT_TABLES", "percentiles_us"]


def _sim() -> list[dict]:
    from engine.bench.sim import bench_sim

    return bench_sim()


def _reference() -> list[dict]:
    from engine.bench.reference import bench_reference

    return bench_reference()


def _mpc() -> list[dict]:
    from engine.bench.mpc import benchmark_solve

    r = benchmark_solve()
    return [{"section": "mpc", **{k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()},
             "goal_median_us": 500}]


def _wbc() -> list[dict]:
    from engine.bench.wbc import bench_wbc

    return bench_wbc()


def _estimator() -> list[dict]:
    from engine.bench.estimator import benchmark_estimator

    r = benchmark_estimator("g1")
    return [{"section": "estimator", "robot": "g1", **{k: (round(v, 1) if isinstance(v, float) else v) for k, v in r.items()}}]


def _qp() -> list[dict]:
    from engine.bench.qp import bench_qp

    return bench_qp()


def _stack() -> list[dict]:
    from engine.bench.stack import bench_stack

    return bench_stack()


def _retarget(**options) -> list[dict]:
    from engine.bench.options import call_with_known
    from engine.bench.retarget import bench_retarget

    return call_with_known(bench_retarget, options)


def _tmr() -> list[dict]:
    from engine.bench.tmr import bench_tmr

    return bench_tmr()


def _tmr_clips(**options) -> list[dict]:
    from engine.bench.options import call_with_known
    from engine.bench.retarget import bench_tmr_clips

    return call_with_known(bench_tmr_clips, options)


def _arms(**options) -> list[dict]:
    from engine.bench.arms import bench_arms
    from engine.bench.options import call_with_known

    return call_with_known(bench_arms, options)


def _puppet(**options) -> list[dict]:
    from engine.bench.options import call_with_known
    from engine.bench.puppet import bench_puppet

    return call_with_known(bench_puppet, options)


def _push(**options) -> list[dict]:
    from engine.bench.options import call_with_known
    from engine.bench.push import bench_push

    return call_with_known(bench_push, options)


def _styles(**options) -> list[dict]:
    from engine.bench.options import call_with_known
    from engine.bench.styles import bench_styles

    return call_with_known(bench_styles, options)


SECTIONS: dict[str, Callable[..., list[dict]]] = {
    "sim": _sim, "reference": _reference, "mpc": _mpc, "wbc": _wbc, "qp": _qp, "estimator": _estimator,
    "stack": _stack, "retarget": _retarget, "tmr": _tmr, "arms": _arms,
    "push": _push, "styles": _styles, "tmr-clips": _tmr_clips, "puppet": _puppet,
}
def _methods_table(rows: list[dict]) -> str:
    from engine.bench.retarget import methods_table

    return methods_table(rows)


# sections whose text output is a table of their own (``--json`` prints their rows as they are)
TEXT_TABLES: dict[str, Callable[[list[dict]], str]] = {"retarget-methods": _methods_table}
BATCH_SECTIONS = ("push", "styles", "tmr-clips", "puppet")  # minutes to hours of closed-loop runs: only when asked for
