"""TMR end to end on motions the project makes itself: a standing clip is trivially feasible (α stays 1, the
open-loop replay stands with near-zero tracking error); the dynamic motion's fields are consistent."""

from __future__ import annotations

import numpy as np
import pytest

from engine.retarget.quadruped.tmr import kinematic_clips
from engine.retarget.quadruped.tmr.ddp import MotionTracker
from engine.retarget.motion import RobotMotion
from engine.retarget.quadruped.tmr.tmr import TMRSettings, temporal_retarget
from engine.robot.model import load_robot


@pytest.fixture(scope="module")
def go1():  # noqa: ANN201
    return load_robot("go1")


@pytest.fixture(scope="module")
def standing_result(go1):  # noqa: ANN001, ANN201
    motion = kinematic_clips.standing(go1, duration_s=0.2)
    seen = []
    result = temporal_retarget(motion, TMRSettings(budget=3, init_points=3), progress=seen.append)
    return motion, result, seen


def test_standing_keeps_alpha_one_and_tracks_within_millimetres(standing_result) -> None:  # noqa: ANN001
    motion, result, seen = standing_result
    s = result.summary
    assert s["alpha"] == [1.0]
    assert s["duration_s"]["after"] == pytest.approx(s["duration_s"]["before"])
    assert not s["replay_fell"]
    assert s["tracking_error_mm"] < 5.0
    assert s["bo_evaluations"] == 3 and [p.evaluation for p in seen] == [1, 2, 3]


def test_dynamic_motion_replays_and_its_pd_targets_reproduce_the_torques(go1, standing_result, tmp_path) -> None:  # noqa: ANN001
    _, result, _ = standing_result
    path = tmp_path / "stand_tmr.npz"
    result.motion.save(path)
    m = RobotMotion.load(path)
    assert m.method == "stmr" and m.fps == pytest.approx(100.0)
    assert m.qvel.shape == (m.frames, go1.mj_model.nv) and m.ctrl.shape == (m.frames, 12)
    lim = go1.effort_limits.max()
    assert np.all(np.abs(m.ctrl) <= lim + 1e-9)
    kp, kd = m.extra["pd_kp"], m.extra["pd_kd"]
    theta, dtheta = m.qpos[:, 7:], m.qvel[:, 6:]
    np.testing.assert_allclose(kp * (m.extra["pd_targets"] - theta) - kd * dtheta, m.ctrl, atol=1e-9)
    # open-loop replay of the stored torques (joint order → actuators) gives the stored trajectory
    tracker = MotionTracker(go1)
    names = list(m.joint_names)
    U = np.zeros((m.frames - 1, tracker.model.nu))
    for j, n in enumerate(names):
        U[:, int(go1.mj_actuator_index[go1.joint_names.index(n)])] = m.ctrl[:-1, j]
    replay = tracker.replay(m.qpos[0], m.qvel[0], U)
    np.testing.assert_allclose(replay.qpos, m.qpos, atol=1e-9)


def test_tracker_detects_a_fall(go1) -> None:  # noqa: ANN001
    tracker = MotionTracker(go1)
    q0 = go1.mj_standing_qpos()
    replay = tracker.replay(q0, np.zeros(tracker.model.nv), np.zeros((120, tracker.model.nu)))
    assert replay.fell, "zero torque: the trunk drops onto the floor"
    assert replay.qpos[-1, 2] < 0.5 * q0[2]



def test_shipped_backflip_turns_once_with_a_ballistic_flight_and_clean_feet() -> None:
    from tests.conftest import REPO

    m = RobotMotion.load(REPO / "motions" / "go1" / "backflip.npz")
    assert m.robot == "go1" and m.source["keyframes"] == 12 and (m.frames - 1) / m.fps == pytest.approx(1.48)
    q = m.qpos
    pitch = np.unwrap(2.0 * np.arctan2(q[:, 5], q[:, 3]))  # rotation about y (x = z = 0 in this clip)
    assert np.allclose(q[:, [4, 6]], 0.0, atol=1e-9)
    assert pitch[-1] - pitch[0] == pytest.approx(-2.0 * np.pi, abs=1e-6)
    air = ~m.contact.any(axis=1)
    assert air.sum() / m.fps == pytest.approx(0.40, abs=0.03)
    z = q[air, 2]
    acc = np.diff(z, 2) * m.fps**2
    np.testing.assert_allclose(acc, -9.81, atol=0.05)  # ballistic base in flight
    feet = m.keypoints[:, [3, 7, 11, 15]]
    assert feet[..., 2].min() >= 0.02 - 1e-6  # foot spheres (r = 2 cm) never below the floor
    for leg in range(4):
        both = m.contact[1:, leg] & m.contact[:-1, leg]
        slide = np.linalg.norm(np.diff(feet[:, leg], axis=0), axis=1)[both]
        assert slide.max() < 1e-3


def test_when_every_alpha_within_the_bound_falls_the_search_widens(go1, monkeypatch) -> None:  # noqa: ANN001
    """a1's HopTurn falls at every α in [½, 2] and stands at α = 0.33: TMR goes on over the widened bound, from
    the far end on the side of the fall that got furthest, and reports the bound it searched. Here the replays of
    a standing clip are made to 'fall' above log2 α = −1.3 (the real evaluation, its verdict overridden)."""
    import engine.retarget.quadruped.tmr.tmr as tmr

    real = tmr.evaluate_alpha
    evaluated = []

    def evaluate(robot_name, qpos, contact, fps, log2_alpha, settings, cancel=None):  # noqa: ANN001, ANN202
        ev = real(robot_name, qpos, contact, fps, log2_alpha, settings, cancel)
        evaluated.append(float(log2_alpha[0]))
        if log2_alpha[0] > -1.3:  # a fall: the later in the clip, the closer to the bound (as the fall shaping does)
            ev.fell = True
            ev.score = {**ev.score, "score": -2.0 + 0.1 * float(-log2_alpha[0]), "fell_at_s": 0.1}
        return ev

    monkeypatch.setattr(tmr, "evaluate_alpha", evaluate)
    motion = kinematic_clips.standing(go1, duration_s=0.2)
    narrow = temporal_retarget(motion, TMRSettings(budget=3, init_points=3, widen_budget=0))
    assert narrow.summary["replay_fell"] and narrow.summary["log2_bound_searched"] == 1.0
    evaluated.clear()
    seen = []
    res = temporal_retarget(motion, TMRSettings(budget=3, init_points=3, widen_log2_bound=1.6, widen_budget=1),
                            progress=seen.append)
    s = res.summary
    assert evaluated == [0.0, -1.0, 1.0, -1.6], "the widened search starts at the far end of the falls' better side"
    assert [(p.evaluation, p.budget, p.stage) for p in seen] == [(1, 3, ""), (2, 3, ""), (3, 3, ""), (4, 4, "widened")]
    assert s["log2_bound"] == 1.0 and s["log2_bound_searched"] == 1.6 and s["bo_evaluations_widened"] == 1
    assert not s["replay_fell"] and s["alpha"] == [pytest.approx(2.0 ** -1.6, abs=1e-4)] and s["bo_evaluations"] == 4
    assert len(res.evaluations) == 4 and [e["replay_fell"] for e in res.evaluations] == [True, True, True, False]
