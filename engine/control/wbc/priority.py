"""Task priority of the whole-body QP (issue 13): balance first, the style's tasks in what balance leaves.

The QP of :mod:`engine.control.wbc.controller` weighs every task against every other: a style that asks
the swing foot to turn further than its ankle reaches, or the pelvis and arms to move fast, is tracked at
the cost of the CoM and the pelvis height (README "Which tasks the whole-body QP trades the CoM for").
Two levels:

* **level 1** — the feet on the ground (any corner in contact), the swing foot's position (where it
  lands is balance: the step adjustment places it), the pelvis height and the CoM (the rows the MPC's
  plan and the contacts stand on);
* **level 2** — the style's tasks: the swing foot's orientation (heel/toe pitch, roll, yaw), the pelvis
  orientation, the upper-body joints, and the angular-momentum damping.

With the swing foot's position in level 2 as well, G1's random-2-6 and random-2-7 (``studio bench styles
--seed 2 --extent 0.15``) fell at 1.8 and 2.8 s (2-7 walks without the priority); with it in level 1 both
walk (README "Task priority in the whole-body QP").

:class:`LexicographicSolve` solves the QP twice per tick (same constraints: dynamics, friction, joint and
torque limits): first with the level-2 weights × ``LEVEL1_SOLVE_LEVEL2_SHARE`` (level 1 alone, level 2
only shaping what is left), then with every weight and level 1's task accelerations ``J₁ q̈`` held within
``slack`` of the first solve's (extra two-sided rows of the QP, next to the torque rows): level 2 cannot
buy its tracking with level 1's. A second solve that fails keeps the first's solution.

The per-tick arithmetic (the first solve's objective, the held rows and their bounds) is compiled
(:func:`level1_objective`, :func:`hold_level1`); :func:`level2_rows` is their numpy reference.

The rows' layout is the controller's stack: feet 0–11 (left, right; 6 each), pelvis height 12, pelvis
orientation 13–15, CoM 16–18, upper body 19…, angular momentum last three.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from engine.control.wbc.qp import ActiveSetQpSolver, CentroidalQp, DaqpQpSolver

FloatArray = NDArray[np.float64]

#: In the first (level-1) solve the level-2 weights are scaled by this: small enough that level 1 is
#: served first, not zero so the arms and swing foot still follow their targets with what is left.
LEVEL1_SOLVE_LEVEL2_SHARE = 1e-3
#: Rows of the stack that can be level 1: both feet, pelvis height, CoM x, y, z.
HELD_ROWS = np.array([*range(12), 12, 16, 17, 18], dtype=np.int64)
#: A held row that is not level 1 this tick (a swing foot's orientation, an untracked CoM height) is bounded by this.
FREE_BOUND = 1e20


def level2_rows(n_rows: int, contact: NDArray[np.bool_], com_z_tracked: bool) -> NDArray[np.bool_]:
    """Mask of the stack's level-2 rows for this tick's ``contact`` (2, 4)."""
    mask = np.ones(n_rows, dtype=bool)
    for side in range(2):
        mask[6 * side:6 * side + 3] = False  # position: on the ground or landing
        if contact[side].any():
            mask[6 * side + 3:6 * side + 6] = False  # orientation of a foot on the ground
    mask[12] = False
    mask[16:18] = False
    if com_z_tracked:
        mask[18] = False
    return mask


@njit(cache=True, nogil=True)
def level1_objective(jac, rhs, w, contact, com_z_tracked, scale, p_qq, c_q, level2, p_out, c_out):  # noqa: ANN001, ANN201
    """The first solve's objective: ``level2`` ← :func:`level2_rows`; ``p_out`` = P − scale Σ wᵣ Jᵣᵀ Jᵣ and
    ``c_out`` = c + scale Σ wᵣ rᵣ Jᵣ over the level-2 rows r (zero entries skipped, as the assembly does)."""
    n_rows, nv = jac.shape
    for r in range(n_rows):
        level2[r] = True
    for side in range(2):
        touching = False
        for c in range(contact.shape[1]):
            if contact[side, c]:
                touching = True
        for r in range(6):
            if r < 3 or touching:
                level2[6 * side + r] = False
    level2[12] = False
    level2[16] = False
    level2[17] = False
    if com_z_tracked:
        level2[18] = False
    for i in range(nv):
        c_out[i] = c_q[i]
        for j in range(nv):
            p_out[i, j] = p_qq[i, j]
    for r in range(n_rows):
        if not level2[r]:
            continue
        wr = scale * w[r]
        if wr == 0.0:
            continue
        wrr = wr * rhs[r]
        for i in range(nv):
            a = jac[r, i]
            if a == 0.0:
                continue
            wa = wr * a
            c_out[i] += a * wrr
            for j in range(i, nv):
                b = jac[r, j]
                if b != 0.0:
                    p_out[i, j] -= wa * b
    for i in range(nv):
        for j in range(i + 1, nv):
            p_out[j, i] = p_out[i, j]


@njit(cache=True, nogil=True)
def hold_level1(jac, held, level2, qdd1, slack, tau_qdd, tau_rho, tau_bias, tau_lo, tau_up,
                out_qdd, out_rho, out_bias, out_lo, out_up):  # noqa: ANN001, ANN201
    """The second solve's rows: the torque rows (copied), then the ``held`` rows of the stack, bounded within
    ``slack`` of their value at ``qdd1`` (±FREE_BOUND for a row that is level 2 this tick)."""
    nj, nv = tau_qdd.shape
    n_rho = tau_rho.shape[1]
    for r in range(nj):
        for j in range(nv):
            out_qdd[r, j] = tau_qdd[r, j]
        for j in range(n_rho):
            out_rho[r, j] = tau_rho[r, j]
        out_bias[r] = tau_bias[r]
        out_lo[r] = tau_lo[r]
        out_up[r] = tau_up[r]
    for k in range(held.shape[0]):
        r = held[k]
        acc = 0.0
        for j in range(nv):
            a = jac[r, j]
            out_qdd[nj + k, j] = a
            acc += a * qdd1[j]
        for j in range(n_rho):
            out_rho[nj + k, j] = 0.0
        out_bias[nj + k] = 0.0
        if level2[r]:
            out_lo[nj + k], out_up[nj + k] = -FREE_BOUND, FREE_BOUND
        else:
            out_lo[nj + k], out_up[nj + k] = acc - slack, acc + slack


class LexicographicSolve:
    """The two solves of one tick (see the module docstring); reuses its arrays from tick to tick."""

    def __init__(self, nv: int, n_rho: int, n_joints: int, n_rows: int, slack: float):
        self.nv, self.n_joints = nv, n_joints
        self.slack = float(slack)
        n_held = HELD_ROWS.size
        self.solver = ActiveSetQpSolver(nv, n_rho, n_joints + n_held)
        self.daqp = DaqpQpSolver(nv, n_rho, n_joints + n_held, compiled=True)
        self.level2 = np.zeros(n_rows, dtype=np.bool_)  # this tick's level-2 rows
        self._p = np.zeros((nv, nv))
        self._c = np.zeros(nv)
        self._tau_qdd = np.zeros((n_joints + n_held, nv))
        self._tau_rho = np.zeros((n_joints + n_held, n_rho))
        self._tau_bias = np.zeros(n_joints + n_held)
        self._tau_lo = np.zeros(n_joints + n_held)
        self._tau_up = np.zeros(n_joints + n_held)
        self.second_failed = 0  # ticks whose second solve failed (the first's solution was used)
        self._warm_up(n_rows, n_rho)

    def _warm_up(self, n_rows: int, n_rho: int) -> None:
        """Compile (or load) the two kernels now, not at the first tick (off by default: not in
        engine/compiled_kernels.py)."""
        nv, nj = self.nv, self.n_joints
        jac, level2 = np.zeros((n_rows, nv)), np.zeros(n_rows, dtype=np.bool_)
        level1_objective(jac, np.zeros(n_rows), np.zeros(n_rows), np.zeros((2, 4), dtype=np.bool_), False, 1.0,
                         np.zeros((nv, nv)), np.zeros(nv), level2, self._p, self._c)
        hold_level1(jac, HELD_ROWS, level2, np.zeros(nv), 0.0, np.zeros((nj, nv)), np.zeros((nj, n_rho)),
                    np.zeros(nj), np.zeros(nj), np.zeros(nj), self._tau_qdd, self._tau_rho, self._tau_bias,
                    self._tau_lo, self._tau_up)

    def level1_qp(self, qp: CentroidalQp, jac: FloatArray, rhs: FloatArray, w: FloatArray,
                  contact: NDArray[np.bool_], com_z_tracked: bool) -> CentroidalQp:
        """``qp`` with the level-2 rows' weights × LEVEL1_SOLVE_LEVEL2_SHARE (P and c only); sets ``level2``."""
        level1_objective(jac, rhs, w, contact, com_z_tracked, 1.0 - LEVEL1_SOLVE_LEVEL2_SHARE, qp.p_qq, qp.c_q,
                         self.level2, self._p, self._c)
        return CentroidalQp(self._p, self._c, qp.r_rr, qp.a_h, qp.g_rho, qp.b, qp.qdd_joint_lo, qp.qdd_joint_up,
                            qp.rho_up, tau_qdd=qp.tau_qdd, tau_rho=qp.tau_rho, tau_bias=qp.tau_bias,
                            tau_lo=qp.tau_lo, tau_up=qp.tau_up)

    def level2_qp(self, qp: CentroidalQp, jac: FloatArray, qdd1: FloatArray) -> CentroidalQp:
        """``qp`` with level 1's task accelerations held within the slack of ``qdd1``'s (after :meth:`level1_qp`)."""
        assert qp.tau_qdd is not None and qp.tau_rho is not None and qp.tau_bias is not None \
            and qp.tau_lo is not None and qp.tau_up is not None, "the controller's QP has torque rows"
        hold_level1(jac, HELD_ROWS, self.level2, qdd1, self.slack, qp.tau_qdd, qp.tau_rho, qp.tau_bias, qp.tau_lo,
                    qp.tau_up, self._tau_qdd, self._tau_rho, self._tau_bias, self._tau_lo, self._tau_up)
        return CentroidalQp(qp.p_qq, qp.c_q, qp.r_rr, qp.a_h, qp.g_rho, qp.b, qp.qdd_joint_lo, qp.qdd_joint_up,
                            qp.rho_up, tau_qdd=self._tau_qdd, tau_rho=self._tau_rho, tau_bias=self._tau_bias,
                            tau_lo=self._tau_lo, tau_up=self._tau_up)

    def solve_level2(self, qp2: CentroidalQp) -> tuple[FloatArray, FloatArray] | None:
        """The second solve: the compiled active set, then DAQP; None when both fail."""
        solution = self.solver.solve(qp2)
        if solution is None:
            solution = self.daqp.solve(qp2)
        if solution is None:
            self.second_failed += 1
            return None
        return solution
