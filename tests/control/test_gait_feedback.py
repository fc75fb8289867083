"""Gait feedback (§7.1): directions, limits, the 0.15 Hz low-pass, time-scaling bounds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from engine.control.gait_feedback import GaitFeedback, GaitFeedbackGains

DT = 0.008


def run(fb: GaitFeedback, error_xy, vel_error_xy=(0.0, 0.0), yaw=0.0, single=True, steps=1):
    out = None
    for _ in range(steps):
        out = fb.update(DT, np.array(error_xy), np.array(vel_error_xy), np.zeros(2), np.zeros(2), 0.6, yaw,
                        np.array([0.0, 0.1]), np.array([0.3, -0.1]), single)
    return out


def test_no_error_no_feedback():
    out = run(GaitFeedback(), (0.0, 0.0))
    assert out.kappa == 1.0 and not out.velocity_adjust_mps.any() and not out.step_adjust_m.any()


def test_lagging_com_slows_the_gait_and_steps_back():
    out = run(GaitFeedback(), (-0.05, 0.0), (-0.1, 0.0))
    assert out.kappa < 1.0  # the reference waits for the CoM
    assert out.step_adjust_m[0] < 0.0  # next foothold toward the error
    out = run(GaitFeedback(), (0.05, 0.0), (0.1, 0.0))
    assert out.kappa > 1.0 and out.step_adjust_m[0] > 0.0


def test_velocity_adjustment_is_a_slow_low_pass_in_the_path_frame():
    fb = GaitFeedback()
    first = run(fb, (0.2, 0.0))
    assert 0 < first.velocity_adjust_mps[0] < 0.02  # 0.15 Hz: one tick moves it very little
    later = run(fb, (0.2, 0.0), steps=int(3.0 / DT))
    assert later.velocity_adjust_mps[0] > 5 * first.velocity_adjust_mps[0]
    rotated = run(GaitFeedback(), (0.2, 0.0), yaw=math.pi / 2, steps=200)
    assert rotated.velocity_adjust_mps[1] < 0 and abs(rotated.velocity_adjust_mps[0]) < 1e-9  # world +x is path −y


def test_deadband_and_limits():
    g = GaitFeedbackGains()
    small = run(GaitFeedback(g), (0.001, 0.0), steps=500)
    assert not small.velocity_adjust_mps.any() and not small.step_adjust_m.any()
    huge = run(GaitFeedback(g), (5.0, 5.0), (5.0, 5.0), steps=int(20 / DT))
    assert np.linalg.norm(huge.step_adjust_m) <= g.step_max_m + 1e-12
    assert np.linalg.norm(huge.velocity_adjust_mps) <= g.velocity_max_mps + 1e-12
    assert huge.kappa == pytest.approx(g.kappa_single[1])
    assert run(GaitFeedback(g), (-5.0, 0.0), single=False).kappa == pytest.approx(g.kappa_double[0])


def test_garbage_is_ignored():
    out = run(GaitFeedback(), (float("nan"), 0.0))
    assert out.kappa == 1.0 and np.all(np.isfinite(out.step_adjust_m))


def test_disabled_feedback_is_neutral():
    out = run(GaitFeedback(enabled=False), (0.3, 0.3), (1.0, 1.0))
    assert out.kappa == 1.0 and not out.step_adjust_m.any()
