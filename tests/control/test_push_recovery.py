"""Push recovery on the recorded run (issue 16): where the robot ends up and how fast it goes afterwards,
not only "did not fall". The issue's check: a 1 s push at the pelvis of 1.5 N/kg and of 1 N/kg from each
of four sides — from standing the robot comes back to rest within 3 s after the push ends and has moved
< 0.6 m; from walking it is back at the commanded velocity within 3 s. The velocity is the mean over the
first whole gait cycle from 3 s after the push (over another length the sway of the steps biases it: G1
undisturbed at 0.15 m/s reads up to 0.055 m/s off over 1 s, 0.031 over a cycle; engine/bench/push.py).
The same matrix with 16 phases of the gait cycle while walking is `studio bench push`.
"""

from __future__ import annotations

import numpy as np
import pytest

from engine.bench.push import DIRECTIONS, gait_cycle, settled_window
from engine.gait.command_schedule import parse_command
from engine.gait.style import load_style
from engine.robot.model import load_robot
from engine.walk_batch import com_at, window_velocity
from engine.walk_runner import PushSpec, run_walk
from tests.conftest import REPO

pytestmark = pytest.mark.slow

PUSH_S = 1.0
SETTLE_S = 3.0  # back at rest / at the commanded velocity this long after the push ends
MAX_DISPLACEMENT_M = 0.6  # from standing: CoM from the push's start to SETTLE_S after its end
AT_REST_MPS = 0.05  # mean CoM velocity over the gait cycle after SETTLE_S (stepping in place sways)
WALK_MPS = 0.15

# Cases measured outside the goal (G1 neutral, push at t = 3.0 s): kept as strict xfails so a fix
# shows up as an unexpected pass. Figures: README "Style space, feasibility check and push recovery".
NOT_MET: dict[tuple[str, float], str] = {}

WALK_NOT_MET: dict[str, str] = {}


@pytest.fixture(scope="module")
def g1():
    return load_robot("g1"), load_style(REPO / "styles/g1/neutral.json")


def _push(robot, style, command: str, t_push: float, side: str, n_per_kg: float):
    ux, uy = DIRECTIONS[side]
    force = (ux * n_per_kg * robot.mass_kg, uy * n_per_kg * robot.mass_kg, 0.0)
    t_end = t_push + PUSH_S
    window = settled_window(t_end, gait_cycle(robot.name, style, float(command.split(",")[0]), t_push)[1])
    summary, rec = run_walk(robot, style, parse_command(command, style.velocities), window[1] + 0.1,
                            pushes=[PushSpec(t_push, force, PUSH_S)])
    return summary, rec, t_end, window


def _standing_cases():
    for n_per_kg in (1.5, 1.0):
        for side in DIRECTIONS:
            reason = NOT_MET.get((side, n_per_kg))
            marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
            yield pytest.param(side, n_per_kg, marks=marks, id=f"{side}-{n_per_kg:g}N/kg")


@pytest.mark.parametrize(("side", "n_per_kg"), list(_standing_cases()))
def test_a_push_from_standing_ends_at_rest_nearby(g1, side, n_per_kg):
    """Standing (command 0): it used to walk away for good (8 m in 15 s from the front)."""
    robot, style = g1
    t_push = 3.0
    summary, rec, t_end, window = _push(robot, style, "0,0,0", t_push, side, n_per_kg)
    assert not summary["fell"], summary
    v = window_velocity(rec, *window)
    assert v is not None and np.linalg.norm(v) < AT_REST_MPS, f"still moving {SETTLE_S} s after the push: {v} m/s"
    moved = float(np.linalg.norm(com_at(rec, t_end + SETTLE_S) - com_at(rec, t_push)))
    assert moved < MAX_DISPLACEMENT_M, f"moved {moved:.2f} m"


def _walking_cases():
    for side in DIRECTIONS:
        reason = WALK_NOT_MET.get(side)
        yield pytest.param(side, marks=[pytest.mark.xfail(strict=True, reason=reason)] if reason else [], id=side)


@pytest.mark.parametrize("side", list(_walking_cases()))
def test_a_push_while_walking_returns_to_the_commanded_velocity(g1, side):
    """1.5 N/kg while walking at 0.15 m/s (the body-frame command: a push that turns the robot a little
    changes the heading, so the speed is compared)."""
    robot, style = g1
    summary, rec, t_end, window = _push(robot, style, f"{WALK_MPS},0,0", 4.5, side, 1.5)
    assert not summary["fell"], summary
    v = window_velocity(rec, *window)
    assert v is not None and abs(np.linalg.norm(v) - WALK_MPS) < 0.05, v


# TALOS, 1.5 N/kg from standing (robots/talos.toml [control.walking]: the stance-foot capture, 0.6 m steps,
# κ at its bound (2.0 in single support) while pushed, path_follows_feet 0.5). From the side it fell before
# (4.4 / 5.3 s). Cases measured outside the goal would be strict xfails here.
TALOS_NOT_MET: dict[str, str] = {}


def _talos_cases():
    for side in DIRECTIONS:
        reason = TALOS_NOT_MET.get(side)
        yield pytest.param(side, marks=[pytest.mark.xfail(strict=True, reason=reason)] if reason else [], id=side)


@pytest.mark.parametrize("side", list(_talos_cases()))
def test_talos_pushed_from_standing_ends_at_rest_nearby(side):
    robot, style = load_robot("talos"), load_style(REPO / "styles/talos/neutral.json")
    t_push = 3.0
    summary, rec, t_end, window = _push(robot, style, "0,0,0", t_push, side, 1.5)
    assert not summary["fell"], summary
    v = window_velocity(rec, *window)
    assert v is not None and np.linalg.norm(v) < AT_REST_MPS, f"still moving {SETTLE_S} s after the push: {v} m/s"
    moved = float(np.linalg.norm(com_at(rec, t_end + SETTLE_S) - com_at(rec, t_push)))
    assert moved < MAX_DISPLACEMENT_M, f"moved {moved:.2f} m"
