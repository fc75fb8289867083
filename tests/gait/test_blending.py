"""Phase-space blending (§5.1–5.2): contact timing survives any convex blend of samples."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.gait.blending import MIN_MEMBER_WEIGHT, BlendedGait, ChannelLayout, SampleBanks
from engine.gait.phase_map import PHI_LTD, PHI_RLO, PHI_RTD, equivalent_time
from tests.gait.strategies import g1_context, gait_samples

SETTINGS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def layout() -> ChannelLayout:
    ctx = g1_context()
    return ChannelLayout(ctx.upper_joints, np.array([ctx.standing_angles[j] for j in ctx.upper_joints]))


@SETTINGS
@given(st.lists(gait_samples(), min_size=1, max_size=4), st.data())
def test_blend_keeps_event_order_and_minimum_durations(samples, data):
    ctx = g1_context()
    raw = np.array(data.draw(st.lists(st.floats(0.01, 1.0), min_size=len(samples), max_size=len(samples))))
    lay = layout()
    blend = BlendedGait([(w, SampleBanks(s, lay)) for w, s in zip(raw / raw.sum(), samples)])
    t_ltd, t_rlo, t_rtd, cycle = blend.events_s
    assert 0 < t_ltd < t_rlo < t_rtd < cycle
    assert t_ltd >= ctx.min_single_support_s - 1e-9 and t_rtd - t_rlo >= ctx.min_single_support_s - 1e-9
    assert t_rlo - t_ltd >= ctx.min_double_support_s - 1e-9 and cycle - t_rtd >= ctx.min_double_support_s - 1e-9
    # The blended phase map maps events to events (contact timing kept by blending).
    for phi, t in ((PHI_LTD, t_ltd), (PHI_RLO, t_rlo), (PHI_RTD, t_rtd)):
        assert blend.time_at(phi) == pytest.approx(t, abs=1e-12)
        assert blend.phase_of_time(t) == pytest.approx(phi, abs=1e-9)
    phis = np.linspace(0, 1, 400)
    assert np.all(np.diff([blend.time_at(p) for p in phis]) > 0)


@SETTINGS
@given(gait_samples(), gait_samples(), st.floats(0.0, 1.0), st.floats(0.0, 0.999))
def test_two_sample_blend_is_the_papers_six_steps(a, b, alpha, phi):
    """value(t) = (1−α) f_A(Ω_A(Ω_AB⁻¹(t))) + α f_B(Ω_B(Ω_AB⁻¹(t))) for every curve channel."""
    lay = layout()
    # BlendedGait drops members of weight ≤ MIN_MEMBER_WEIGHT (and renormalises): such a blend is the other sample alone
    # (hypothesis found α = 1e-9: the blend gave f_A where the formula with α = 1e-9 differs by 1.25e-9)
    alpha_used = 0.0 if alpha <= MIN_MEMBER_WEIGHT else (1.0 if 1.0 - alpha <= MIN_MEMBER_WEIGHT else alpha)
    ba, bb = SampleBanks(a, lay), SampleBanks(b, lay)
    blend = BlendedGait([(1 - alpha, ba), (alpha, bb)]) if 0 < alpha < 1 else BlendedGait([(1.0, ba if alpha == 0 else bb)])
    t = blend.time_at(phi)
    phase = blend.phase_map.phase_at(t)  # step (1)
    t_a, t_b = ba.phase_map.time_at(phase), bb.phase_map.time_at(phase)  # (2), (3)
    for channel, idx in (("pelvis.yaw", 1), ("joints.left_shoulder_pitch_joint", 4 + list(g1_context().upper_joints).index("left_shoulder_pitch_joint"))):
        fa = a.curves.get(channel)
        fb = b.curves.get(channel)
        default = lay.cycle_defaults[idx]
        va = fa.evaluate(t_a) if fa else default  # (4)
        vb = fb.evaluate(t_b) if fb else default  # (5)
        cycle, *_ = blend.channels(phi)
        assert cycle[idx] == pytest.approx((1 - alpha_used) * va + alpha_used * vb, abs=1e-9)  # (6)
    assert equivalent_time(t_a, ba.phase_map, bb.phase_map) == pytest.approx(t_b, abs=1e-9)


@SETTINGS
@given(gait_samples(), st.floats(0.0, 0.999))
def test_blend_of_one_sample_is_the_sample(sample, phi):
    lay = layout()
    blend = BlendedGait([(1.0, SampleBanks(sample, lay))])
    t = blend.time_at(phi)
    cycle, left, right, *_ = blend.channels(phi)
    z = sample.curves["left_foot.z"]
    if phi < PHI_LTD:
        assert left[2] == pytest.approx(z.evaluate(t), abs=1e-12)
