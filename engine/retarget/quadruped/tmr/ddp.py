"""The inner optimal-control problem of TMR (STMR Eq. 9, §III-B): box-constrained iLQR on MuJoCo's derivatives.

``ilqr`` is the DDP variant the paper uses (iterative LQR, Tassa et al. 2012): Gauss–Newton cost expansion,
the dynamics linearised by ``mujoco.mjd_transitionFD`` (chained exactly over the physics sub-steps of one
control interval), Levenberg–Marquardt regularisation, a backtracking line search, and torque limits as box
constraints on the controls (box-DDP, Tassa et al. 2014): each step's control QP is solved by DAQP through
qpsolvers when the Newton step leaves the box, and the feedback rows of clamped controls are zeroed.

``MotionTracker`` poses the tracking problem for a quadruped in the robot's full MuJoCo model (the engine's
loader model: mesh-hull collisions, elliptic cones, armature): keypoints (16 points), base pose and joint
posture of a target motion, the contact schedule as foot costs (a foot the schedule puts on the ground keeps
still), torque limits from the URDF efforts. The answer is always judged by :meth:`MotionTracker.replay`,
which replays the controls open-loop from the initial state: the solver's nominal trajectory *is* such an
open-loop rollout, so what the solver reports is what the replay shows.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Callable, Protocol

import mujoco
import numpy as np

from engine.retarget.quadruped.tmr.keypoints import KeypointSet

DEFAULT_TIMESTEP_S = 0.01  # control interval of the tracker (physics runs at the model's own step inside)
FALL_HEIGHT_FRACTION = 0.5  # base below this share of the standing height: fallen (targets crouch to ≥ 0.7)


class Cancelled(Exception):
    """Raised inside a solve when the cancel hook says so."""


# ============================================================================ dynamics


class MjDynamics:
    """x_{k+1} = f(x_k, u_k): ``substeps`` MuJoCo steps with the control held (zero-order hold).

    The state lives in MjData (qpos, qvel, act, warm-start); its tangent is (dq, dqvel, dact) of size 2·nv + na,
    MuJoCo's convention for ``mjd_transitionFD``.
    """

    def __init__(self, model: mujoco.MjModel, substeps: int = 1, fd_eps: float = 1e-6, fd_centered: bool = False):
        if substeps < 1:
            raise ValueError("substeps must be ≥ 1")
        self.model = model
        self.substeps = int(substeps)
        self.fd_eps = fd_eps
        # forward differences (as MuJoCo MPC's iLQG uses): half the cost of centred ones, which the solver's
        # line search does not need (the linearisation was ~60 % of a tracking solve's time)
        self.fd_centered = bool(fd_centered)
        self.nx = 2 * model.nv + model.na
        self.nu = model.nu
        self.dt_s = float(model.opt.timestep) * self.substeps
        self.u_lower = np.where(model.actuator_ctrllimited, model.actuator_ctrlrange[:, 0], -np.inf)
        self.u_upper = np.where(model.actuator_ctrllimited, model.actuator_ctrlrange[:, 1], np.inf)
        self._scratch = mujoco.MjData(model)

    # state snapshots: (qpos, qvel, act, qacc_warmstart, time)
    @staticmethod
    def snapshot(data: mujoco.MjData) -> tuple:
        return (data.qpos.copy(), data.qvel.copy(), data.act.copy(), data.qacc_warmstart.copy(), float(data.time))

    @staticmethod
    def restore(data: mujoco.MjData, snap: tuple) -> None:
        data.qpos[:], data.qvel[:], data.act[:], data.qacc_warmstart[:] = snap[0], snap[1], snap[2], snap[3]
        data.time = snap[4]

    def state_difference(self, x_from: tuple, x_to: tuple) -> np.ndarray:
        """Tangent-space x_to ⊖ x_from (2·nv + na)."""
        m = self.model
        dx = np.empty(self.nx)
        mujoco.mj_differentiatePos(m, dx[: m.nv], 1.0, x_from[0], x_to[0])
        dx[m.nv: 2 * m.nv] = x_to[1] - x_from[1]
        dx[2 * m.nv:] = x_to[2] - x_from[2]
        return dx

    def step(self, data: mujoco.MjData, u: np.ndarray) -> None:
        data.ctrl[:] = u
        for _ in range(self.substeps):
            mujoco.mj_step(self.model, data)

    def derivatives(self, snap: tuple, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A = ∂f/∂x, B = ∂f/∂u at (x, u), chained over the sub-steps: A = Π A_j, B = Σ (Π_{i>j} A_i) B_j."""
        m, d = self.model, self._scratch
        self.restore(d, snap)
        d.ctrl[:] = u
        A = np.eye(self.nx)
        B = np.zeros((self.nx, self.nu))
        Aj = np.zeros((self.nx, self.nx))
        Bj = np.zeros((self.nx, self.nu))
        for j in range(self.substeps):
            mujoco.mjd_transitionFD(m, d, self.fd_eps, self.fd_centered, Aj, Bj, None, None)
            A = Aj @ A
            B = Aj @ B + Bj
            if j + 1 < self.substeps:
                mujoco.mj_step(m, d)
        return A, B


# ============================================================================ cost


class StageCost(Protocol):
    """Cost of a stage (k < H) or the final state (k = H), evaluated on MjData holding x_k with its forward
    quantities computed (mj_forward or mj_step1)."""

    def value(self, k: int, data: mujoco.MjData, u: np.ndarray | None) -> float: ...

    def expand(self, k: int, data: mujoco.MjData, u: np.ndarray | None
               ) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(l, l_x, l_u, l_xx, l_uu, l_ux); u is None at the final stage (then l_u etc. are empty)."""
        ...


# ============================================================================ iLQR


@dataclass
class ILQRSettings:
    max_iterations: int = 30
    tolerance: float = 1e-4  # stop when the relative cost decrease of an iteration is below this
    mu_init: float = 1e-3
    mu_min: float = 1e-8
    mu_max: float = 1e8
    line_search: tuple[float, ...] = (1.0, 0.5, 0.25, 0.1, 0.03, 0.01)


@dataclass
class ILQRResult:
    U: np.ndarray  # (H, nu) applied controls (feedback included, clipped): replay these open-loop
    states: list[tuple]  # H + 1 MjData snapshots of the nominal rollout
    cost: float
    cost_history: list[float]
    iterations: int
    converged: bool
    wall_time_s: float
    derivative_time_s: float = 0.0


def rollout(dyn: MjDynamics, cost: StageCost, x0: tuple, U: np.ndarray, data: mujoco.MjData,
            nominal: list[tuple] | None = None, k_ff: np.ndarray | None = None, K: np.ndarray | None = None,
            step_size: float = 1.0, max_cost: float = np.inf) -> tuple[float, list[tuple], np.ndarray]:
    """Forward pass. Open loop when ``nominal`` is None; otherwise u_k = clip(U_k + a·k_k + K_k (x_k ⊖ x̄_k))."""
    m = dyn.model
    H = len(U)
    dyn.restore(data, x0)
    states = [dyn.snapshot(data)]
    applied = np.empty_like(U)
    total = 0.0
    for k in range(H):
        mujoco.mj_forward(m, data)
        u = U[k].copy()
        if nominal is not None:
            assert k_ff is not None and K is not None  # a closed-loop pass has its gains
            dx = dyn.state_difference(nominal[k], states[k])
            u = u + step_size * k_ff[k] + K[k] @ dx
        u = np.clip(u, dyn.u_lower, dyn.u_upper)
        applied[k] = u
        total += cost.value(k, data, u)
        if not np.isfinite(total) or total > max_cost:
            return np.inf, states, applied
        dyn.step(data, u)
        if not (np.all(np.isfinite(data.qpos)) and np.all(np.isfinite(data.qvel))):
            return np.inf, states, applied
        states.append(dyn.snapshot(data))
    mujoco.mj_forward(m, data)
    total += cost.value(H, data, None)
    return total, states, applied


def _box_qp(Quu: np.ndarray, Qu: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """argmin ½ duᵀ Quu du + Quᵀ du, lower ≤ du ≤ upper. Returns (du, free mask)."""
    du = -np.linalg.solve(Quu, Qu)
    if np.all(du >= lower - 1e-12) and np.all(du <= upper + 1e-12):
        return du, np.ones(len(du), dtype=bool)
    from qpsolvers import solve_qp

    sol = solve_qp(Quu, Qu, lb=lower, ub=upper, solver="daqp")
    if sol is None:  # fall back to the clamped Newton step
        sol = np.clip(du, lower, upper)
    tol = 1e-9 + 1e-7 * np.maximum(1.0, np.abs(sol))
    free = (sol > lower + tol) & (sol < upper - tol)
    return sol, free


def backward_pass(dyn: MjDynamics, derivs: list, U: np.ndarray, mu: float
                  ) -> tuple[np.ndarray, np.ndarray, float, float] | None:
    """Riccati sweep (paper Eqs. 4–6 without second-order dynamics terms). None when Q_uu is not positive
    definite (the caller raises the regularisation)."""
    H = len(U)
    nx, nu = dyn.nx, dyn.nu
    k_ff = np.zeros((H, nu))
    K = np.zeros((H, nu, nx))
    _, lx, _, lxx, _, _, _, _ = derivs[H]
    Vx, Vxx = lx.copy(), lxx.copy()
    dV1 = dV2 = 0.0
    eye = np.eye(nu)
    for k in range(H - 1, -1, -1):
        _, lx, lu, lxx, luu, lux, A, B = derivs[k]
        Qx = lx + A.T @ Vx
        Qu = lu + B.T @ Vx
        VxxA = Vxx @ A
        Qxx = lxx + A.T @ VxxA
        Qux = lux + B.T @ VxxA
        Quu = luu + B.T @ Vxx @ B
        Quu = 0.5 * (Quu + Quu.T) + mu * eye
        try:
            np.linalg.cholesky(Quu)
        except np.linalg.LinAlgError:
            return None
        du, free = _box_qp(Quu, Qu, dyn.u_lower - U[k], dyn.u_upper - U[k])
        Kk = np.zeros((nu, nx))
        if free.any():
            f = np.flatnonzero(free)
            Kk[f] = -np.linalg.solve(Quu[np.ix_(f, f)], Qux[f])
        k_ff[k], K[k] = du, Kk
        dV1 += du @ Qu
        dV2 += 0.5 * du @ Quu @ du
        Vx = Qx + Kk.T @ Quu @ du + Kk.T @ Qu + Qux.T @ du
        Vxx = Qxx + Kk.T @ Quu @ Kk + Kk.T @ Qux + Qux.T @ Kk
        Vxx = 0.5 * (Vxx + Vxx.T)
    return k_ff, K, dV1, dV2


def ilqr(dyn: MjDynamics, cost: StageCost, x0: tuple, U0: np.ndarray, settings: ILQRSettings | None = None,
         cancel: Callable[[], bool] | None = None, progress: Callable[[int, float], None] | None = None) -> ILQRResult:
    """Minimise Σ l_k(x_k, u_k) + l_H(x_H) over U, torque box included, from the fixed initial state x0."""
    settings = settings or ILQRSettings()
    t_start = time.perf_counter()
    data = mujoco.MjData(dyn.model)
    U = np.clip(np.asarray(U0, dtype=float).copy(), dyn.u_lower, dyn.u_upper)
    J, states, U = rollout(dyn, cost, x0, U, data)
    if not np.isfinite(J):
        raise FloatingPointError("the initial rollout diverged")
    history = [J]
    mu = settings.mu_init
    converged = False
    t_deriv = 0.0
    it = 0
    for it in range(1, settings.max_iterations + 1):
        if cancel is not None and cancel():
            raise Cancelled()
        # derivatives along the nominal trajectory
        t0 = time.perf_counter()
        derivs = []
        for k in range(len(U) + 1):
            dyn.restore(data, states[k])
            mujoco.mj_forward(dyn.model, data)
            A: np.ndarray | None = None  # the terminal step has no dynamics
            B: np.ndarray | None = None
            if k < len(U):
                l, lx, lu, lxx, luu, lux = cost.expand(k, data, U[k])
                A, B = dyn.derivatives(states[k], U[k])
            else:
                l, lx, lu, lxx, luu, lux = cost.expand(k, data, None)
            derivs.append((l, lx, lu, lxx, luu, lux, A, B))
            if cancel is not None and k % 20 == 0 and cancel():
                raise Cancelled()
        t_deriv += time.perf_counter() - t0
        accepted = False
        while not accepted:
            bp = backward_pass(dyn, derivs, U, mu)
            if bp is None:
                mu = max(mu * 10.0, settings.mu_min)
                if mu > settings.mu_max:
                    break
                continue
            k_ff, K, dV1, dV2 = bp
            for a in settings.line_search:
                J_new, states_new, U_new = rollout(dyn, cost, x0, U, data, states, k_ff, K, a, max_cost=J * 10)
                expected = -(a * dV1 + a * a * dV2)
                if np.isfinite(J_new) and J_new < J and (expected <= 0 or (J - J_new) / expected > 1e-4):
                    accepted = True
                    break
            if accepted:
                break
            mu *= 10.0
            if mu > settings.mu_max:
                break
        if not accepted:
            converged = True  # no descent direction left at any regularisation: a local minimum
            break
        rel = (J - J_new) / max(abs(J), 1e-12)
        J, states, U = J_new, states_new, U_new
        history.append(J)
        mu = max(mu / 10.0, settings.mu_min)
        if progress is not None:
            progress(it, J)
        if rel < settings.tolerance:
            converged = True
            break
    return ILQRResult(U=U, states=states, cost=J, cost_history=history, iterations=it, converged=converged,
                      wall_time_s=time.perf_counter() - t_start, derivative_time_s=t_deriv)


class _WindowCost:
    """A stage cost seen from a window that starts at stage ``offset`` (receding horizon)."""

    def __init__(self, cost: StageCost, offset: int, end: int, last: int):
        self.cost, self.offset, self.end, self.last = cost, offset, end, last

    def value(self, k, data, u):  # noqa: ANN001, ANN201
        return self.cost.value(k + self.offset, data, u)

    def expand(self, k, data, u):  # noqa: ANN001, ANN201
        return self.cost.expand(k + self.offset, data, u)


def receding_horizon(dyn: MjDynamics, cost: StageCost, x0: tuple, U0: np.ndarray, window: int, replan_every: int,
                     settings: ILQRSettings, cancel: Callable[[], bool] | None = None,
                     progress: Callable[[int, float], None] | None = None,
                     stop: Callable[[tuple], bool] | None = None) -> ILQRResult:
    """Model-predictive tracking as MuJoCo MPC runs iLQG: solve a ``window``-step problem from the current state,
    apply the first ``replan_every`` controls, shift, warm-start with the rest. The applied controls replay
    open-loop to exactly the executed trajectory (every rollout starts from the same MjData snapshot).
    ``stop(x)`` true after a chunk (the robot fell): the rest of the horizon keeps the warm-start controls
    unsolved — a fallen evaluation is scored as fallen, there is nothing left to track."""
    t_start = time.perf_counter()
    H = len(U0)
    U_guess = np.clip(np.asarray(U0, dtype=float).copy(), dyn.u_lower, dyn.u_upper)
    U_exec = np.zeros_like(U_guess)
    states = [x0]
    x = x0
    total_iters, t_deriv = 0, 0.0
    start = 0
    while start < H:
        if cancel is not None and cancel():
            raise Cancelled()
        end = min(start + window, H)
        res = ilqr(dyn, _WindowCost(cost, start, end, H), x, U_guess[start:end], settings, cancel=cancel)
        n = min(replan_every, end - start)
        U_exec[start:start + n] = res.U[:n]
        U_guess[start:end] = res.U
        states.extend(res.states[1:n + 1])
        x = res.states[n]
        total_iters += res.iterations
        t_deriv += res.derivative_time_s
        start += n
        if progress is not None:
            progress(start, res.cost)
        if stop is not None and start < H and stop(x):
            U_exec[start:] = U_guess[start:]
            break
    # the executed trajectory's total cost (open-loop replay of the applied controls)
    data = mujoco.MjData(dyn.model)
    J, states, U_exec = rollout(dyn, cost, x0, U_exec, data)
    return ILQRResult(U=U_exec, states=states, cost=J, cost_history=[J], iterations=total_iters, converged=True,
                      wall_time_s=time.perf_counter() - t_start, derivative_time_s=t_deriv)


# ============================================================================ tracking a motion


@dataclass
class TrackingWeights:
    """Weights of the residuals (squared, ½ w r²). Units: m, rad, m/s, rad/s, N·m."""

    keypoints: float = 200.0
    base_position: float = 200.0
    base_orientation: float = 50.0
    joints: float = 2.0
    base_velocity: float = 0.5
    joint_velocity: float = 0.01
    foot_velocity_in_contact: float = 20.0  # a foot the schedule puts on the ground keeps still
    foot_clearance_in_swing: float = 200.0  # a swinging foot stays above its contact height
    torque: float = 1e-4
    torque_rate: float = 1e-4
    # the last stage of every (receding) window weighs this many stages: with a 0.25 s window it stands in for
    # the cost-to-go beyond the window, and at 5 the solver traded the window's end state for its middle —
    # go1 trot1 (α = 1) fell at 1.26 s; at 20 it stands (5.9 → 3.3 % DTW), and over the four short clips on go1
    # and a1 falls 2 → 1 of 8, mean DTW 5.18 → 4.37 %, mean keypoint error 32.4 → 26.6 mm at +8 % CPU
    # (``python tools/tmr_tracker_ab.py``); 50 fell on go1 pace1
    final_scale: float = 20.0


@dataclass
class TrackingTarget:
    """What the tracker follows at each control instant k = 0..H (H + 1 samples, spacing dt_s)."""

    dt_s: float
    qpos: np.ndarray  # (H + 1, nq)
    qvel: np.ndarray  # (H + 1, nv)
    contact: np.ndarray  # (H + 1, 4) bool
    keypoints: np.ndarray  # (H + 1, 16, 3)

    @property
    def horizon(self) -> int:
        return self.qpos.shape[0] - 1


class TrackingCost:
    """Gauss–Newton tracking cost of a :class:`TrackingTarget` (paper Eq. 9 with the foot constraints as costs)."""

    def __init__(self, model: mujoco.MjModel, keypoints: KeypointSet, target: TrackingTarget,
                 weights: TrackingWeights, joint_dof: np.ndarray, foot_radius_m: np.ndarray,
                 u_ref: np.ndarray | None = None):
        self.m, self.kp, self.target, self.w = model, keypoints, target, weights
        self.joint_dof = joint_dof
        self.foot_radius = foot_radius_m
        self.nv = model.nv
        self.nu = model.nu
        self.u_ref = np.zeros((target.horizon, model.nu)) if u_ref is None else u_ref

    def _residuals(self, k: int, data: mujoco.MjData, with_jac: bool):
        m, t, w, nv = self.m, self.target, self.w, self.nv
        nx = 2 * nv + m.na
        res, jac, wts = [], [], []
        pts = self.kp.positions(data)
        res.append((pts - t.keypoints[k]).ravel())
        wts.append(np.full(pts.size, w.keypoints))
        Jkp = None
        if with_jac:
            Jkp = self.kp.jacobians(m, data, pts)
            J = np.zeros((pts.size, nx))
            J[:, :nv] = Jkp.reshape(-1, nv)
            jac.append(J)
        # base pose and joints, in the tangent space of qpos (mj_differentiatePos: world xyz, local rotation)
        dq = np.empty(nv)
        mujoco.mj_differentiatePos(m, dq, 1.0, t.qpos[k], data.qpos)
        res += [dq[0:3], dq[3:6], dq[6:]]
        wts += [np.full(3, w.base_position), np.full(3, w.base_orientation), np.full(nv - 6, w.joints)]
        dv = data.qvel - t.qvel[k]
        res += [dv[0:6], dv[6:]]
        wts += [np.full(6, w.base_velocity), np.full(nv - 6, w.joint_velocity)]
        if with_jac:
            J = np.zeros((nv, nx))
            J[:, :nv] = np.eye(nv)
            jac.append(J)
            J = np.zeros((nv, nx))
            J[:, nv: 2 * nv] = np.eye(nv)
            jac.append(J)
        # feet: still while the schedule says contact, above the ground while it says swing
        for leg, fi in enumerate(self.kp.foot_index):
            if t.contact[k, leg]:
                jp = np.zeros((3, nv))
                mujoco.mj_jac(m, data, jp, None, pts[fi], int(self.kp.body[fi]))
                res.append(jp @ data.qvel)
                wts.append(np.full(3, w.foot_velocity_in_contact))
                if with_jac:
                    J = np.zeros((3, nx))
                    J[:, nv: 2 * nv] = jp
                    jac.append(J)
            else:
                gap = pts[fi, 2] - self.foot_radius[leg]
                res.append(np.array([min(gap, 0.0)]))
                wts.append(np.array([w.foot_clearance_in_swing]))
                if with_jac:
                    J = np.zeros((1, nx))
                    if gap < 0.0 and Jkp is not None:
                        J[0, :nv] = Jkp[fi, 2]
                    jac.append(J)
        r = np.concatenate(res)
        W = np.concatenate(wts)
        return r, W, (np.vstack(jac) if with_jac else None)

    def _control_terms(self, k: int, u: np.ndarray):
        w = self.w
        du = u - self.u_ref[k]
        return du, w.torque

    def value(self, k: int, data: mujoco.MjData, u: np.ndarray | None) -> float:
        r, W, _ = self._residuals(k, data, False)
        scale = 1.0 if u is not None else self.w.final_scale
        val = 0.5 * scale * float(r @ (W * r))
        if u is not None:
            du, wu = self._control_terms(k, u)
            val += 0.5 * wu * float(du @ du)
        return val

    def expand(self, k: int, data: mujoco.MjData, u: np.ndarray | None):
        r, W, J = self._residuals(k, data, True)
        scale = 1.0 if u is not None else self.w.final_scale
        WJ = (W * scale)[:, None] * J
        l = 0.5 * scale * float(r @ (W * r))
        lx = WJ.T @ r
        lxx = J.T @ WJ
        if u is None:
            return l, lx, np.zeros(0), lxx, np.zeros((0, 0)), np.zeros((0, J.shape[1]))
        du, wu = self._control_terms(k, u)
        l += 0.5 * wu * float(du @ du)
        lu = wu * du
        luu = wu * np.eye(self.nu)
        lux = np.zeros((self.nu, J.shape[1]))
        return l, lx, lu, lxx, luu, lux


@dataclass
class TrackResult:
    """The dynamic motion the tracker found (every array at the control rate 1/dt_s, H + 1 samples)."""

    dt_s: float
    qpos: np.ndarray  # (H + 1, nq)
    qvel: np.ndarray  # (H + 1, nv)
    ctrl: np.ndarray  # (H, nu) joint torques, actuator order
    contact: np.ndarray  # (H + 1, 4) bool: feet touching the floor in the rollout
    keypoints: np.ndarray  # (H + 1, 16, 3)
    fell: bool  # the trunk, a hip or a thigh touched the floor, or the base sank below half its standing height
    cost: float
    cost_history: list[float] = field(default_factory=list)
    fall_fraction: float = 1.0  # share of the horizon done before the first fall (1: did not fall)
    iterations: int = 0
    wall_time_s: float = 0.0
    derivative_time_s: float = 0.0


def _candidate_key(res: ILQRResult, out: TrackResult) -> tuple[bool, float, float]:
    """Order of the tracker's candidate answers: standing first, then the latest fall, then the least cost."""
    return (out.fell, -out.fall_fraction, res.cost if np.isfinite(res.cost) else np.inf)


class MotionTracker:
    """Tracks any motion (UVM, SMR, STMR, a keyframed one) of a quadruped in its full MuJoCo model.

    ``timestep_s`` is the control interval, ``physics_step_s`` MuJoCo's step inside it (default: the same 10 ms,
    the step MuJoCo MPC's tasks use; the engine's 2 ms is allowed, five times dearer). ``mode`` "receding"
    (default) solves ``window_s`` windows re-planned every ``replan_s`` as MuJoCo MPC does — and once more per
    length in ``other_windows_s`` (and in ``fallback_windows_s``, then with ``window_s`` and each terminal weight
    in ``fallback_final_scales``, one by one, while every answer falls), answering with the candidate that stands
    (else falls latest), then of least cost; "full" solves the whole horizon at once. The replay uses the very
    same model.
    """

    def __init__(self, robot, timestep_s: float = DEFAULT_TIMESTEP_S, physics_step_s: float | None = None,  # noqa: ANN001
                 weights: TrackingWeights | None = None, settings: ILQRSettings | None = None,
                 torque_limit_scale: float = 1.0, mode: str = "receding", window_s: float = 0.3,
                 replan_s: float = 0.03, window_iterations: int = 3, polish_iterations: int = 0,
                 stop_on_fall: bool = True, other_windows_s: tuple[float, ...] = (),
                 fallback_windows_s: tuple[float, ...] = (), fallback_final_scales: tuple[float, ...] = ()):
        if mode not in ("receding", "full"):
            raise ValueError(f"mode: expected 'receding' or 'full', got {mode!r}")
        self.mode = mode
        self.robot = robot
        model = robot.mj_model.__copy__()
        physics = float(physics_step_s or DEFAULT_TIMESTEP_S)
        substeps = max(1, int(round(timestep_s / physics)))
        model.opt.timestep = timestep_s / substeps
        scale = float(torque_limit_scale)
        model.actuator_ctrlrange[:] = robot.mj_model.actuator_ctrlrange * scale
        self.model = model
        self.dyn = MjDynamics(model, substeps)
        self.dt_s = self.dyn.dt_s
        self.keypoints = KeypointSet.for_robot(robot)
        self.weights = weights or TrackingWeights()
        self.settings = settings or ILQRSettings()
        self.window = max(2, int(round(window_s / self.dt_s)))
        # receding mode: further window lengths solved from the same start; the answer is the candidate whose
        # replay stands (or falls latest), then the one of least cost (the same whole-clip objective for all)
        self.other_windows = [max(2, int(round(w / self.dt_s))) for w in other_windows_s]
        # tried one at a time, in order, only while every answer so far falls (a fallen pass stops early: cheap)
        self.fallback_windows = [max(2, int(round(w / self.dt_s))) for w in fallback_windows_s]
        # then ``window_s`` again with another terminal weight (``TrackingWeights.final_scale``), one at a time while
        # every answer falls; its answer is costed with the tracker's own weights, like the other candidates
        self.fallback_final_scales = [float(s) for s in fallback_final_scales]
        self.replan = max(1, int(round(replan_s / self.dt_s)))
        self.window_settings = ILQRSettings(max_iterations=window_iterations, tolerance=1e-3)
        self.polish_iterations = int(polish_iterations)  # full-horizon iLQR after the receding pass
        self.stop_on_fall = bool(stop_on_fall)  # receding: stop solving once the trunk touches the floor
        self.joint_dof = np.asarray(robot.mj_dof_index)
        self.joint_qpos = np.asarray(robot.mj_qpos_index)
        self.actuator = np.asarray(robot.mj_actuator_index)
        self.foot_radius = np.array([model.geom_size[g][0] if g >= 0 else 0.0 for g in self.keypoints.foot_geoms])
        self._fall_geoms = self._trunk_geoms()
        # a base this low is lying on the floor even when no trunk contact registers (resting contacts at margin 0)
        self.fall_height_m = FALL_HEIGHT_FRACTION * float(robot.mj_standing_qpos()[2])

    # ------------------------------------------------------------------ set-up
    def _trunk_geoms(self) -> set[int]:
        """Collision geoms whose floor contact means a fall: everything but the lower legs and feet."""
        m = self.model
        lower = set()
        for fb in self.keypoints.foot_body:
            lower.add(int(fb))
        for i, b in enumerate(self.keypoints.body):
            if i % 4 == 2:  # knee joint body: the shank
                lower.add(int(b))
        # bodies below a shank (feet, rotors) count as lower leg too
        for b in range(1, m.nbody):
            p = b
            while p > 0:
                if p in lower:
                    lower.add(b)
                    break
                p = int(m.body_parentid[p])
        return {g for g in range(m.ngeom) if m.geom_contype[g] and int(m.geom_bodyid[g]) not in lower
                and int(m.geom_bodyid[g]) != 0}

    def initial_state(self, qpos0: np.ndarray, qvel0: np.ndarray | None = None) -> tuple:
        d = mujoco.MjData(self.model)
        d.qpos[:] = qpos0
        if qvel0 is not None:
            d.qvel[:] = qvel0
        return MjDynamics.snapshot(d)

    def make_cost(self, target: TrackingTarget, u_ref: np.ndarray | None = None,
                  weights: TrackingWeights | None = None) -> TrackingCost:
        return TrackingCost(self.model, self.keypoints, target, weights or self.weights, self.joint_dof,
                            self.foot_radius, u_ref)

    def stance_torques(self, target: TrackingTarget) -> np.ndarray:
        """Feed-forward guess per step: gravity and Coriolis of the target minus Jᵀ f with the weight shared by
        the feet the schedule puts on the ground."""
        m = self.model
        d = mujoco.MjData(m)
        weight = float(np.sum(m.body_mass)) * float(-m.opt.gravity[2])
        H = target.horizon
        U = np.zeros((H, m.nu))
        for k in range(H):
            d.qpos[:] = target.qpos[k]
            d.qvel[:] = target.qvel[k]
            mujoco.mj_forward(m, d)
            tau = d.qfrc_bias.copy()
            stance = np.flatnonzero(target.contact[k])
            if len(stance):
                pts = self.keypoints.positions(d)
                for leg in stance:
                    fi = self.keypoints.foot_index[leg]
                    jp = np.zeros((3, m.nv))
                    mujoco.mj_jac(m, d, jp, None, pts[fi], int(self.keypoints.body[fi]))
                    tau -= jp.T @ np.array([0.0, 0.0, weight / len(stance)])
            U[k, self.actuator] = tau[self.joint_dof]
        return np.clip(U, self.dyn.u_lower, self.dyn.u_upper)

    def pd_initial_controls(self, target: TrackingTarget, u_ff: np.ndarray, gain_scale: float = 1.0) -> np.ndarray:
        """Initial guess: roll out PD on the target joints plus the feed-forward, record the torques."""
        m, dyn = self.model, self.dyn
        d = mujoco.MjData(m)
        dyn.restore(d, self.initial_state(target.qpos[0], target.qvel[0]))
        kp = self.robot.kp * gain_scale
        kd = self.robot.kd * gain_scale
        U = np.zeros((target.horizon, m.nu))
        for k in range(target.horizon):
            q = d.qpos[self.joint_qpos]
            v = d.qvel[self.joint_dof]
            tau = u_ff[k].copy()
            tau[self.actuator] += kp * (target.qpos[k, self.joint_qpos] - q) + kd * (target.qvel[k, self.joint_dof] - v)
            U[k] = np.clip(tau, dyn.u_lower, dyn.u_upper)
            dyn.step(d, U[k])
            if not np.all(np.isfinite(d.qpos)):
                break
        return U

    # ------------------------------------------------------------------ solve & replay
    def track(self, target: TrackingTarget, U0: np.ndarray | None = None, cancel: Callable[[], bool] | None = None,
              progress: Callable[[int, float], None] | None = None) -> TrackResult:
        if abs(target.dt_s - self.dt_s) > 1e-9:
            raise ValueError(f"target spacing {target.dt_s} s differs from the tracker's control interval {self.dt_s} s")
        u_ff = self.stance_torques(target)
        if U0 is None:
            U0 = self.pd_initial_controls(target, u_ff)
        cost = self.make_cost(target, u_ref=u_ff)
        x0 = self.initial_state(target.qpos[0], target.qvel[0])
        if self.mode == "receding":
            best: tuple[ILQRResult, TrackResult] | None = None
            wall_s = deriv_s = 0.0
            always = 1 + len(self.other_windows)
            candidates: list[tuple[int, float | None]] = [
                *((w, None) for w in [self.window, *self.other_windows, *self.fallback_windows]),
                *((self.window, s) for s in self.fallback_final_scales)]
            for i, (window, final_scale) in enumerate(candidates):
                if i >= always and best is not None and not best[1].fell:
                    break
                # each candidate polished before the choice: a receding replay that touches the floor on the way
                # can stand once polished (go1 trot1's 0.4 s window: chosen after the polish, 3.18 → 2.88 % DTW)
                if final_scale is None:
                    res, out = self._receding(target, cost, x0, U0, window, cancel, progress)
                else:
                    own = self.make_cost(target, u_ref=u_ff, weights=replace(self.weights, final_scale=final_scale))
                    res, out = self._receding(target, own, x0, U0, window, cancel, progress)
                    # the same whole-clip objective for every candidate: the tracker's own terminal weight
                    res.cost = rollout(self.dyn, cost, x0, res.U, mujoco.MjData(self.model))[0]
                wall_s += res.wall_time_s
                deriv_s += res.derivative_time_s
                if best is None or _candidate_key(res, out) < _candidate_key(*best):
                    best = (res, out)
            assert best is not None
            res, out = best
            res.wall_time_s, res.derivative_time_s = wall_s, deriv_s
        else:
            res = ilqr(self.dyn, cost, x0, U0, self.settings, cancel=cancel, progress=progress)
            out = self.replay(target.qpos[0], target.qvel[0], res.U)
        out.cost, out.cost_history, out.iterations = res.cost, res.cost_history, res.iterations
        out.wall_time_s, out.derivative_time_s = res.wall_time_s, res.derivative_time_s
        return out

    def _receding(self, target: TrackingTarget, cost: TrackingCost, x0: tuple, U0: np.ndarray, window: int,
                  cancel: Callable[[], bool] | None, progress: Callable[[int, float], None] | None
                  ) -> tuple[ILQRResult, TrackResult]:
        """The receding-horizon pass with ``window`` steps, its open-loop replay, then the whole-clip polish."""
        res = receding_horizon(self.dyn, cost, x0, U0, window, self.replan, self.window_settings, cancel=cancel,
                               progress=progress, stop=self.fallen if self.stop_on_fall else None)
        out = self.replay(target.qpos[0], target.qvel[0], res.U)
        if self.polish_iterations > 0 and not self.fallen(res.states[-1]):
            res, out = self._polish(target, cost, x0, res, out, cancel)
        return res, out

    def _polish(self, target: TrackingTarget, cost: TrackingCost, x0: tuple, res: ILQRResult, out: TrackResult,
                cancel: Callable[[], bool] | None) -> tuple[ILQRResult, TrackResult]:
        """Full-horizon iLQR from the receding answer: lowers the whole motion's cost (the windows each saw a
        fraction of a second); the cost has no fall term, so a polished replay that falls where the receding one
        stood is not taken."""
        polished = ilqr(self.dyn, cost, x0, res.U, ILQRSettings(max_iterations=self.polish_iterations), cancel=cancel)
        polished.wall_time_s += res.wall_time_s
        polished.derivative_time_s += res.derivative_time_s
        out_polished = self.replay(target.qpos[0], target.qvel[0], polished.U)
        if out_polished.fell <= out.fell:
            return polished, out_polished
        res.wall_time_s, res.derivative_time_s = polished.wall_time_s, polished.derivative_time_s
        return res, out

    def replay(self, qpos0: np.ndarray, qvel0: np.ndarray, U: np.ndarray) -> TrackResult:
        """Open-loop replay of the controls from the initial state, in the tracker's MuJoCo model."""
        m, dyn = self.model, self.dyn
        d = mujoco.MjData(m)
        dyn.restore(d, self.initial_state(qpos0, qvel0))
        H = len(U)
        qpos = np.zeros((H + 1, m.nq))
        qvel = np.zeros((H + 1, m.nv))
        contact = np.zeros((H + 1, 4), dtype=bool)
        kps = np.zeros((H + 1, 16, 3))
        fell = False
        fall_k = H
        for k in range(H + 1):
            mujoco.mj_forward(m, d)
            qpos[k], qvel[k] = d.qpos, d.qvel
            kps[k] = self.keypoints.positions(d)
            c, f = self._contacts(d)
            contact[k] = c
            if f and not fell:
                fall_k = k
            fell = fell or f
            if k < H:
                dyn.step(d, U[k])
                if not np.all(np.isfinite(d.qpos)):
                    qpos[k + 1:], qvel[k + 1:], kps[k + 1:] = qpos[k], 0.0, kps[k]
                    fall_k = k if not fell else fall_k
                    fell = True
                    break
        return TrackResult(self.dt_s, qpos, qvel, np.asarray(U).copy(), contact, kps, fell, cost=float("nan"),
                           fall_fraction=(fall_k / H if fell and H else 1.0))

    def fallen(self, snap: tuple) -> bool:
        """The trunk, a hip or a thigh touches the floor in state ``snap``."""
        d = mujoco.MjData(self.model)
        MjDynamics.restore(d, snap)
        mujoco.mj_forward(self.model, d)
        return self._contacts(d)[1]

    def _contacts(self, d: mujoco.MjData) -> tuple[np.ndarray, bool]:
        feet = np.zeros(4, dtype=bool)
        fell = bool(d.qpos[2] < self.fall_height_m)
        geoms = self.keypoints.foot_geoms
        for c in d.contact[: d.ncon]:
            pair = (int(c.geom1), int(c.geom2))
            other = pair[1] if self.model.geom_bodyid[pair[0]] == 0 else (pair[0] if self.model.geom_bodyid[pair[1]] == 0 else -1)
            if other < 0:
                continue
            if other in geoms:
                feet[geoms.index(other)] = True
            elif other in self._fall_geoms:
                fell = True
        return feet, fell
