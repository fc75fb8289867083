"""Spatial motion retargeting (§V, Algorithm 1, Eq. 14).

Per frame a convex QP on the configuration step Δ (velocity-level IK, pinocchio tangent space):

    min ½ ‖Δ − δq̃‖²_Q   s.t.  J_j Δ = p̃_j − FK_j(q)        for feet in contact   (foot locking, Eq. 12)
                              J_j^z Δ ≥ h(p_j^xy) + r − FK_j^z(q)  for feet in swing  (no penetration, Eq. 10)
                              θ_lo ≤ θ + Δ_θ ≤ θ_hi                                  (joint limits)

where q̃ = q^{i−1} ⊕ ᴵᴷq̇^i Δt is the reference built from the IK solution's velocity (Kq = 1), anchors p̃_j
are the reference foot projected onto the HeightMap at the start of each contact segment, and the step is
re-linearised a few times (Newton) so the locked feet end within micrometres of their anchors. The QP is
solved by OSQP with a fixed sparsity pattern, warm-started from the previous solve.

Base: its *position* follows the reference velocity only (it is reconstructed from the anchored feet, and
in baseless mode the reference has no base motion at all); joints and base orientation are pulled gently
toward the IK solution (``joint_pull``) so constraint corrections do not accumulate.

Flight (§V-C): when no foot is in contact the reference base moves ballistically from the exit velocity
(polynomial fit of the base history) under gravity; a swing foot that reaches the ground during the flight
starts a new contact there (Algorithm 1, lines 17–22), which ends the flight; it lasts until the source
schedule has a contact again. Deviation: the vertical exit velocity is chosen so the arc lands at the next
scheduled contact (``land_on_schedule``), because the STMR clips are slowed down ×2.4 in time and an arc from
the polynomial exit velocity would land early and change the contact schedule.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import osqp
import pinocchio as pin
from scipy import sparse

from engine.retarget.quadruped.flight import GRAVITY_VECTOR_MPS2, exit_velocity, landing_exit_velocity_z
from engine.retarget.heightmap import HeightMap
from engine.retarget.quadruped.kinematics import QuadrupedKinematics
from engine.retarget.quadruped.uvm import RetargetCancelled


@dataclass(frozen=True)
class SmrOptions:
    weight_base_pos: float = 0.05
    weight_base_rot: float = 1.0
    weight_joint: float = 1.0
    joint_pull: float = 0.2  # per frame, toward the IK joints and base orientation
    newton_iterations: int = 8
    tolerance_m: float = 1e-4  # a step this small leaves an O(step²) ≈ 1e-8 m linearisation error
    flight_horizon: int = 6
    touchdown_tolerance_m: float = 1e-4
    swing_clearance_m: float = 0.01  # swing feet stay this far above the height map
    flight_base_weight: float = 1e6  # base position weight in flight: the base follows the ballistic reference
    land_on_schedule: bool = True  # vertical exit velocity so the ballistic arc lands at the scheduled contact
    touchdowns: bool = True  # Algorithm 1 lines 17–22: a foot reaching the ground in flight starts a contact


@dataclass
class SmrResult:
    q: np.ndarray  # (T, nq) pinocchio configurations
    contact: np.ndarray  # (T, 4) the schedule enforced (source + touchdowns during flight)
    anchors: np.ndarray  # (T, 4, 3) anchor of each foot while in contact (NaN in swing)
    flight: np.ndarray  # (T,) bool: frames with a ballistic base reference
    qp_failures: int
    qp_solves: int = 0
    joint_limit_relaxed: int = 0


class FootLockQP:
    """The per-frame QP of Eq. 14 with a fixed sparsity pattern (OSQP, warm-started)."""

    def __init__(self, kin: QuadrupedKinematics, options: SmrOptions):
        self.kin = kin
        nv = kin.nv
        self.nv = nv
        nj = nv - 6
        w = np.concatenate([np.full(3, options.weight_base_pos), np.full(3, options.weight_base_rot), np.full(nj, options.weight_joint)])
        self.w = w
        mask = np.zeros((12 + nj, nv), dtype=bool)
        for leg in range(4):
            mask[3 * leg:3 * leg + 3, :6] = True
            mask[3 * leg:3 * leg + 3, kin.leg_v[leg]] = True
        mask[12:, 6:] = np.eye(nj, dtype=bool)
        a = sparse.csc_matrix(mask.astype(float))
        a.sort_indices()
        self.flat = a.indices * nv + np.repeat(np.arange(nv), np.diff(a.indptr))  # CSC data order
        self.a_dense = np.zeros(mask.shape)
        self.a_dense[12:, 6:] = np.eye(nj)
        self.lower = np.full(12 + nj, -np.inf)
        self.upper = np.full(12 + nj, np.inf)
        self.solver = osqp.OSQP()
        self.solver.setup(P=sparse.diags(w.copy()).tocsc(), q=np.zeros(nv), A=a, l=self.lower.copy(), u=self.upper.copy(),
                          eps_abs=1e-8, eps_rel=1e-8, max_iter=4000, polishing=False, verbose=False,
                          warm_starting=True, adaptive_rho=True)
        self.ext = self.solver._solver
        self.q_lo = kin.model.lowerPositionLimit[7:]
        self.relaxed = 0  # solves that had to drop the joint limits
        self.q_hi = kin.model.upperPositionLimit[7:]

    def set_base_weight(self, weight: float) -> None:
        if weight != self.w[0]:
            self.w[:3] = weight
            self.ext.update_data_mat(P_x=self.w.copy(), P_i=None, A_x=None, A_i=None)

    def solve(self, target_step: np.ndarray, feet: np.ndarray, jac: np.ndarray, contact: np.ndarray,
              anchors: np.ndarray, ground_z: np.ndarray, joints: np.ndarray) -> np.ndarray | None:
        self.a_dense[:12] = jac.reshape(12, self.nv)
        lo, up = self.lower, self.upper
        lo[:12], up[:12] = -np.inf, np.inf
        for leg in range(4):
            r = slice(3 * leg, 3 * leg + 3)
            if contact[leg]:
                lo[r] = up[r] = anchors[leg] - feet[leg]
            else:
                lo[3 * leg + 2] = ground_z[leg] - feet[leg, 2]
        lo[12:] = self.q_lo - joints
        up[12:] = self.q_hi - joints
        # a joint already beyond a limit may not be pushed further but is not forced back in one step
        lo[12:] = np.minimum(lo[12:], 0.0)
        up[12:] = np.maximum(up[12:], 0.0)
        # The wrapper's solver object directly: OSQP.update/solve rebuild Python namespaces on every call,
        # which costs more than the solve itself for this 18-variable QP (same calls underneath).
        ext = self.ext
        ext.update_data_vec(q=-self.w * target_step, l=np.maximum(lo, -INF), u=np.minimum(up, INF))
        ext.update_data_mat(P_x=None, P_i=None, A_x=self.a_dense.ravel()[self.flat], A_i=None)
        ext.solve()
        self.last_status = ext.info.status_val
        if self.last_status not in (1, 2):  # solved, solved inaccurate
            # the anchors cannot be held within the joint limits: hold them, let the limits give
            self.relaxed += 1
            lo[12:], up[12:] = -INF, INF
            ext.update_data_vec(q=None, l=np.maximum(lo, -INF), u=np.minimum(up, INF))
            ext.solve()
            if ext.info.status_val not in (1, 2):
                return None
        return np.array(ext.solution.x)


FREEZE_GROUND_AFTER = 3
INF = 1e30  # OSQP_INFTY


def _swing_ground(heightmap: HeightMap, feet: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Lowest allowed foot-centre height: the highest ground under a disc around each foot (box edges)."""
    return heightmap.support_heights(feet[:, :2], radius) + radius


def _newton(kin: QuadrupedKinematics, data, qp: FootLockQP, q_start: np.ndarray, q_ref: np.ndarray, c: np.ndarray,
            anchors: np.ndarray, heightmap: HeightMap, options: SmrOptions) -> tuple[np.ndarray, int, int]:
    """Re-linearised QP steps from q_start toward q_ref under the foot constraints: (q, solves, failures)."""
    model = kin.model
    radius = kin.foot_radius_m
    q = q_start.copy()
    solves = 0
    ground = None
    for it in range(options.newton_iterations):
        feet, jac = kin.foot_jacobians(data, q)
        if it < FREEZE_GROUND_AFTER or ground is None:  # then frozen: box edges cannot make the steps cycle
            ground = _swing_ground(heightmap, feet, radius) + options.swing_clearance_m
        step = pin.difference(model, q, q_ref)
        dq = qp.solve(step, feet, jac, c, anchors, ground, q[7:])
        if dq is None:
            return q, solves, 1
        q = pin.integrate(model, q, dq)
        solves += 1
        if np.abs(dq).max() < options.tolerance_m:
            break
    return q, solves, 0


def smr(kin: QuadrupedKinematics, ref_q: np.ndarray, contact: np.ndarray, fps: float, heightmap: HeightMap,
        options: SmrOptions = SmrOptions(), progress: Callable[[float], None] | None = None,
        cancel=None) -> SmrResult:
    """Algorithm 1 over the IK reference ``ref_q`` (T, nq) and the source schedule ``contact`` (T, 4)."""
    model = kin.model
    data = model.createData()
    dt = 1.0 / fps
    t_n = len(ref_q)
    qp = FootLockQP(kin, options)
    radius = kin.foot_radius_m
    source_sched = np.asarray(contact, dtype=bool)
    sched = source_sched.copy()
    out_q = np.empty_like(ref_q)
    anchors_out = np.full((t_n, 4, 3), np.nan)
    flight = np.zeros(t_n, dtype=bool)
    anchors = np.full((4, 3), np.nan)
    prev_contact = np.zeros(4, dtype=bool)
    touchdown = np.zeros(4, dtype=bool)  # contacts begun by a landing during flight
    v_flight = np.zeros(3)
    failures = 0
    iterations = 0
    q_prev = ref_q[0].copy()
    for i in range(t_n):
        if cancel is not None and cancel.is_set():
            raise RetargetCancelled()
        # --- the contact schedule of this frame: the source's, plus touchdowns that persist
        c = sched[i].copy()
        for leg in range(4):
            if touchdown[leg]:
                if source_sched[i].any():
                    touchdown[leg] = False  # the schedule resumes (a scheduled contact of this foot keeps the anchor)
                else:
                    c[leg] = True
        # --- reference q̃
        if i == 0:
            q_ref = ref_q[0].copy()
        else:
            v_ref = pin.difference(model, ref_q[i - 1], ref_q[i])
            in_flight = not c.any()
            if in_flight:
                if prev_contact.any() or not flight[i - 1]:
                    hist = out_q[max(0, i - options.flight_horizon):i, :3]
                    v_flight = exit_velocity(hist, dt, options.flight_horizon)
                    if options.land_on_schedule:
                        landing = np.flatnonzero(sched[i:].any(axis=1))
                        if len(landing):
                            v_flight[2] = landing_exit_velocity_z(ref_q[i - 1:i + landing[0] + 1, 2], dt)
                else:
                    v_flight = v_flight + GRAVITY_VECTOR_MPS2 * dt
                rot = pin.Quaternion(q_prev[3:7]).toRotationMatrix()
                v_ref[:3] = rot.T @ (v_flight * dt)
                flight[i] = True
            q_ref = pin.integrate(model, q_prev, v_ref)
            # pull joints and orientation toward the IK solution (position-level leak)
            q_ref[7:] += options.joint_pull * (ref_q[i, 7:] - q_ref[7:])
            if options.joint_pull > 0:
                q_ref[3:7] = pin.Quaternion(q_ref[3:7]).slerp(options.joint_pull, pin.Quaternion(ref_q[i, 3:7])).coeffs()
        # --- Newton iterations on Eq. 14
        qp.set_base_weight(options.flight_base_weight if flight[i] else options.weight_base_pos)
        feet = kin.foot_jacobians(data, q_ref)[0]
        for leg in range(4):  # anchors at new contact segments: the reference foot projected onto the ground
            if c[leg] and not prev_contact[leg]:
                anchors[leg] = heightmap.project(feet[leg], radius[leg])
            elif not c[leg]:
                anchors[leg] = np.nan
        q, solves, failed = _newton(kin, data, qp, q_ref, q_ref, c, anchors, heightmap, options)
        iterations += solves
        failures += failed
        # --- touchdowns during flight (Algorithm 1, lines 17–22): the foot lands on this very frame
        if flight[i] and options.touchdowns:
            feet = kin.feet(data, q)
            ground = _swing_ground(heightmap, feet, radius) + options.swing_clearance_m
            landed = False
            for leg in range(4):
                # (a foot that lifted off this very frame is not landing: one swing frame at least)
                if not c[leg] and not prev_contact[leg] and feet[leg, 2] <= ground[leg] + options.touchdown_tolerance_m:
                    touchdown[leg] = True
                    c[leg] = True
                    anchors[leg] = heightmap.project(feet[leg], radius[leg])
                    landed = True
            if landed:
                q, solves, failed = _newton(kin, data, qp, q, q_ref, c, anchors, heightmap, options)
                iterations += solves
                failures += failed
        out_q[i] = q
        sched[i] = c
        anchors_out[i] = anchors
        prev_contact = c
        q_prev = q
        if progress is not None and i % 16 == 0:
            progress(i / t_n)
    return SmrResult(out_q, sched, anchors_out, flight, failures, iterations, qp.relaxed)
