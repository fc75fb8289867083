"""Centre-of-mass model predictive controller (paper Sec. 7.1 and Appendix "MPC"), one concept a module:

* :mod:`~engine.control.mpc.types` — SupportInterval, ComMpcWeights, ComMpcSolution (``com_at``: Eq. 11's
  exact solution);
* :mod:`~engine.control.mpc.regions` — the waypoints' constraint regions (Eq. 12's polygons);
* :mod:`~engine.control.mpc.lip` — exact LIP propagation under a piecewise-linear CoP (Eq. 11);
* :mod:`~engine.control.mpc.problem` — the support schedule as QP rows and the condensed QP (Eqs. 12–14);
* :mod:`~engine.control.mpc.active_set` — the dense dual active-set solver (compiled:
  :mod:`~engine.control.mpc.active_set_kernel`, :mod:`~engine.control.mpc.kernels`);
* :mod:`~engine.control.mpc.warm_start` — matching the previous solutions' active rows;
* :mod:`~engine.control.mpc.osqp_backend` — OSQP on a padded, fixed sparsity pattern (``solver="osqp"``);
* :mod:`~engine.control.mpc.state_input` — the input state, made finite and flagged;
* :mod:`~engine.control.mpc.fallbacks` — previous plan, centroid plan or held CoP when the QP gives none;
* :mod:`~engine.control.mpc.controller` — :class:`ComMpc` (build, condense, solve).

Other QP backends: :mod:`engine.control.qp_backends`. Polygon geometry: :mod:`engine.geometry.polygon`.


Plans the horizontal CoM and the Centre of Pressure (CoP) over a preview window
(default T = 2 s) given the upcoming convex support polygons and their timing.

Model (Eq. 11 with constant CoM height ``z`` and constant angular momentum)::

    x'' = omega^2 (x - p(t)),   omega^2 = g / z

Decision variables (Eq. 12): CoP waypoints ``p_0 .. p_N`` (``N = 2K``: one at the
midpoint and one at the end of each of the ``K`` support intervals, the CoP being
linear in between).  ``p_0`` equals the current CoP, midpoints lie in their polygon
``C_k``, end points in ``C_k ∩ C_k+1`` (the last one in ``C_K``).

Cost (Eq. 14)::

    W_T |CP_T - c_T|^2 + sum_n W_c |p_n - c_n|^2 + sum_n W_v |(p_n+1 - p_n) / dt_n|^2

with ``CP_T = x_T + v_T / omega`` the final capture point, ``c_n`` the centroid of
waypoint ``n``'s region (the intersection polygon for end points) and ``c_T`` the
last polygon's.

Well-conditioned, condensed form
--------------------------------
The paper optimises the final CoM state ``xi_T`` too, tied to the initial state by
reverse-time integration (Eq. 14's equalities).  Their coefficients, and those of
the capture-point cost expressed in the CoP, grow like ``exp(omega T)`` (~3000 for
z = 0.6 m, T = 2 s), which made the ADMM solver need hundreds to thousands of
iterations on closed-loop problems.  Here the final state is eliminated: with the
divergent component of motion ``zeta = x + v / omega`` and the exact LIP solution for
a piecewise-linear CoP (segment ``j`` of duration ``h_j``, ``E_j = exp(-omega h_j)``,
``r_j = (1 - E_j) / (omega h_j)``, ``a_j = 1 - r_j``, ``b_j = r_j - E_j``)::

    CP_T - c_T = exp(omega T) * r,
    r = zeta_0 - exp(-omega T) c_T - sum_n beta_n p_n,
    beta_n = exp(-omega tau_n) a_n + exp(-omega tau_n-1) b_n-1      (tau_n = t_n - t_0)

The "stability residual" ``r`` (IS-MPC's boundedness condition, Scianca et al. 2020)
has coefficients ``0 <= beta_n <= 1`` summing to ``1 - exp(-omega T)``, and the
capture-point term becomes ``W_s |r|^2`` with ``W_s = W_T exp(2 omega T)`` -- the
*same* objective as Eq. 14, so the optimum is unchanged (``ComMpcWeights.stability``
may set another ``W_s``; note that a residual ``r`` moves the final capture point by
``exp(omega T) r``, so "moderate" weights such as 1e4 let it drift by decimetres to
metres on walking problems).  The Hessian per axis is ``D + W_s beta beta^T`` (``D``
tridiagonal, eigenvalues within ``[W_c, W_c + 4 W_v / dt^2]``); the stiff rank-one
term is handled exactly with the Sherman-Morrison formula
(``H^-1 = D^-1 - kappa u u^T``, ``u = D^-1 beta``, ``kappa = W_s / (1 + W_s beta.u)``),
so ``W_s`` never enters a factorisation.  The CoM trajectory follows in closed form
from the initial state and the CoP (exact LIP integration), so ``com_at`` is
consistent with ``cop_at`` and the initial state by construction.

QP solver
---------
After elimination the QP has ``2N`` variables (~16-26 waypoints x 2 axes) and ~100
polygon rows (4-6 per waypoint), each touching one waypoint.  It is solved by a dense
dual active-set method (Goldfarb-Idnani, as in ``quadprog``): start from the
unconstrained optimum and add the most violated polygon row until none is violated,
dropping rows whose multiplier would turn negative (see :func:`_dual_active_set`).
Columns of the dual Hessian ``G = A H^-1 A^T`` are computed on demand from ``H^-1``.
Calls warm start from the active sets of the previous two solutions (rows matched by
waypoint time, kind and edge normal, so that shifted timings and moved footholds keep
them; two, because the controller alternates between plan continuations and
restarts from the measured state after a failed solve), and large changes of the
active set are made in blocks.  Closed-loop problems need 0-3 steps, restarts after
large pushes up to ~70.  The result is exact up to rounding (no tolerance-driven
polishing).  The condensation and the solver run compiled (numba: :mod:`engine.control.mpc.kernels`,
:mod:`engine.control.mpc.active_set_kernel`, the default solve from the supports to the plan in one call,
:func:`~engine.control.mpc.active_set_kernel.plan_window`; a solve with a wall-time limit runs the numpy solver,
which can check the clock).  An iteration cap (``max_iter``) or time limit returns the current
iterate with its waypoints pulled into their regions (``"solved_inaccurate"``)
instead of a fallback.  ``solver="osqp"`` solves the same condensed QP with OSQP
(kept for cross-checking: ADMM still needs hundreds to thousands of iterations with
the exact ``W_s``).

Long supports (e.g. standing) are split into equal pieces of at most
``max_interval_s`` (anchored at the support's start, same polygon), each with its
two waypoints.  Without this a 2 s stance is steered by a single CoP ramp per second,
which cannot stabilise the capture point in closed loop; ``max_interval_s=inf``
gives the paper's literal two waypoints per support.

Polygon geometry (half-planes, centroids, intersections of consecutive supports) is
computed vectorised for all polygons of a call (footholds move a little every call,
so caching by contents rarely hits); in walking the intersection of consecutive
supports is one of them (a foot inside the double-support hull), which a containment
test detects without clipping.
"""

from engine.constants import GRAVITY_MPS2
from engine.control.mpc.controller import ComMpc
from engine.control.mpc.lip import propagate_lip
from engine.control.mpc.types import ComMpcSolution, ComMpcWeights, SupportInterval, SupportPhase
from engine.geometry.polygon import (
    clip_convex_polygons,
    convex_hull,
    polygon_area,
    polygon_centroid,
    polygon_halfplanes,
)

__all__ = [
    "GRAVITY_MPS2",
    "ComMpc",
    "ComMpcSolution",
    "ComMpcWeights",
    "SupportInterval",
    "SupportPhase",
    "clip_convex_polygons",
    "convex_hull",
    "polygon_area",
    "polygon_centroid",
    "polygon_halfplanes",
    "propagate_lip",
]
