"""The kinematic preview (the reference ghost, `studio plan`): its CoM plan keeps up with the path,
and its IK degrades toward the reference where the reference cannot be reached."""

from __future__ import annotations

import dataclasses
from functools import lru_cache

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.gait.kinematic_preview import KinematicPreview, SupportCenterComPlan
from engine.gait.offline_plan import planner_for
from engine.gait.planner import PLANNER_RATE_HZ
from engine.gait.style import StyleContext, load_style
from engine.robot.model import load_robot
from tests.conftest import REPO

DT = 1.0 / PLANNER_RATE_HZ


def _walk(robot_name: str, command: tuple[float, float, float], duration_s: float):
    """(planner references, CoM plan) walking ``command`` from standing for ``duration_s``."""
    robot = load_robot(robot_name)
    ctx = StyleContext.for_robot(robot_name)
    style = load_style(REPO / "styles" / robot_name / "neutral.json", ctx)
    planner = planner_for(robot, style, ctx)
    plan = SupportCenterComPlan()
    refs, coms = [], []
    for _ in range(int(round(duration_s / DT))):
        ref = planner.step(DT, np.array(command), with_preview=False)
        refs.append(ref)
        coms.append(plan.step(DT, ref))
    return robot, ctx, refs, np.array(coms)


def test_the_com_plan_keeps_up_with_the_path():
    # A follower without the path's velocity fed forward trails it by 2τv (11 cm at dino's 0.45 m/s):
    # the pelvis then stays behind and the front foot leaves the leg's reach.
    _, _, refs, coms = _walk("dino", (0.45, 0.0, 0.0), 6.0)
    path = np.array([r.path_pose[:2] for r in refs])
    late = slice(len(refs) // 2, None)  # steady walking, several cycles
    lag = np.mean(coms[late, 0] - path[late, 0])
    assert abs(lag) < 0.02, lag
    assert np.abs(coms[late, 1] - path[late, 1]).max() < 0.1  # sways toward the stance foot, no drift


@lru_cache(maxsize=None)
def _solved_walk():
    robot, ctx, refs, coms = _walk("g1", (0.3, 0.0, 0.0), 4.0)
    ik = KinematicPreview(robot, ctx.upper_joints)
    k = len(refs) - 1
    for i in range(k + 1):
        q = ik.solve(refs[i], coms[i])
    return robot, ctx, refs[k], coms[k], q


@settings(max_examples=25, deadline=None)
@given(offset=st.tuples(*[st.floats(-0.4, 0.4)] * 3), side=st.integers(0, 1))
def test_a_foot_out_of_reach_degrades_the_preview_never_diverges(offset, side):
    """Warm-started at the exact solution, the preview never ends farther from the moved reference
    than where it started (the moved foot's distance), whatever the target: no leaps, no divergence."""
    robot, ctx, ref, com, q_exact = _solved_walk()
    foot_pos = ref.foot_pos.copy()
    foot_pos[side] += np.array(offset)
    moved = dataclasses.replace(ref, foot_pos=foot_pos)
    ik = KinematicPreview(robot, ctx.upper_joints)
    q = ik.solve(moved, com, q_init=q_exact)
    assert np.isfinite(q).all()
    assert ik.last_error <= np.linalg.norm(offset) + 1e-6  # (the exact solution is met to ~1e-8)
    model = robot.pin_model
    assert (q[7:] >= model.lowerPositionLimit[7:] - 1e-12).all() and (q[7:] <= model.upperPositionLimit[7:] + 1e-12).all()


def test_the_com_gives_way_so_the_feet_reach():
    """A CoM plan 0.4 m behind the feet, ~8 cm farther than G1's legs reach: the CoM leaves its plan
    and the feet stay (within a few mm: the CoM's weight is small, not zero) where the reference puts them."""
    robot, ctx, ref, com, q_exact = _solved_walk()
    ik = KinematicPreview(robot, ctx.upper_joints)
    ik.solve(ref, com - np.array([0.4, 0.0]), q_init=q_exact)
    assert ik.last_error < 3e-3
    assert ik.last_com_error > 0.05
