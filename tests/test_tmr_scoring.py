"""The TMR score (Eq. 15 + our fall shaping): a fall always scores below a standing replay, among falls with the
same pre-fall tracking the later one scores higher, a fall much later scores higher whatever the tracking, and
what the robot does after it fell does not count (BO climbs towards the α that gets furthest)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.retarget.quadruped.tmr.scoring import (
    FALL_PENALTY,
    FALL_PENALTY_PER_SHARE_LEFT,
    FALLEN_TRACKING_BOUND,
    tmr_score,
)


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
    assert s_late < up
    if up > FALLEN_TRACKING_BOUND - FALL_PENALTY:  # any standing replay that is not metres off
        assert up - s_late > 0.0
    if late - early > 2 * FALLEN_TRACKING_BOUND / FALL_PENALTY_PER_SHARE_LEFT:
        assert s_early < s_late  # a fall much later wins whatever the tracking before it


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 1000), a=st.floats(0.0, 1.0), b=st.floats(0.0, 1.0), log2=st.floats(-1, 1),
       err=st.floats(0.0, 0.3))
def test_of_two_falls_with_the_same_tracking_the_later_scores_higher(seed, a, b, log2, err) -> None:  # noqa: ANN001
    """A replay that follows its target with a constant offset until it falls: the later fall scores higher (the
    pre-fall terms are the same, the penalty shrinks with the share left), strictly, for any positive gap."""
    q_ref, c = _motion(seed)
    q = q_ref.copy()
    q[:, 0] += err
    early, late = sorted((a, b))
    alpha = np.array([log2])
    s_early = tmr_score(q, c, q_ref, c, alpha, True, fall_fraction=early)
    s_late = tmr_score(q, c, q_ref, c, alpha, True, fall_fraction=late)
    assert s_early["d_b_m"] == pytest.approx(err) and s_late["d_b_m"] == pytest.approx(err)
    if late - early > 1e-9:
        assert s_early["score"] < s_late["score"]
    assert s_early["fall_penalty"] == pytest.approx(FALL_PENALTY + FALL_PENALTY_PER_SHARE_LEFT * (1 - early))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 1000), fall=st.floats(0.1, 0.9), junk=st.floats(0.1, 5.0))
def test_what_happens_after_the_fall_does_not_count(seed, fall, junk) -> None:  # noqa: ANN001
    """The rollout after its fall (lying on the floor, sliding away) changes nothing: only the frames before count."""
    q_ref, c = _motion(seed)
    q = q_ref.copy()
    q_far = q_ref.copy()
    k = int(round(fall * (len(q) - 1))) + 1
    q_far[k:, 0:3] += junk
    alpha = np.zeros(1)
    s = tmr_score(q, c, q_ref, c, alpha, True, fall_fraction=fall)
    s_far = tmr_score(q_far, c, q_ref, c, alpha, True, fall_fraction=fall)
    assert s_far["score"] == pytest.approx(s["score"])
    assert tmr_score(q, c, q_ref, c, alpha, False)["score"] > s["score"]


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
