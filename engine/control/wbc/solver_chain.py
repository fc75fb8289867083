"""Which solver gives the whole-body QP's solution: the chosen backend, then the fallbacks.

``"active_set"`` (the default, the compiled dual active set) falls back to DAQP, every backend to OSQP
(fixed sparsity pattern, warm started) when it gives no solution; ``"proxsuite"`` and ``"quadprog"`` go
through :mod:`engine.control.qp_backends`. With a task priority (:mod:`engine.control.wbc.priority`) the
tick is two solves: level 1 by this chain, then level 2 with level 1 held.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.control import qp_backends
from engine.control.wbc.priority import LexicographicSolve
from engine.control.wbc.qp import ActiveSetQpSolver, CentroidalQp, DaqpQpSolver, DenseQpSolver, OsqpQpSolver

FloatArray = NDArray[np.float64]
#: (q̈, ρ) or None, the backend that gave it, the solvers' iterations, their status message
SolveResult = tuple[tuple[FloatArray, FloatArray] | None, str, int, str]


def solve_status(backend: str, message: str) -> str:
    """The diagnostics' status of a solution: OSQP and the standard-form backends say when it is inaccurate."""
    accurate = backend in ("active_set", "dense", "daqp") or "inaccurate" not in message
    return "solved" if accurate else "solved_inaccurate"


class QpSolverChain:
    """The controller's solvers in their order: ``backend`` first, DAQP after the active set, OSQP last."""

    def __init__(self, backend: str, active_set: ActiveSetQpSolver, daqp: DaqpQpSolver, dense: DenseQpSolver,
                 osqp: OsqpQpSolver, priority: LexicographicSolve | None):
        self.backend = backend
        self.active_set, self.daqp, self.dense, self.osqp = active_set, daqp, dense, osqp
        self.priority = priority

    def solve_prioritized(self, qp: CentroidalQp, jac: FloatArray, rhs: FloatArray, w: FloatArray,
                          contact: NDArray[np.bool_], com_z_tracked: bool) -> SolveResult:
        """:meth:`solve`, or with a task priority its two solves: the level-1 QP (from the stacked rows ``jac``,
        ``rhs``, ``w``) by the chain, then level 2 with level 1 held (level 1's solution kept when that fails).
        ``com_z_tracked``: the CoM height is a task this tick (its row belongs to level 1)."""
        priority = self.priority
        if priority is None:
            return self.solve(qp)
        first, backend, iterations, message = self.solve(priority.level1_qp(qp, jac, rhs, w, contact, com_z_tracked))
        if first is None:
            return first, backend, iterations, message
        second = priority.solve_level2(priority.level2_qp(qp, jac, first[0]))
        iterations += priority.solver.iterations
        if second is None:
            return first, backend, iterations, f"{message}; level 2 failed, level 1's solution"
        return second, backend, iterations, message

    def solve(self, qp: CentroidalQp) -> SolveResult:
        """The QP by the chosen backend, OSQP when that one gives no solution (DAQP first after the active set)."""
        solution: tuple[FloatArray, FloatArray] | None = None
        backend, iterations, message = self.backend, 0, ""
        if backend == "active_set":
            solution = self.active_set.solve(qp)
            if solution is None:  # a singular working set or the iteration cap: DAQP, then OSQP
                return self.after_active_set(qp, self.active_set.iterations)
            iterations, message = self.active_set.iterations, self.active_set.status
        elif backend == "daqp":
            solution = self.daqp.solve(qp)
            iterations, message = self.daqp.iterations, self.daqp.status
        elif backend == "dense":
            solution = self.dense.solve(qp)
            iterations = self.dense.iterations
        elif backend != "osqp":
            result = qp_backends.solve(qp.standard_form(), backend)
            message = result.status
            if result.ok and result.x is not None:
                nv = qp.p_qq.shape[0]
                solution = (result.x[:nv].copy(), np.clip(result.x[nv:], 0.0, qp.rho_up))
        if solution is None:
            return self._osqp(qp)
        return solution, backend, iterations, message

    def after_active_set(self, qp: CentroidalQp, iterations: int) -> SolveResult:
        """The active set gave no solution after ``iterations``: DAQP (its iterations added), then OSQP."""
        solution = self.daqp.solve(qp)
        if solution is None:
            return self._osqp(qp)
        return solution, "daqp", iterations + self.daqp.iterations, self.daqp.status

    def _osqp(self, qp: CentroidalQp) -> SolveResult:
        return self.osqp.solve(qp), "osqp", self.osqp.iterations, f"osqp: {self.osqp.status}"
