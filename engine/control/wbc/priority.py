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

The rows' layout is the controller's stack: feet 0–11 (left, right; 6 each), pelvis height 12, pelvis
orientation 13–15, CoM 16–18, upper body 19…, angular momentum last three.
"""

from __future__ import annotations

import numpy as np
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


class LexicographicSolve:
    """The two solves of one tick (see the module docstring); reuses its arrays from tick to tick."""

    def __init__(self, nv: int, n_rho: int, n_joints: int, slack: float):
        self.nv, self.n_joints = nv, n_joints
        self.slack = float(slack)
        n_held = HELD_ROWS.size
        self.solver = ActiveSetQpSolver(nv, n_rho, n_joints + n_held)
        self.daqp = DaqpQpSolver(nv, n_rho, n_joints + n_held, compiled=True)
        self._tau_qdd = np.zeros((n_joints + n_held, nv))
        self._tau_rho = np.zeros((n_joints + n_held, n_rho))
        self._tau_bias = np.zeros(n_joints + n_held)
        self._tau_lo = np.zeros(n_joints + n_held)
        self._tau_up = np.zeros(n_joints + n_held)
        self.second_failed = 0  # ticks whose second solve failed (the first's solution was used)

    def level1_qp(self, qp: CentroidalQp, jac: FloatArray, rhs: FloatArray, w: FloatArray,
                  level2: NDArray[np.bool_]) -> CentroidalQp:
        """``qp`` with the level-2 rows' weights × LEVEL1_SOLVE_LEVEL2_SHARE (P and c only)."""
        j2 = jac[level2]
        wj2 = j2 * ((1.0 - LEVEL1_SOLVE_LEVEL2_SHARE) * w[level2])[:, None]
        p_qq = qp.p_qq - j2.T @ wj2
        c_q = qp.c_q + wj2.T @ rhs[level2]
        return CentroidalQp(p_qq, c_q, qp.r_rr, qp.a_h, qp.g_rho, qp.b, qp.qdd_joint_lo, qp.qdd_joint_up,
                            qp.rho_up, tau_qdd=qp.tau_qdd, tau_rho=qp.tau_rho, tau_bias=qp.tau_bias,
                            tau_lo=qp.tau_lo, tau_up=qp.tau_up)

    def level2_qp(self, qp: CentroidalQp, jac: FloatArray, level2: NDArray[np.bool_],
                  qdd1: FloatArray) -> CentroidalQp:
        """``qp`` with level 1's task accelerations held within the slack of ``qdd1``'s."""
        nj = self.n_joints
        assert qp.tau_qdd is not None and qp.tau_rho is not None and qp.tau_bias is not None \
            and qp.tau_lo is not None and qp.tau_up is not None, "the controller's QP has torque rows"
        held_jac = jac[HELD_ROWS]
        self._tau_qdd[:nj] = qp.tau_qdd
        self._tau_qdd[nj:] = held_jac
        self._tau_rho[:nj] = qp.tau_rho
        self._tau_bias[:nj] = qp.tau_bias
        self._tau_lo[:nj] = qp.tau_lo
        self._tau_up[:nj] = qp.tau_up
        achieved = held_jac @ qdd1
        free = level2[HELD_ROWS]
        self._tau_lo[nj:] = np.where(free, -FREE_BOUND, achieved - self.slack)
        self._tau_up[nj:] = np.where(free, FREE_BOUND, achieved + self.slack)
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
