"""Capsules (§III): segment–segment distance against brute force, the fixer's monotonicity, MuJoCo agreement."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from engine.retarget.humanoid_arm.capsules import CapsuleModel, fit_capsule, mujoco_agreement, segment_distance
from engine.retarget.humanoid_arm.upper_body import UpperBody

coord = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
point = st.tuples(coord, coord, coord).map(np.array)


@example(p1=np.array([0.0, 0.0, 6.103515625e-05]), q1=np.zeros(3), p2=np.zeros(3), q2=np.array([0.0, 0.015625, 0.0]))
# nearly antiparallel segments sharing an end (q1 = p2): distance 0, not the 6e-6 m of taking s = 0
@example(p1=np.zeros(3), q1=np.array([0.0, 1.0, 0.0]), p2=np.array([0.0, 1.0, 0.0]), q2=np.array([0.0, 0.0, 6.3e-6]))
# two 1 m segments crossing in an X at 1.3e-5 rad: they meet, not 6e-6 m apart
@example(p1=np.zeros(3), q1=np.array([6.3e-6, 1.0, 0.0]), p2=np.array([0.0, 1.0, 0.0]), q2=np.array([6.3e-6, 0.0, 0.0]))
@settings(max_examples=100, deadline=None)
@given(point, point, point, point)
def test_segment_distance_matches_brute_force(p1, q1, p2, q2):
    d, c1, c2 = segment_distance(p1, q1, p2, q2)
    s = np.linspace(0, 1, 401)
    a = p1 + s[:, None] * (q1 - p1)
    b = p2 + s[:, None] * (q2 - p2)
    brute = np.min(np.linalg.norm(a[:, None] - b[None], axis=-1))
    # never more than any sampled pair, to within the implementation's degenerate threshold: a segment
    # shorter than 1 µm (squared length ≤ 1e-12) counts as its first point (Ericson's special case)
    assert d <= brute + 2e-6
    # grid spacing bounds how far the sampled minimum can be above the true one
    assert brute - d <= 0.5 * (np.linalg.norm(q1 - p1) + np.linalg.norm(q2 - p2)) / 400 + 1e-9
    assert np.linalg.norm(c1 - c2) == pytest.approx(d, abs=1e-9)


@settings(max_examples=50, deadline=None)
@given(st.lists(point, min_size=4, max_size=40))
def test_fitted_capsule_encloses_its_points(points):
    pts = np.array(points)
    a, b, r = fit_capsule(pts)
    d, _, _ = segment_distance(pts, np.broadcast_to(b, pts.shape), np.broadcast_to(a, pts.shape), np.broadcast_to(a, pts.shape))
    dist = np.array([segment_distance(p, p, a, b)[0] for p in pts])
    assert np.all(dist <= r + 1e-9)
    del d


@pytest.fixture(scope="module")
def g1_capsules():
    return CapsuleModel(UpperBody("g1"))


def test_fixer_never_increases_penetration_and_frees_most_random_poses(g1_capsules):
    cm = g1_capsules
    rng = np.random.default_rng(3)
    freed = colliding = 0
    for _ in range(15):
        x = rng.uniform(cm.ub.lower, cm.ub.upper)
        before = cm.penetration(x)
        fixed, ok = cm.fix(x)
        after = cm.penetration(fixed)
        assert after <= before + 1e-12
        assert np.all(fixed >= cm.ub.lower - 1e-12) and np.all(fixed <= cm.ub.upper + 1e-12)
        if before > 0:
            colliding += 1
            freed += ok
        if ok:
            assert np.all(cm.signed_distances(fixed) >= 0)
    assert colliding > 3 and freed >= 0.8 * colliding


def test_capsules_are_conservative_against_mujoco(g1_capsules):
    report = mujoco_agreement(g1_capsules, n_poses=60, seed=5)
    assert report["mujoco_only"] == 0, report
    assert report["both_collide"] > 0


@pytest.mark.parametrize("robot", ["g1", "talos"])
def test_coal_distances_equal_the_numpy_segment_test(robot, g1_capsules):
    """The run-time path (coal capsules through pinocchio) gives the reference numbers, penetrations included."""
    cm = g1_capsules if robot == "g1" else CapsuleModel(UpperBody(robot))
    rng = np.random.default_rng(7)
    negatives = 0
    for _ in range(60):
        x = rng.uniform(cm.ub.lower, cm.ub.upper)
        fast, ref = cm.signed_distances(x), cm.signed_distances_numpy(x)
        np.testing.assert_allclose(fast, ref, atol=1e-10)
        assert cm.min_signed_distance(x) == pytest.approx(ref.min(), abs=1e-10)
        assert cm.is_free(x) == bool(np.all(ref >= 0))
        negatives += int(np.sum(ref < 0))
    assert negatives > 0  # penetrating pairs were compared too


@pytest.mark.parametrize("robot", ["g1", "talos"])
def test_capsules_on_bodies_follow_the_mujoco_bodies_in_any_pose(robot, g1_capsules):
    """What the studio draws: each capsule placed on the MuJoCo body of its frame's name, composed with that
    body's simulated pose, is the capsule the checks use (pinocchio) — in random poses, not only the fitting one."""
    import mujoco

    from engine.retarget.humanoid_arm.capsules import fitted_capsules_on_bodies

    cm = g1_capsules if robot == "g1" else CapsuleModel(UpperBody(robot))
    placed = cm.on_bodies()
    assert [c.name for c in placed] == [c.name for c in fitted_capsules_on_bodies(robot)]  # the studio's fit
    ub = cm.ub
    mm = ub.model.mj_model
    data = mujoco.MjData(mm)
    rng = np.random.default_rng(11)
    for _ in range(10):
        x = rng.uniform(ub.lower, ub.upper)
        a, b = cm.segments(x)
        data.qpos[:] = ub.model.mj_qpos_from_pin(ub.full_q(x))
        mujoco.mj_kinematics(mm, data)
        for i, c in enumerate(placed):
            bid = mm.body(c.body).id
            body_rot = data.xmat[bid].reshape(3, 3)
            rot = np.zeros(9)
            mujoco.mju_quat2Mat(rot, c.wxyz)
            centre = body_rot @ c.position + data.xpos[bid]
            axis = body_rot @ rot.reshape(3, 3)[:, 2]
            ends = np.array([centre - 0.5 * c.length * axis, centre + 0.5 * c.length * axis])
            np.testing.assert_allclose(ends, [a[i], b[i]], atol=1e-5)
            assert c.radius == cm.capsules[i].radius


def test_each_capsules_min_distance_is_its_closest_checked_pair(g1_capsules):
    cm = g1_capsules
    x = cm.ub.neutral()
    pairs = cm.signed_distances(x)
    per = cm.capsule_min_distances(pairs)
    for c in range(len(cm.capsules)):
        mine = [pairs[k] for k, (i, j) in enumerate(cm.pairs) if c in (i, j)]
        assert per[c] == (min(mine) if mine else np.inf)
    assert np.min(per) == np.min(pairs)
