"""QP backends on recorded problems: the hand-written dense active-set solvers against daqp,
proxsuite, quadprog and OSQP (:mod:`engine.control.qp_backends`).

* ``wbc``: the whole-body QPs (Eqs. 20–25, x = [q̈; ρ], 67 variables for G1) of a closed-loop
  G1 walk, recorded tick by tick; the hand-written solver runs in sequence, warm-started from
  the previous tick as in the controller.
* ``mpc``: the condensed CoM MPC QPs (Eq. 14 after elimination) of a closed-loop-like walk
  (:func:`engine.bench.mpc_problems.closed_loop_like_problems`) and of a recorded closed-loop G1 walk
  (:func:`engine.bench.mpc.record_calls`), the hand-written dual active set (compiled) warm-started as in
  the controller.

Times are thread CPU time per solve, each backend's own input conversion included; the
standard form itself is built once per problem outside that time (``with_form_median_us`` adds it);
``max_dx`` is the largest difference from the hand-written solution, ``max_violation`` the
largest constraint violation.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Callable

import numpy as np

from engine.bench.stats import percentiles_us
from engine.control.qp_backends import BACKENDS, QpProblem, solve

if TYPE_CHECKING:
    from engine.control.wbc.qp import CentroidalQp

WBC_TICKS = (500, 700, 2)  # from, to, every: ticks of the walk whose QPs are kept


def record_wbc_qps(robot_name: str = "g1") -> list[CentroidalQp]:
    """CentroidalQp of every 2nd tick from 1.0 s to 1.4 s of the G1 neutral sweep (closed loop)."""
    from engine.control.walking_controller import WalkingController
    from engine.gait.command_schedule import preset
    from engine.gait.style import load_style, styles_dir
    from engine.robot.model import load_robot
    from engine.sim import Simulation

    robot = load_robot(robot_name)
    style = load_style(styles_dir(robot_name) / "neutral.json")
    schedule = preset("sweep", style.velocities)
    ctrl = WalkingController(robot, style)
    sim = Simulation(robot, ctrl)
    first, last, every = WBC_TICKS
    qps: list[CentroidalQp] = []
    for k in range(last):
        ctrl.set_command(schedule(k * 0.002))
        sim.step()
        diag = ctrl.wbc.diagnostics  # a solved tick carries the QP it solved
        if k >= first and (k - first) % every == 0 and diag.ok and diag.qp is not None:
            qps.append(diag.qp)
    return qps


def _table(name: str, problems: list[QpProblem], ours: Callable[[int], np.ndarray], form_s: list[float],
           ours_label: str) -> list[dict]:
    """One row per backend, every problem given to each backend in turn (interleaved: all of them
    under the same machine conditions); ``with_form_median_us`` adds building the standard form
    (what a controller switched to that backend pays each call). ``ours_label`` names the hand-written
    solver's row (whether it is the controller's default)."""
    names = [ours_label, *BACKENDS]
    times: dict[str, list[float]] = {b: [] for b in names}
    xs: dict[str, list] = {b: [] for b in names}
    for i, p in enumerate(problems):
        t0 = time.thread_time()
        x_ref = ours(i)
        times[names[0]].append(time.thread_time() - t0)
        xs[names[0]].append(x_ref)
        for backend in BACKENDS:
            t0 = time.thread_time()
            res = solve(p, backend)
            times[backend].append(time.thread_time() - t0)
            xs[backend].append(res.x if res.ok else None)
    rows = []
    for b in names:
        solved = [(p, x, r) for p, x, r in zip(problems, xs[b], xs[names[0]]) if x is not None]
        dx = max((float(np.max(np.abs(x - r))) for _, x, r in solved), default=math.nan)
        viol = max((p.violation(x) for p, x, _ in solved), default=math.nan)
        form = np.zeros(len(problems)) if b == names[0] else np.asarray(form_s)
        rows.append({"section": "qp", "problems": name, "n": len(problems), "backend": b, **percentiles_us(times[b]),
                     "with_form_median_us": percentiles_us(np.add(times[b], form))["median_us"],
                     "solved_fraction": round(len(solved) / len(problems), 3), "max_dx": f"{dx:.1e}",
                     "max_violation": f"{viol:.1e}"})
    return rows


def bench_wbc_qps() -> list[dict]:
    from engine.control.wbc.qp import DenseQpSolver

    qps = record_wbc_qps()
    nv, n_rho = qps[0].p_qq.shape[0], qps[0].r_rr.shape[0]
    solver = DenseQpSolver(nv, n_rho)
    problems, form_s = [], []
    for qp in qps:
        t0 = time.thread_time()
        problems.append(qp.standard_form())
        form_s.append(time.thread_time() - t0)

    def ours(i: int) -> np.ndarray:  # in sequence, warm-started from the previous tick
        solution = solver.solve(qps[i])
        assert solution is not None, f"the dense solver did not settle on recorded QP {i}"
        qdd, rho = solution
        return np.concatenate([qdd, rho])

    return _table("wbc (G1 walk)", problems, ours, form_s, "hand-written (the controller's default is daqp)")


def bench_mpc_qps(n: int = 150, recorded_s: float = 4.0) -> list[dict]:
    """Both MPC problem sets: the closed-loop-like walk (``n`` calls) and the calls of a recorded closed-loop
    G1 walk (``recorded_s`` of the neutral sweep)."""
    from engine.bench.mpc import record_calls
    from engine.bench.mpc_problems import closed_loop_like_problems

    like = closed_loop_like_problems(n, seed=2, pull=0.0, state_noise=(0.0, 0.0))
    return (_mpc_table("mpc (condensed, walk)", like)
            + _mpc_table("mpc (condensed, recorded G1 walk)", record_calls("g1", recorded_s)))


def _mpc_table(name: str, calls: list[tuple[tuple, dict]]) -> list[dict]:
    from engine.constants import GRAVITY_MPS2
    from engine.control.mpc import ComMpc
    from engine.control.mpc.lip import _Segments

    mpc = ComMpc(max_intervals=16)
    built, problems, form_s = [], [], []
    for args, _ in calls:
        t_now, com, vel, cop, height, supports = args
        pb, message = mpc._build_problem(t_now, supports)
        assert pb is not None, message
        seg = _Segments.build(pb.times_s, math.sqrt(GRAVITY_MPS2 / height))
        cop = np.asarray(cop, float)
        qp = mpc._condense(pb, seg, cop, np.asarray(com, float) + np.asarray(vel, float) / seg.omega - cop)
        built.append((pb, qp))
        t0 = time.thread_time()
        problems.append(qp.standard_form())
        form_s.append(time.thread_time() - t0)

    def ours(i: int) -> np.ndarray:  # in sequence, warm-started as in the controller
        pb, qp = built[i]
        wps = mpc._solve_active_set(pb, qp, math.inf)[0]
        return np.asarray(wps).ravel()

    return _table(name, problems, ours, form_s, "hand-written (default)")


def bench_qp() -> list[dict]:
    return bench_wbc_qps() + bench_mpc_qps()
