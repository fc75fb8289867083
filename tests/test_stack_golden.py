"""The speed-ups compute the same numbers as before.

tests/data/stack_golden_g1.npz was recorded by tools/record_stack_golden.py with the
implementation before any speed-up (commit 924822b): a 1.5 s closed-loop G1 sweep (joint
commands, gait references, CoM plans) and the whole-body QP's recorded inputs and outputs.
"""

from __future__ import annotations

from dataclasses import fields
from pathlib import Path

import numpy as np
import pytest

from engine.control.controller import RobotState
from engine.control.wbc import TaskSpaceInverseDynamics, WbcReference
from engine.robot.model import load_robot
from tools.record_stack_golden import record

GOLDEN = Path(__file__).parent / "data" / "stack_golden_g1.npz"


@pytest.fixture(scope="module")
def golden() -> dict[str, np.ndarray]:
    with np.load(GOLDEN, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def test_closed_loop_reproduces_the_recording(golden) -> None:
    now = record()
    # Plans and references first (a divergence shows where it starts), then the joint commands.
    np.testing.assert_allclose(now["plan_t"], golden["plan_t"], atol=1e-12)
    np.testing.assert_allclose(now["ref_foot_pos"], golden["ref_foot_pos"], atol=1e-9)
    np.testing.assert_allclose(now["ref_pelvis_z"], golden["ref_pelvis_z"], atol=1e-9)
    np.testing.assert_allclose(now["ref_upper_q"], golden["ref_upper_q"], atol=1e-9)
    np.testing.assert_allclose(now["plan_waypoints"], golden["plan_waypoints"], atol=1e-7)
    np.testing.assert_allclose(now["plan_com"], golden["plan_com"], atol=1e-7)
    np.testing.assert_allclose(now["q_des"], golden["q_des"], atol=1e-7)
    np.testing.assert_allclose(now["qd_des"], golden["qd_des"], atol=1e-5)
    np.testing.assert_allclose(now["tau_ff"], golden["tau_ff"], atol=1e-4)


def test_whole_body_qp_reproduces_recorded_ticks(golden) -> None:
    robot = load_robot("g1")
    from engine.gait.style import StyleContext

    wbc = TaskSpaceInverseDynamics(robot, upper_body_joints=StyleContext.for_robot("g1").upper_joints)
    n = len(golden["id_q"])
    names = [f.name for f in fields(WbcReference)]
    for k in range(n):
        kw = {}
        for name in names:
            value = golden[f"id_ref_{name}"][k]
            if name in ("external_wrench", "com_z_m") and np.isnan(value).all():
                kw[name] = None
            elif name == "contact":
                kw[name] = value.astype(bool)
            elif value.ndim == 0 or name in ("pelvis_height_m", "pelvis_height_rate_mps"):
                kw[name] = float(value)
            elif name == "com_z_m":
                kw[name] = float(value[0])
            else:
                kw[name] = value
        state = RobotState(0.0, golden["id_q"][k], golden["id_v"][k])
        if k == 0:
            wbc.reset(state)
        wbc.compute(state, WbcReference(**kw))
        assert wbc.diagnostics.ok
        np.testing.assert_allclose(wbc.diagnostics.qdd, golden["id_qdd"][k], atol=1e-6)
        np.testing.assert_allclose(wbc.diagnostics.tau_nm, golden["id_tau"][k], atol=1e-6)
