"""The TMR score (Eq. 15 + our fall penalty): a fall always scores below the same motion standing, and among
falls, the later one scores higher (BO climbs towards the α that gets furthest)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.retarget.quadruped.tmr.scoring import tmr_score


def _motion(seed: int, T: int = 20):  # noqa: ANN202
    rng = np.random.default_rng(seed)
    q = np.zeros((T, 19))
    q[:, :3] = rng.normal(0, 0.05, (T, 3))
    q[:, 3] = 1.0
    return q, rng.random((T, 4)) > 0.3


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 1000), a=st.floats(0.0, 1.0), b=st.floats(0.0, 1.0), log2=st.floats(-1, 1))
def test_falls_score_below_standing_and_later_falls_score_higher(seed, a, b, log2) -> None:  # noqa: ANN001
    q, c = _motion(seed)
    q_ref, c_ref = _motion(seed + 1)
    alpha = np.array([log2])
    up = tmr_score(q, c, q_ref, c_ref, alpha, False)["score"]
    early, late = sorted((a, b))
    s_early = tmr_score(q, c, q_ref, c_ref, alpha, True, fall_fraction=early)["score"]
    s_late = tmr_score(q, c, q_ref, c_ref, alpha, True, fall_fraction=late)["score"]
    assert s_early <= s_late < up
    assert up - s_late >= 1.0  # at least the whole fall penalty


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 1000), err=st.floats(0.001, 0.05), more=st.floats(0.001, 0.05))
def test_keypoint_term_ranks_closer_rollouts_higher(seed, err, more) -> None:  # noqa: ANN001
    """With w_keypoints > 0 the score prefers, all else equal, the rollout whose keypoints are closer to the
    target (what the DTW figure measures); with w_keypoints = 0 it is Eq. 15's base-only score."""
    q, c = _motion(seed)
    rng = np.random.default_rng(seed)
    kp_ref = rng.normal(0, 0.3, (len(q), 16, 3))
    direction = rng.normal(0, 1, (len(q), 16, 3))
    direction /= np.abs(direction).sum(axis=-1, keepdims=True)  # unit L1 per keypoint
    near, far = kp_ref + err * direction, kp_ref + (err + more) * direction
    alpha = np.zeros(1)
    s_near = tmr_score(q, c, q, c, alpha, False, keypoints=near, keypoints_ref=kp_ref, w_keypoints=1.0)
    s_far = tmr_score(q, c, q, c, alpha, False, keypoints=far, keypoints_ref=kp_ref, w_keypoints=1.0)
    assert s_near["d_k_m"] == pytest.approx(err) and s_far["d_k_m"] == pytest.approx(err + more)
    assert s_far["score"] == pytest.approx(s_near["score"] - more)
    base_only = tmr_score(q, c, q, c, alpha, False, keypoints=far, keypoints_ref=kp_ref, w_keypoints=0.0)
    assert base_only["score"] == pytest.approx(tmr_score(q, c, q, c, alpha, False)["score"])
