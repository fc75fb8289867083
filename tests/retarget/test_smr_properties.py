"""SMR's invariants (§V-A) under hypothesis: every contact foot stays within 0.1 mm of its anchor for the
whole contact segment, and no foot goes below the height map, for random contact schedules and robots."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from engine.retarget.contacts import segments
from engine.retarget.heightmap import Box, HeightMap
from engine.retarget.quadruped.kinematics import quadruped_kinematics
from engine.retarget.quadruped.pipeline import RetargetOptions, retarget_detailed
from engine.retarget.quadruped.smr import SmrOptions
from engine.retarget.synthetic import synthetic_trot

ROBOTS = ("go1", "a1", "go2", "b1", "anymal_c")
FRAMES = 24


@st.composite
def schedules(draw) -> np.ndarray:
    cols = []
    for _ in range(4):
        c, t = [], 0
        state = draw(st.booleans())
        while t < FRAMES:
            n = draw(st.integers(1, 8))
            c += [state] * n
            t += n
            state = not state
        cols.append(c[:FRAMES])
    return np.array(cols).T


def check(robot: str, contact: np.ndarray, heightmap: HeightMap, baseless: bool = False, touchdowns: bool = True) -> None:
    kin = quadruped_kinematics(robot)
    source = synthetic_trot("a1", frames=FRAMES, fps=30.0, contact=contact)
    options = RetargetOptions(baseless=baseless, contacts="source", heightmap=heightmap,  # the schedule under test
                              smr=SmrOptions(touchdowns=touchdowns))
    motion = retarget_detailed(source, robot, "smr", options).motion
    enforced = np.array(motion.source["contact_enforced"], dtype=bool)
    assert enforced[contact].all()  # every source contact is kept
    if not touchdowns:
        assert (enforced == contact).all()  # and nothing else: the schedule is preserved exactly
    feet = motion.keypoints[:, 3::4]
    for leg in range(4):
        for start, end, value in segments(enforced[:, leg]):
            if value:
                drift = np.linalg.norm(feet[start:end, leg] - feet[start, leg], axis=1).max()
                assert drift < 1e-4, f"{robot} leg {leg} frames {start}-{end}: foot moved {drift * 1000:.4f} mm"
                ground = heightmap.support_heights(feet[start, leg, :2], kin.foot_radius_m[leg])[0] + kin.foot_radius_m[leg]
                assert abs(feet[start, leg, 2] - ground) < 1e-4
    ground = heightmap.heights(feet[:, :, :2]) + kin.foot_radius_m[None, :]
    assert (feet[:, :, 2] >= ground - 1e-5).all(), f"penetration {(ground - feet[:, :, 2]).max() * 1000:.3f} mm"


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(robot=st.sampled_from(ROBOTS), contact=schedules())
def test_contact_feet_stay_on_their_anchors_on_flat_ground(robot, contact):
    check(robot, contact, HeightMap())
    check(robot, contact, HeightMap(), touchdowns=False)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(robot=st.sampled_from(ROBOTS), contact=schedules(), height=st.floats(0.02, 0.08), x=st.floats(0.0, 0.3))
def test_contact_feet_stay_on_their_anchors_with_a_box(robot, contact, height, x):
    check(robot, contact, HeightMap(0.0, (Box(x, 0.0, 0.4, 1.0, height),)))


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(robot=st.sampled_from(ROBOTS), contact=schedules())
def test_baseless_reconstruction_keeps_the_invariants(robot, contact):
    check(robot, contact, HeightMap(), baseless=True)
