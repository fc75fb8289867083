"""The walking controller's CoM comes from the whole-body controller's dynamics pass of the same tick (issue 12):
one pass per tick instead of two, the same CoM and CoM velocity as pinocchio's centerOfMass to rounding."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engine.control.walking_controller import WalkingController
from engine.control.wbc.snapshot import SnapshotReader
from engine.gait.command_schedule import preset
from engine.gait.style import load_style, styles_dir
from engine.robot.model import load_robot
from engine.sim import Simulation


def test_one_dynamics_pass_per_tick_and_the_com_matches_center_of_mass(monkeypatch) -> None:
    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    controller = WalkingController(robot, style)
    sim = Simulation(robot, controller)
    passes = [0]
    compute = SnapshotReader.compute

    def counting(self, q, v):
        passes[0] += 1
        return compute(self, q, v)

    monkeypatch.setattr(SnapshotReader, "compute", counting)
    center_of_mass = pin.centerOfMass
    com_calls = [0]

    def counting_com(*args):
        com_calls[0] += 1
        return center_of_mass(*args)

    monkeypatch.setattr(pin, "centerOfMass", counting_com)
    schedule = preset("sweep", style.velocities)
    dt = float(sim.model.opt.timestep)
    data = robot.pin_model.createData()
    worst_com, worst_vcom = 0.0, 0.0
    ticks = 600
    for k in range(ticks):
        controller.set_command(schedule(k * dt))
        sim.step()
        est = controller.estimate
        com = center_of_mass(robot.pin_model, data, est.q, est.v)
        worst_com = max(worst_com, float(np.abs(controller._com_now[0] - com).max()))
        worst_vcom = max(worst_vcom, float(np.abs(controller._com_now[1] - data.vcom[0]).max()))
    assert not sim.fallen
    assert passes[0] == ticks  # the controller's CoM and the QP read one pass per tick
    assert com_calls[0] == 0  # no second pass for the CoM
    assert worst_com < 1e-12 and worst_vcom < 1e-12, (worst_com, worst_vcom)
    assert controller.wbc.diagnostics.status == "solved"


def test_a_changed_state_is_not_served_the_prepared_pass(monkeypatch) -> None:
    """snapshot() prepares the pass for those (q, v) arrays; compute() with other arrays, or with the same arrays
    changed in place, computes its own pass; with the same unchanged arrays it reuses the prepared one."""
    from engine.control.controller import RobotState

    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    controller = WalkingController(robot, style)
    wbc = controller.wbc
    q = robot.q_standing.copy()
    v = np.zeros(robot.pin_model.nv)
    ref = wbc.hold_reference(q)
    wbc.reset(RobotState(0.0, q, v))
    passes: list[float] = []
    compute = SnapshotReader.compute

    def counting(self, q_, v_):
        passes.append(float(q_[0]))
        return compute(self, q_, v_)

    monkeypatch.setattr(SnapshotReader, "compute", counting)
    snap = wbc.snapshot(q, v)
    assert snap is not None and len(passes) == 1
    com_standing = snap.com_m.copy()
    wbc.compute(RobotState(0.0, q, v), ref)  # the same arrays, unchanged: the prepared pass
    assert len(passes) == 1 and wbc.diagnostics.status == "solved"
    q2 = q.copy()
    q2[0] += 0.1
    wbc.snapshot(q, v)
    wbc.compute(RobotState(0.0, q2, v), ref)  # other arrays: a pass of their own
    assert passes[1:] == [q[0], q2[0]]
    wbc.snapshot(q, v)
    x_prepared = float(q[0])
    q[0] += 0.1  # the prepared arrays changed in place before compute: not the prepared pass
    wbc.compute(RobotState(0.0, q, v), ref)
    assert passes[3:] == [x_prepared, float(q[0])]
    snap2 = wbc.snapshot(q2, v)
    np.testing.assert_allclose(snap2.com_m[0] - com_standing[0], 0.1, atol=1e-12)
    bad = q.copy()
    bad[3] = np.nan
    assert wbc.snapshot(bad, v) is None and wbc._prepared is None
