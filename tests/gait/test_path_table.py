"""The planner's path table (vectorised) equals the piecewise-arc loop it replaced."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.gait.path_frame import PathFrame, predict
from engine.gait.planner import PATH_TABLE_HORIZON_S, PATH_TABLE_STEP_S, GaitPlanner


def loop_table(pose: np.ndarray, command: np.ndarray, goal: np.ndarray, limits: np.ndarray):
    """The implementation before the speed-up (one numpy arc per 50 ms piece)."""
    limits = np.abs(np.asarray(limits, dtype=float))
    n = int(math.ceil(PATH_TABLE_HORIZON_S / PATH_TABLE_STEP_S)) + 1
    times = np.arange(n) * PATH_TABLE_STEP_S
    poses, vels = np.empty((n, 3)), np.empty((n, 3))
    v, h = command.copy(), PATH_TABLE_STEP_S
    for i in range(n):
        dv = np.clip(goal - v, -limits * h, limits * h)
        poses[i], vels[i] = pose, v + 0.5 * dv
        pose = predict(pose, vels[i], h)
        v = v + dv
    return times, poses, vels


class _Stub:
    """Just the planner state the table reads."""

    _build_path_table = GaitPlanner._build_path_table

    def __init__(self, pose, command, goal, limits):
        self.path = PathFrame(*pose)
        self.command, self.command_goal, self.command_rate_limits = command, goal, limits
        self.command_clamped = False

    def clamp_command(self, c):  # noqa: ANN001, ANN201
        return np.asarray(c, dtype=float)


vel = st.floats(-1.0, 1.0)


@settings(max_examples=60, deadline=None)
@given(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-4, 4)), st.tuples(vel, vel, vel),
       st.tuples(vel, vel, vel), st.sampled_from([(0.25, 0.3, 1.5), (1.0, 1.0, 1.0), (0.05, 0.05, 0.1)]))
def test_table_matches_the_loop(pose, command, goal, limits) -> None:
    pose, command, goal, limits = (np.array(x, dtype=float) for x in (pose, command, goal, limits))
    times, poses, vels = _Stub(pose, command, goal, limits)._build_path_table()
    t_ref, p_ref, v_ref = loop_table(pose, command, goal, limits)
    np.testing.assert_array_equal(times, t_ref)
    np.testing.assert_array_equal(vels, v_ref)
    np.testing.assert_allclose(poses, p_ref, rtol=0, atol=1e-12)
