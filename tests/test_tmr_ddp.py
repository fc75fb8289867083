"""Box-iLQR on MuJoCo derivatives (TMR's inner problem): derivatives against finite differences, cost descent,
torque box, and the open-loop replay reproducing the solver's trajectory."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from engine.retarget.quadruped.tmr.ddp import ILQRSettings, MjDynamics, ilqr, rollout

ARM_XML = """
<mujoco>
  <option timestep="0.005"/>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body name="a" pos="0 0 1">
      <joint name="j1" type="hinge" axis="0 1 0" damping="0.05"/>
      <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" mass="1"/>
      <body name="b" pos="0.4 0 0">
        <joint name="j2" type="hinge" axis="0 1 0" damping="0.05"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.04" mass="0.5"/>
        <site name="tip" pos="0.4 0 0"/>
      </body>
    </body>
  </worldbody>
  <actuator>
    <motor joint="j1" ctrllimited="true" ctrlrange="-8 8"/>
    <motor joint="j2" ctrllimited="true" ctrlrange="-4 4"/>
  </actuator>
</mujoco>
"""


@pytest.fixture(scope="module")
def arm() -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(ARM_XML)


def _step_composite(dyn: MjDynamics, snap: tuple, u: np.ndarray) -> tuple:
    d = mujoco.MjData(dyn.model)
    dyn.restore(d, snap)
    dyn.step(d, u)
    return dyn.snapshot(d)


def test_chained_derivatives_match_central_differences(arm: mujoco.MjModel) -> None:
    dyn = MjDynamics(arm, substeps=3)
    d = mujoco.MjData(arm)
    d.qpos[:] = [0.4, -0.7]
    d.qvel[:] = [0.3, -0.2]
    snap = dyn.snapshot(d)
    u = np.array([1.0, -0.5])
    A, B = dyn.derivatives(snap, u)
    base = _step_composite(dyn, snap, u)
    eps = 1e-6
    A_fd = np.zeros_like(A)
    for i in range(dyn.nx):
        cols = []
        for sgn in (1, -1):
            dx = np.zeros(dyn.nx)
            dx[i] = sgn * eps
            s = list(snap)
            qpos = s[0].copy()
            mujoco.mj_integratePos(arm, qpos, dx[: arm.nv], 1.0)
            s[0], s[1] = qpos, s[1] + dx[arm.nv:]
            cols.append(dyn.state_difference(base, _step_composite(dyn, tuple(s), u)))
        A_fd[:, i] = (cols[0] - cols[1]) / (2 * eps)
    B_fd = np.zeros_like(B)
    for i in range(dyn.nu):
        du = np.zeros(dyn.nu)
        du[i] = eps
        B_fd[:, i] = (dyn.state_difference(base, _step_composite(dyn, snap, u + du))
                      - dyn.state_difference(base, _step_composite(dyn, snap, u - du))) / (2 * eps)
    np.testing.assert_allclose(A, A_fd, atol=1e-4 * max(1.0, np.abs(A_fd).max()))
    np.testing.assert_allclose(B, B_fd, atol=1e-4 * max(1.0, np.abs(B_fd).max()))


class TipCost:
    """Bring the arm tip to a point and hold it (quadratic in the tip error, the velocity and the torque)."""

    def __init__(self, model: mujoco.MjModel, goal: np.ndarray):
        self.m, self.goal = model, goal
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tip")

    def _res(self, data: mujoco.MjData):
        r = np.concatenate([10.0 * (data.site_xpos[self.site] - self.goal), 0.3 * data.qvel])
        jac = np.zeros((3, self.m.nv))
        mujoco.mj_jacSite(self.m, data, jac, None, self.site)
        J = np.zeros((3 + self.m.nv, 2 * self.m.nv))
        J[:3, : self.m.nv] = 10.0 * jac
        J[3:, self.m.nv:] = 0.3 * np.eye(self.m.nv)
        return r, J

    def value(self, k, data, u):  # noqa: ANN001, ANN201
        r, _ = self._res(data)
        return 0.5 * r @ r + (0.0 if u is None else 0.5e-3 * u @ u)

    def expand(self, k, data, u):  # noqa: ANN001, ANN201
        r, J = self._res(data)
        l = 0.5 * r @ r
        if u is None:
            return l, J.T @ r, np.zeros(0), J.T @ J, np.zeros((0, 0)), np.zeros((0, J.shape[1]))
        return (l + 0.5e-3 * u @ u, J.T @ r, 1e-3 * u, J.T @ J, 1e-3 * np.eye(len(u)), np.zeros((len(u), J.shape[1])))


def test_ilqr_decreases_the_cost_within_the_torque_box_and_replays_exactly(arm: mujoco.MjModel) -> None:
    dyn = MjDynamics(arm, substeps=2)
    d = mujoco.MjData(arm)
    x0 = dyn.snapshot(d)
    cost = TipCost(arm, np.array([0.3, 0.0, 1.5]))
    U0 = np.zeros((60, arm.nu))
    res = ilqr(dyn, cost, x0, U0, ILQRSettings(max_iterations=25))
    hist = np.array(res.cost_history)
    assert np.all(np.diff(hist) <= 1e-12), "every accepted iteration lowers the cost"
    assert hist[-1] < 0.2 * hist[0]
    assert np.all(res.U >= dyn.u_lower - 1e-12) and np.all(res.U <= dyn.u_upper + 1e-12)
    assert np.any(np.isclose(np.abs(res.U[:, 0]), 8.0)), "the box is active somewhere (the goal needs more torque)"
    J, states, _ = rollout(dyn, cost, x0, res.U, mujoco.MjData(arm))
    assert J == pytest.approx(res.cost, rel=1e-12)
    for a, b in zip(states, res.states):
        np.testing.assert_array_equal(a[0], b[0])


def test_tracking_cost_gradient_matches_finite_differences() -> None:
    from engine.retarget.quadruped.tmr.ddp import MotionTracker, TrackingTarget
    from engine.retarget.quadruped.tmr.keypoints import keypoint_trajectory
    from engine.robot.model import load_robot

    robot = load_robot("go1")
    tracker = MotionTracker(robot)
    m = tracker.model
    q_ref = robot.mj_standing_qpos()
    target = TrackingTarget(tracker.dt_s, q_ref[None].repeat(2, 0), np.zeros((2, m.nv)),
                            np.array([[True, False, True, True]] * 2), keypoint_trajectory(robot, q_ref[None].repeat(2, 0)))
    cost = tracker.make_cost(target)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(3)
    q = q_ref.copy()
    mujoco.mj_integratePos(m, q, 0.02 * rng.standard_normal(m.nv), 1.0)
    q[2] += 0.05  # lift so that the swing foot's clearance term is inactive and smooth
    d.qpos[:] = q
    mujoco.mj_forward(m, d)
    u = np.zeros(m.nu)
    _, lx, _, _, _, _ = cost.expand(0, d, u)
    eps = 1e-6
    g = np.zeros(m.nv)
    for i in range(m.nv):
        vals = []
        for sgn in (1, -1):
            qq = q.copy()
            dq = np.zeros(m.nv)
            dq[i] = sgn * eps
            mujoco.mj_integratePos(m, qq, dq, 1.0)
            d.qpos[:] = qq
            mujoco.mj_forward(m, d)
            vals.append(cost.value(0, d, u))
        g[i] = (vals[0] - vals[1]) / (2 * eps)
    # the orientation residual's Jacobian is the identity (exact at zero error): allow a small relative slack
    np.testing.assert_allclose(lx[: m.nv], g, rtol=2e-2, atol=1e-3 * np.abs(g).max())


def test_polish_lowers_the_receding_cost_and_is_dropped_when_its_replay_falls() -> None:
    """The full-horizon polish after the receding pass only lowers the cost of the same open-loop motion, and a
    polished replay that falls where the receding one stood is not taken."""
    from dataclasses import replace

    from engine.retarget.quadruped.tmr.ddp import MotionTracker, TrackingTarget
    from engine.retarget.quadruped.tmr.keypoints import keypoint_trajectory
    from engine.robot.model import load_robot

    robot = load_robot("go1")
    H = 20
    q_ref = robot.mj_standing_qpos()[None].repeat(H + 1, 0)
    q_ref[:, 0] += 0.2 * np.linspace(0.0, H * 0.01, H + 1)  # drift forward at 0.2 m/s on four feet
    qvel = np.zeros((H + 1, robot.mj_model.nv))
    qvel[:, 0] = 0.2
    target = TrackingTarget(0.01, q_ref, qvel, np.ones((H + 1, 4), bool), keypoint_trajectory(robot, q_ref))
    receding = MotionTracker(robot, window_s=0.1, replan_s=0.05, window_iterations=2, polish_iterations=0).track(target)
    polisher = MotionTracker(robot, window_s=0.1, replan_s=0.05, window_iterations=2, polish_iterations=3)
    polished = polisher.track(target)
    assert not receding.fell and not polished.fell
    assert polished.cost < receding.cost
    assert not np.array_equal(polished.ctrl, receding.ctrl)

    real_replay = polisher.replay
    calls = []

    def second_replay_falls(qpos0: np.ndarray, qvel0: np.ndarray, U: np.ndarray):  # noqa: ANN202
        out = real_replay(qpos0, qvel0, U)
        calls.append(1)
        return replace(out, fell=True, fall_fraction=0.5) if len(calls) == 2 else out

    polisher.replay = second_replay_falls  # type: ignore[method-assign]
    kept = polisher.track(target)
    assert len(calls) == 2
    assert not kept.fell
    np.testing.assert_array_equal(kept.ctrl, receding.ctrl)



def _gliding_target(robot, steps: int = 20):  # noqa: ANN001, ANN202
    """A standing pose that glides forward at 0.2 m/s over ``steps`` ticks of 10 ms: a target the tracker can meet."""
    from engine.retarget.quadruped.tmr.ddp import TrackingTarget
    from engine.retarget.quadruped.tmr.keypoints import keypoint_trajectory

    q_ref = robot.mj_standing_qpos()[None].repeat(steps + 1, 0)
    q_ref[:, 0] += 0.2 * np.linspace(0.0, steps * 0.01, steps + 1)
    qvel = np.zeros((steps + 1, robot.mj_model.nv))
    qvel[:, 0] = 0.2
    return TrackingTarget(0.01, q_ref, qvel, np.ones((steps + 1, 4), bool), keypoint_trajectory(robot, q_ref))


def test_other_windows_keep_the_standing_answer_of_least_cost() -> None:
    """With further receding windows the tracker answers with the candidate of least whole-clip cost among those
    whose replay stands; a cheaper candidate that falls is passed over."""
    from dataclasses import replace

    from engine.retarget.quadruped.tmr.ddp import MotionTracker
    from engine.robot.model import load_robot

    robot = load_robot("go1")
    target = _gliding_target(robot)
    kw: dict = {"replan_s": 0.05, "window_iterations": 2, "polish_iterations": 0}
    short = MotionTracker(robot, window_s=0.1, **kw).track(target)
    long = MotionTracker(robot, window_s=0.2, **kw).track(target)
    assert not short.fell and not long.fell and short.cost != long.cost
    cheaper, dearer = (short, long) if short.cost < long.cost else (long, short)
    both = MotionTracker(robot, window_s=0.1, other_windows_s=(0.2,), **kw)
    best = both.track(target)
    assert best.cost == cheaper.cost
    np.testing.assert_array_equal(best.ctrl, cheaper.ctrl)

    real_replay = both.replay

    def cheaper_falls(qpos0: np.ndarray, qvel0: np.ndarray, U: np.ndarray):  # noqa: ANN202
        out = real_replay(qpos0, qvel0, U)
        return replace(out, fell=True, fall_fraction=0.5) if np.array_equal(U, cheaper.ctrl) else out

    both.replay = cheaper_falls  # type: ignore[method-assign]
    kept = both.track(target)
    assert not kept.fell and kept.cost == dearer.cost
    np.testing.assert_array_equal(kept.ctrl, dearer.ctrl)


def test_fallback_windows_run_only_while_every_answer_falls() -> None:
    """A fallback window is solved only when the regular candidates all fall, and its standing answer is kept."""
    from dataclasses import replace

    from engine.retarget.quadruped.tmr.ddp import MotionTracker, TrackingTarget
    from engine.retarget.quadruped.tmr.keypoints import keypoint_trajectory
    from engine.robot.model import load_robot

    robot = load_robot("go1")
    H = 20
    q_ref = robot.mj_standing_qpos()[None].repeat(H + 1, 0)
    target = TrackingTarget(0.01, q_ref, np.zeros((H + 1, robot.mj_model.nv)), np.ones((H + 1, 4), bool),
                            keypoint_trajectory(robot, q_ref))
    kw: dict = {"replan_s": 0.05, "window_iterations": 2, "polish_iterations": 0}
    fallback_alone = MotionTracker(robot, window_s=0.2, **kw).track(target)
    tracker = MotionTracker(robot, window_s=0.1, fallback_windows_s=(0.2,), **kw)
    real_replay = tracker.replay
    calls: list[bool] = []

    def first_falls(qpos0: np.ndarray, qvel0: np.ndarray, U: np.ndarray):  # noqa: ANN202
        out = real_replay(qpos0, qvel0, U)
        calls.append(True)
        return replace(out, fell=True, fall_fraction=0.5) if len(calls) == 1 else out

    tracker.replay = first_falls  # type: ignore[method-assign]
    kept = tracker.track(target)
    assert len(calls) == 2 and not kept.fell
    np.testing.assert_array_equal(kept.ctrl, fallback_alone.ctrl)
    calls.clear()

    def counted(qpos0: np.ndarray, qvel0: np.ndarray, U: np.ndarray):  # noqa: ANN202
        calls.append(True)
        return real_replay(qpos0, qvel0, U)

    tracker.replay = counted  # type: ignore[method-assign]
    standing = tracker.track(target)  # the first answer stands: the fallback is not solved
    assert len(calls) == 1 and not standing.fell
    assert not np.array_equal(standing.ctrl, fallback_alone.ctrl)


def test_fallback_final_scale_runs_last_and_is_costed_with_the_trackers_weights() -> None:
    """A fallback terminal weight is solved (with ``window_s``) only once every other answer falls; its standing
    answer is the one a tracker with that terminal weight finds, and its cost is the tracker's own objective."""
    from dataclasses import replace

    from engine.retarget.quadruped.tmr.ddp import MotionTracker, TrackingWeights, rollout
    from engine.robot.model import load_robot

    robot = load_robot("go1")
    target = _gliding_target(robot)
    kw: dict = {"window_s": 0.1, "replan_s": 0.05, "window_iterations": 2, "polish_iterations": 0}
    low = MotionTracker(robot, weights=TrackingWeights(final_scale=2.0), **kw).track(target)
    tracker = MotionTracker(robot, fallback_windows_s=(0.2,), fallback_final_scales=(2.0,), **kw)
    high = MotionTracker(robot, **kw).track(target)
    assert not low.fell and not np.array_equal(low.ctrl, high.ctrl)
    real_replay = tracker.replay
    calls: list[bool] = []

    def all_but_last_fall(qpos0: np.ndarray, qvel0: np.ndarray, U: np.ndarray):  # noqa: ANN202
        out = real_replay(qpos0, qvel0, U)
        calls.append(True)
        return replace(out, fell=True, fall_fraction=0.5) if len(calls) < 3 else out

    tracker.replay = all_but_last_fall  # type: ignore[method-assign]
    kept = tracker.track(target)
    assert len(calls) == 3 and not kept.fell
    np.testing.assert_array_equal(kept.ctrl, low.ctrl)
    u_ff = tracker.stance_torques(target)
    own_cost = rollout(tracker.dyn, tracker.make_cost(target, u_ref=u_ff), tracker.initial_state(target.qpos[0], target.qvel[0]),
                       kept.ctrl, mujoco.MjData(tracker.model))[0]
    assert kept.cost == pytest.approx(own_cost) and kept.cost != pytest.approx(low.cost)
    calls.clear()
    tracker.replay = lambda q0, v0, U: (calls.append(True), real_replay(q0, v0, U))[1]  # type: ignore[method-assign]
    standing = tracker.track(target)  # the first answer stands: no fallback is solved
    assert len(calls) == 1 and not standing.fell
    np.testing.assert_array_equal(standing.ctrl, high.ctrl)
