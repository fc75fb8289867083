"""Start settle: from a reset the reference's posture eases from the standing pose into the style's (issue 13)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.control.controller import RobotState
from engine.control.walking_controller import WalkingController
from engine.control.walking_parameters import WalkingParameters
from engine.gait.start_settle import StartPose, StartSettle
from engine.gait.style import StyleContext, load_style, styles_dir
from engine.geometry.rotation import log_so3, roll_pitch_of, rot_zyx, yaw_of
from engine.robot.model import load_robot

angles = st.floats(-0.4, 0.4)
heights = st.floats(0.4, 1.1)


def _pose(z: float, roll: float, pitch: float, upper: list[float]) -> StartPose:
    return StartPose(z, roll, pitch, np.array(upper))


def _style(settle: StartSettle, t: float, yaw: float, z: float, rot: np.ndarray, upper: np.ndarray):  # noqa: ANN202
    return settle.apply(t, yaw, z, 0.0, rot, np.zeros(3), upper, np.zeros_like(upper))


@settings(max_examples=60, deadline=None)
@given(z0=heights, z=heights, r0=angles, p0=angles, r=angles, p=angles, y=st.floats(-3.0, 3.0),
       dur=st.floats(0.2, 2.0), q0=st.lists(st.floats(-1.5, 1.5), min_size=3, max_size=3),
       q=st.lists(st.floats(-1.5, 1.5), min_size=3, max_size=3))
def test_starts_at_the_pose_ends_at_the_style_and_its_rates_are_the_derivatives(z0, z, r0, p0, r, p, y, dur, q0, q):
    settle = StartSettle(dur)
    settle.reset(_pose(z0, r0, p0, q0))
    rot = rot_zyx(y + 0.1, p, r)  # the style's pelvis, its own yaw on the path's
    upper = np.array(q)
    # at the reset: the robot's own pose under the path's yaw, at rest
    z_s, z_rate, rot_s, w_s, q_s, qd_s = _style(settle, 0.0, y, z, rot, upper)
    assert math.isclose(z_s, z0, abs_tol=1e-12) and z_rate == 0.0
    np.testing.assert_allclose(rot_s, rot_zyx(y, p0, r0), atol=1e-9)
    np.testing.assert_allclose(w_s, 0.0, atol=1e-12)
    np.testing.assert_allclose(q_s, q0, atol=1e-12)
    np.testing.assert_allclose(qd_s, 0.0, atol=1e-12)
    # settled: the style's own values, the same objects
    out = _style(settle, dur, y, z, rot, upper)
    assert out[0] == z and out[2] is rot and out[4] is upper
    # in between: the rates are the time derivatives of the values (central differences)
    h = 1e-6 * dur
    for t in np.linspace(0.05, 0.95, 7) * dur:
        a, b = _style(settle, t - h, y, z, rot, upper), _style(settle, t + h, y, z, rot, upper)
        mid = _style(settle, t, y, z, rot, upper)
        assert math.isclose(mid[1], (b[0] - a[0]) / (2 * h), rel_tol=1e-4, abs_tol=1e-6)
        np.testing.assert_allclose(mid[5], (b[4] - a[4]) / (2 * h), rtol=1e-4, atol=1e-6)
        w_fd = log_so3(b[2] @ a[2].T) / (2 * h)  # world angular velocity
        np.testing.assert_allclose(mid[3], w_fd, rtol=1e-3, atol=1e-5)


@settings(max_examples=40, deadline=None)
@given(z0=heights, z=heights, r0=angles, p0=angles, r=angles, p=angles, dur=st.floats(0.2, 2.0))
def test_the_posture_moves_monotonically_toward_the_style(z0, z, r0, p0, r, p, dur):
    settle = StartSettle(dur)
    settle.reset(_pose(z0, r0, p0, [0.3]))
    rot = rot_zyx(0.0, p, r)
    ts = np.linspace(0.0, dur, 41)
    z_gap = [abs(_style(settle, t, 0.0, z, rot, np.zeros(1))[0] - z) for t in ts]
    angle_gap = [np.linalg.norm(log_so3(_style(settle, t, 0.0, z, rot, np.zeros(1))[2].T @ rot)) for t in ts]
    assert all(b <= a + 1e-12 for a, b in zip(z_gap, z_gap[1:]))
    assert all(b <= a + 1e-9 for a, b in zip(angle_gap, angle_gap[1:]))
    assert z_gap[-1] == 0.0 and angle_gap[-1] < 1e-9


def test_off_without_a_duration_or_a_pose():
    rot, upper = rot_zyx(0.2, 0.1, -0.1), np.array([0.5])
    for settle in (StartSettle(0.0), StartSettle(1.0)):
        settle.reset(_pose(0.9, 0.0, 0.0, [0.0]) if not settle.enabled else None)
        out = _style(settle, 0.0, 0.2, 0.6, rot, upper)
        assert out[0] == 0.6 and out[2] is rot and out[4] is upper
        assert not settle.active(0.0)


def _first_reference(params: WalkingParameters):  # noqa: ANN202
    robot = load_robot("g1")
    ctx = StyleContext.for_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json", ctx)
    style = dataclasses.replace(style, samples={name: dataclasses.replace(
        s, attributes=dataclasses.replace(s.attributes, pelvis_height_m=0.62)) for name, s in style.samples.items()})
    ctrl = WalkingController(robot, style, params=params)
    q, v = robot.q_standing.copy(), np.zeros(robot.pin_model.nv)
    ctrl.reset(RobotState(0.0, q, v))
    ctrl.compute(RobotState(0.0, q, v))
    assert ctrl.ref is not None
    return robot, ctrl.ref


def test_the_controller_starts_from_the_standing_pose():
    """A style 14 cm below standing: with the settle the first reference stands where the robot stands; without it,
    at the style's height."""
    robot, settled = _first_reference(dataclasses.replace(WalkingParameters(), start_settle_s=1.0))
    _, jumped = _first_reference(WalkingParameters())
    assert abs(settled.pelvis_z - robot.q_standing[2]) < 1e-4
    assert abs(jumped.pelvis_z - 0.62) < 0.02
    roll, pitch = roll_pitch_of(settled.pelvis_rot)
    assert abs(roll) < 1e-4 and abs(pitch) < 1e-3 and abs(yaw_of(settled.pelvis_rot)) < 1e-3
