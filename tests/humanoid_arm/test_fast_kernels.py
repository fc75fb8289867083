"""The vectorised kernels of LWL2 and the IK baseline compute the numbers of the straightforward code they
replaced (kept here, verbatim in substance, as the references): the Gauss–Newton residual and Jacobian (one
pinocchio call per key point before), the IK solve built on it, the capsule fixer (one point Jacobian and one
segment test per colliding pair before) and the joint-limit clip."""

from __future__ import annotations

import numpy as np
import pytest

from engine.retarget.humanoid_arm.capsules import CapsuleModel, segment_distance
from engine.retarget.humanoid_arm.ik import NECK_WEIGHT, ArmIK, arm_targets
from engine.retarget.humanoid_arm.upper_body import UpperBody


@pytest.fixture(scope="module", params=["g1", "talos"])
def robot(request):
    ub = UpperBody(request.param)
    return ub, CapsuleModel(ub)


def random_pose15(rng: np.random.Generator) -> np.ndarray:
    v = rng.standard_normal((5, 3))
    return (v / np.linalg.norm(v, axis=1, keepdims=True)).ravel()


def reference_residual(ik: ArmIK, x: np.ndarray, pose15: np.ndarray, with_jacobian: bool):
    """The per-frame-Jacobian residual (getFrameJacobian per key point)."""
    ub = ik.ub
    ub.jacobians(x) if with_jacobian else ub.forward(x)
    d = ub.data
    pos = lambda f: d.oMf[f].translation  # noqa: E731
    jac = ub.frame_origin_jacobian
    v = pose15.reshape(5, 3)
    sh = np.stack([pos(f) for f in ik._f["shoulder"]])
    elbow_t, hand_t = arm_targets(ub, pose15, sh)
    res = [NECK_WEIGHT * (sh.mean(axis=0) - pos(ik._f["pelvis"]) - ub.lengths_m["torso"] * v[0])]
    for k in range(2):
        res.append(pos(ik._f["elbow"][k]) - elbow_t[k])
        res.append(pos(ik._f["hand"][k]) - hand_t[k])
    r = np.concatenate(res)
    if not with_jacobian:
        return r, None
    js = [jac(f) for f in ik._f["shoulder"]]
    rows = [NECK_WEIGHT * (0.5 * (js[0] + js[1]) - jac(ik._f["pelvis"]))]
    for k in range(2):
        rows.append(jac(ik._f["elbow"][k]) - js[k])
        rows.append(jac(ik._f["hand"][k]) - js[k])
    return r, np.vstack(rows)


def reference_solve(ik: ArmIK, pose15: np.ndarray, x0: np.ndarray, iters: int = 30) -> np.ndarray:
    ub = ik.ub
    x = np.clip(x0, ub.lower, ub.upper)
    for _ in range(iters):
        r, jm = reference_residual(ik, x, pose15, True)
        h = jm.T @ jm + (ik.damping + ik.reg) * np.eye(ub.n)
        dx = -np.linalg.solve(h, jm.T @ r + ik.reg * (x - ub.neutral()))
        x = np.clip(x + dx, ub.lower, ub.upper)
        if np.max(np.abs(dx)) < 1e-4:
            break
    return x


def reference_fix(cm: CapsuleModel, x: np.ndarray, margin_m: float = 0.002, max_iters: int = 60,
                  damping: float = 1e-3, clearance_m: float = 0.0) -> tuple[np.ndarray, bool]:
    """The fixer with one segment test and two point Jacobians (getFrameJacobian) per colliding pair."""
    ub = cm.ub
    x = np.clip(np.asarray(x, dtype=float), ub.lower, ub.upper)
    if cm.is_free(x, clearance_m):
        return x, True
    target = clearance_m + margin_m
    pen = cm.penetration(x, clearance_m)
    for _ in range(max_iters):
        d_all = cm.signed_distances(x)
        if np.all(d_all >= clearance_m) and pen == 0.0:
            return x, True
        a, b = cm.segments(x, forward=False)
        ub.jacobians(x)
        rows, rhs = [], []
        for k in np.nonzero(d_all < target)[0]:
            i, j = cm.pairs[k]
            _, c1, c2 = segment_distance(a[i], b[i], a[j], b[j])
            n = c1 - c2
            norm = np.linalg.norm(n)
            if norm < 1e-9:
                n = 0.5 * (a[i] + b[i] - a[j] - b[j])
                norm = np.linalg.norm(n) + 1e-12
            n = n / norm
            rows.append(n @ (ub.point_jacobian(cm.capsules[i].frame_id, c1) - ub.point_jacobian(cm.capsules[j].frame_id, c2)))
            rhs.append(target - d_all[k])
        jac = np.array(rows)
        dx = jac.T @ np.linalg.solve(jac @ jac.T + damping * np.eye(len(rows)), np.array(rhs))
        step, accepted = 1.0, False
        while step > 1e-3:
            x_new = np.clip(x + step * dx, ub.lower, ub.upper)
            pen_new = cm.penetration(x_new, clearance_m)
            if pen_new <= pen:
                x, pen, accepted = x_new, pen_new, True
                break
            step *= 0.5
        if not accepted:
            break
    return x, bool(cm.is_free(x, clearance_m))


def test_residual_and_jacobian_equal_the_per_frame_reference(robot):
    ub, cm = robot
    ik = ArmIK(ub, cm)
    rng = np.random.default_rng(0)
    for _ in range(40):
        x, p = rng.uniform(ub.lower, ub.upper), random_pose15(rng)
        r_ref, j_ref = reference_residual(ik, x, p, True)
        r, j = ik.residual(x, p, True)
        np.testing.assert_allclose(r, r_ref, atol=1e-12)
        np.testing.assert_allclose(j, j_ref, atol=1e-12)
        r0, none = ik.residual(x, p, False)
        assert none is None
        np.testing.assert_allclose(r0, r_ref, atol=1e-12)


def test_ik_solve_equals_the_reference_solve(robot):
    ub, cm = robot
    ik = ArmIK(ub, cm)
    rng = np.random.default_rng(1)
    for _ in range(8):
        x0, p = rng.uniform(ub.lower, ub.upper), random_pose15(rng)
        x, _ = ik.solve(p, x0, fix=False)
        np.testing.assert_allclose(x, reference_solve(ik, p, x0), atol=1e-9)


def test_fixer_equals_the_per_pair_reference(robot):
    ub, cm = robot
    rng = np.random.default_rng(2)
    for clearance in (0.0, 0.01):
        colliding = 0
        for _ in range(200):
            x = rng.uniform(ub.lower, ub.upper)
            if cm.is_free(x, clearance):  # the early exit is the same line in both
                continue
            colliding += 1
            fixed, ok = cm.fix(x, clearance_m=clearance)
            ref, ok_ref = reference_fix(cm, x, clearance_m=clearance)
            assert ok == ok_ref
            np.testing.assert_allclose(fixed, ref, atol=1e-9)
            if colliding == 8:
                break
        assert colliding == 8


def test_clip_equals_numpy_clip(robot):
    ub, _ = robot
    rng = np.random.default_rng(3)
    x = rng.uniform(-4, 4, (50, ub.n))
    np.testing.assert_array_equal(ub.clip(x), np.clip(x, ub.lower, ub.upper))


def test_row_cross_equals_numpy_cross():
    from engine.retarget.humanoid_arm.capsules import _cross

    rng = np.random.default_rng(4)
    u, v = rng.standard_normal((2, 20, 3))
    np.testing.assert_allclose(_cross(u, v), np.cross(u, v), atol=1e-15)


def test_pose15_check_fast_path_accepts_and_rejects_like_the_full_check():
    from engine.retarget.humanoid_arm.pose15 import check_pose15

    rng = np.random.default_rng(5)
    for scale in (1.0, 1.04, 0.96, 1.06, 0.94):
        v = random_pose15(rng) * scale
        full_ok = bool(np.all(np.abs(np.linalg.norm(v.reshape(5, 3), axis=1) - 1.0) <= 0.05))
        if full_ok:
            assert check_pose15(v) is not None
        else:
            with pytest.raises(ValueError):
                check_pose15(v)
    for bad in (np.nan, np.inf):
        v = random_pose15(rng)
        v[4] = bad
        with pytest.raises(ValueError, match="finite"):
            check_pose15(v)


def test_lwr_blend_and_reused_neighbours_equal_the_query():
    """LWL2's refinement starts from ``blend(neighbours, k_max)``; ``query(z, neighbours)`` (the fallback) must
    answer as ``query(z)`` and a feasible k_max blend must be the query's pose."""
    from engine.retarget.humanoid_arm.lwr import LatentLWR

    rng = np.random.default_rng(6)
    latents, poses = rng.standard_normal((200, 4)), rng.uniform(-1, 1, (200, 5))
    for feasible in (lambda x: True, lambda x: False, lambda x: x[0] > 0):
        lwr = LatentLWR(latents, poses, feasible, k_max=3)
        for _ in range(20):
            z = rng.standard_normal(4)
            nb = lwr.neighbours(z)
            a, b = lwr.query(z), lwr.query(z, nb)
            assert a.k == b.k and np.array_equal(a.x, b.x)
            if a.k == 3:
                np.testing.assert_array_equal(lwr.blend(*nb, 3), a.x)
            np.testing.assert_array_equal(lwr.blend(*nb, 1), poses[nb[1][0]])


def test_interpolation_check_with_a_known_free_end_equals_the_full_check(robot):
    ub, cm = robot
    rng = np.random.default_rng(7)
    agree = 0
    for _ in range(40):
        x0, x1 = rng.uniform(ub.lower, ub.upper, (2, ub.n))
        x1 = x0 + 0.3 * (x1 - x0)
        if not (cm.is_free(x0) and cm.is_free(x1)):
            continue
        assert cm.interpolation_free(x0, x1, end_free=True) == cm.interpolation_free(x0, x1)
        agree += 1
    assert agree >= 5


def test_coal_nearest_points_give_the_segment_tests_closest_points(robot):
    """The fixer reads the capsule axes' closest points from coal (p1 = c1 + r1·normal, p2 = c2 − r2·normal)."""
    ub, cm = robot
    rng = np.random.default_rng(8)
    compared = 0
    for _ in range(40):
        x = rng.uniform(ub.lower, ub.upper)
        d = cm.signed_distances(x)
        a, b = cm.segments(x, forward=False)
        for k in np.nonzero(d < 0.01)[0]:
            i, j = cm.pairs[k]
            _, c1, c2 = segment_distance(a[i], b[i], a[j], b[j])
            r = cm._geom_data.distanceResults[int(k)]
            normal = np.array(r.normal)
            np.testing.assert_allclose(np.array(r.getNearestPoint1()) - cm._r[i] * normal, c1, atol=1e-10)
            np.testing.assert_allclose(np.array(r.getNearestPoint2()) + cm._r[j] * normal, c2, atol=1e-10)
            compared += 1
    assert compared >= 10


def test_distances_read_through_held_results_follow_every_new_pose(robot):
    """The capsule model reads coal's answers through references taken once: they must be the fresh values."""
    ub, cm = robot
    rng = np.random.default_rng(9)
    for _ in range(10):
        x = rng.uniform(ub.lower, ub.upper)
        d = cm.signed_distances(x)
        fresh = np.array([r.min_distance for r in cm._geom_data.distanceResults])
        np.testing.assert_array_equal(d, fresh)
        assert cm.min_signed_distance(x) == fresh.min()



def test_compiled_encoder_equals_the_numpy_and_torch_forward():
    """LWL2's run-time encoder (normalisation folded into the first layer, one numba call per sample) answers
    as the numpy forward of the same weights (to rounding) and the torch network (to float32 rounding)."""
    from engine.retarget.humanoid_arm.wae import SharedLatentWAE

    rng = np.random.default_rng(11)
    model = SharedLatentWAE({"mocap": 15, "robot": 11}, latent_dim=8, hidden=32, seed=3)
    model.set_normalisation("mocap", rng.normal(0.3, 0.5, (500, 15)))
    enc = model.numpy_encoder("mocap")
    mean, std = model.normalisation_of("mocap")
    xs = rng.normal(0.3, 0.7, (50, 15))
    for x in xs:
        one = enc(x)
        assert one.shape == (1, 8)
        np.testing.assert_allclose(one[0], enc.net(((x - mean) / std)[None, :])[0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(enc(x[None, :]), one, rtol=0, atol=0)
    batch = enc(xs)
    np.testing.assert_allclose(batch, np.vstack([enc(x) for x in xs]), rtol=0, atol=1e-12)
    np.testing.assert_allclose(batch, model.encode("mocap", xs), rtol=0, atol=1e-4)


@pytest.mark.parametrize("n, dims, scale", [(1, 4, 1.0), (7, 3, 1.0), (300, 8, 1.0), (5000, 8, 0.01), (2000, 8, 50.0)])
def test_lwr_scan_finds_the_k_d_trees_neighbours(n, dims, scale):
    """The compiled k-NN scan (float32 prefilter, float64 re-rank) returns the exact float64 neighbours and
    distances of scipy's k-d tree, for queries near and far from the table."""
    from engine.retarget.humanoid_arm.lwr import LatentLWR

    rng = np.random.default_rng(n)
    latents = scale * rng.standard_normal((n, dims))
    lwr = LatentLWR(latents, rng.uniform(-1, 1, (n, 2)), lambda x: True, k_max=3)
    for far in (0.0, 1.0, 10.0):
        for _ in range(30):
            z = scale * (rng.standard_normal(dims) + far)
            dist, idx = lwr.neighbours(z)
            ref_d, ref_i = lwr.neighbours_kdtree(z)
            k = min(3, n)
            assert len(dist) == len(idx) == k
            np.testing.assert_allclose(dist, ref_d[:k], rtol=1e-12, atol=0)
            np.testing.assert_array_equal(idx, ref_i[:k])
            np.testing.assert_allclose(dist, np.linalg.norm(latents[idx] - z, axis=1), rtol=1e-12)


def test_lwr_scan_on_the_shipped_table_equals_the_k_d_tree():
    """On G1's shipped LWR table with held-out mocap codes (where the k-d tree prunes poorly)."""
    from engine.retarget.humanoid_arm import sources
    from engine.retarget.humanoid_arm.metadata import weights_path
    from engine.retarget.humanoid_arm.pose15 import bvh_points
    from engine.retarget.humanoid_arm.puppeteer import ArmRetargeter
    from engine.retarget.importers.bvh import load_bvh

    clips = sources.evaluation_clips()
    if not clips or not weights_path("g1").with_suffix(".json").is_file():
        pytest.skip("shared mocap clips or shipped g1 weights absent")
    arms = ArmRetargeter.load("g1", refine_iters=0)
    for p in bvh_points(load_bvh(clips[0])).pose15()[::6]:
        z = arms.encode_mocap(p)[0]
        dist, idx = arms.lwr.neighbours(z)
        ref_d, ref_i = arms.lwr.neighbours_kdtree(z)
        np.testing.assert_array_equal(idx, ref_i)
        np.testing.assert_allclose(dist, ref_d, rtol=1e-12, atol=0)


def reference_la_dpp_indices(features: np.ndarray, m: int, rng: np.random.Generator, beta: float = 100.0,
                             chunk: int = 10_000) -> np.ndarray:
    """LA-DPP's greedy selection as it was written in numpy before the compiled loop."""
    n = len(features)
    if m >= n:
        return rng.permutation(n)
    pool = rng.choice(n, size=chunk, replace=False) if n > chunk else np.arange(n)
    x = np.asarray(features[pool], dtype=np.float64)
    sq = np.einsum("ij,ij->i", x, x)
    score = rng.uniform(0.0, 1e-12, size=len(pool))
    chosen = np.empty(m, dtype=np.int64)
    j = int(rng.integers(len(pool)))
    for k in range(m):
        chosen[k] = j
        d2 = np.maximum(sq + sq[j] - 2.0 * (x @ x[j]), 0.0)
        score += np.exp(-beta * d2)
        score[j] = np.inf
        if k + 1 < m:
            j = int(np.argmin(score))
    return pool[chosen]


def _g1_hand_elbow_features() -> np.ndarray:
    """LA-DPP's robot-domain features (hands and elbows in the pelvis frame) of G1 poses: the shipped LWR table's
    (the training set's robot domain) when present, else random poses within the limits."""
    from engine.retarget.humanoid_arm.metadata import weights_path
    from engine.retarget.humanoid_arm.training import robot_features

    ub = UpperBody("g1")
    path = weights_path("g1").with_suffix(".safetensors")
    if path.is_file():
        from safetensors.numpy import load_file

        poses = load_file(str(path))["data.robot_poses"][::7]
    else:
        rng = np.random.default_rng(3)
        poses = rng.uniform(ub.lower, ub.upper, size=(3000, ub.n))
    return robot_features(ub, poses)


def test_compiled_la_dpp_picks_the_numpy_loops_indices():
    """Same indices and the same random draws as the numpy loop: on G1's hand/elbow features (training's robot
    batches and the graph's nodes), normalised float32 mocap-like poses (most exps underflow to 0), points spaced so
    that β d² falls around 708–746 (subnormal exps), well-separated triplicates (d² = 0 within, the picks left to
    the jitter), and m ≥ n. (Where scores agree to ~1e-16 — partly covered duplicates — the last-bit differences
    of the dot products may pick another of equals.)"""
    from engine.retarget.humanoid_arm.la_dpp import la_dpp_indices

    rng = np.random.default_rng(11)
    robot = _g1_hand_elbow_features()
    mocap = rng.standard_normal((3000, 15)).astype(np.float32)
    subnormal = rng.standard_normal((1500, 15)) * rng.uniform(0.45, 0.52, size=(1500, 1))
    duplicates = np.repeat(rng.standard_normal((300, 4)), 3, axis=0)
    cases = [(robot, 128, 1024, 30), (robot, 128, 2048, 10), (robot, 600, 10_000, 1), (mocap, 128, 2048, 20),
             (subnormal, 128, 1024, 20), (duplicates, 250, 10_000, 5), (duplicates, 64, 512, 10),
             (duplicates, 900, 900, 1)]
    seen_subnormal = False
    for features, m, chunk, calls in cases:
        r_new, r_ref = np.random.default_rng(5), np.random.default_rng(5)
        for _ in range(calls):
            got = la_dpp_indices(features, m, r_new, chunk=chunk)
            want = reference_la_dpp_indices(features, m, r_ref, chunk=chunk)
            np.testing.assert_array_equal(got, want)
            assert r_new.bit_generator.state == r_ref.bit_generator.state
        if features is duplicates and m < 300:  # a picked point covers its copies: never two of one triplet
            assert len(set(got // 3)) == m
        if features is subnormal:
            x = subnormal[got[:20]]
            bd2 = 100.0 * ((x[:, None] - x[None]) ** 2).sum(-1)
            seen_subnormal = bool(np.any((bd2 > 708) & (bd2 < 746)))
    assert seen_subnormal  # the case does exercise the compiled call's own exp
    assert len(robot) > 1024 and len(set(la_dpp_indices(robot, 128, np.random.default_rng(0), chunk=1024))) == 128
