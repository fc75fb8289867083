"""Task-space inverse dynamics whole-body controller (paper Sec. 7.1 and Appendix "ID", Eqs. 15–25),
one concept a module:

* :mod:`~engine.control.wbc.tasks` — acceleration tasks (Eq. 18) and the per-tick pinocchio snapshot;
* :mod:`~engine.control.wbc.snapshot` — that snapshot as the compiled tick reads it (pinocchio's memory in place);
* :mod:`~engine.control.wbc.reference` — gains, the tracked reference, diagnostics, friction pyramid (Eq. 17);
* :mod:`~engine.control.wbc.qp` — the QP of Eqs. 20–25 and its solvers (DAQP default, hand-written, OSQP);
* :mod:`~engine.control.wbc.controller` — :class:`TaskSpaceInverseDynamics`: the tick (build, solve, torques, set-points);
* :mod:`~engine.control.wbc.kernels` — the tick's numerics compiled (numba);
* :mod:`~engine.control.wbc.assembly_numpy` — the QP assembled in numpy by the task objects (the kernels' reference);
* :mod:`~engine.control.wbc.solver_chain` — the chosen QP backend, then DAQP and OSQP when it gives no solution;
* :mod:`~engine.control.wbc.torques` — Eq. 15's joint torques of a solved QP in numpy;
* :mod:`~engine.control.wbc.setpoints` — set-point integration and the fallback hold (shared with the peer);
* :mod:`~engine.control.wbc.tracking` — the controller slot for a reference-tracking controller;
* :mod:`~engine.control.wbc.placo_peer` — placo's DynamicsSolver behind the same interface.
"""

from engine.control.wbc.controller import TaskSpaceInverseDynamics
from engine.control.wbc.reference import (WbcDiagnostics, WbcGains, WbcReference, WholeBodyController,
                                          friction_basis)
from engine.control.wbc.tracking import TrackingController

__all__ = ["TaskSpaceInverseDynamics", "TrackingController", "WbcDiagnostics", "WbcGains", "WbcReference",
           "WholeBodyController", "friction_basis"]
