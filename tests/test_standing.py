"""Every biped and quadruped stands 10 s in MuJoCo under joint PD (static-balance feed-forward)."""

from __future__ import annotations

import numpy as np
import pytest

from engine.robot.config import load_robot_config, robot_names
from engine.robot.model import load_robot
from engine.sim import Simulation

SIMULATED = [n for n in robot_names() if load_robot_config(n).simulated]
# 10 simulated seconds each: G1 stands in the fast tier, the other robots in the slow one (`make test`)
STANDING = [pytest.param(n, marks=() if n == "g1" else pytest.mark.slow) for n in SIMULATED]


@pytest.mark.parametrize("name", STANDING)
def test_stands_ten_seconds(name):
    sim = Simulation(load_robot(name))
    z0 = float(sim.data.qpos[2])
    heights = []
    for _ in range(int(10.0 / sim.model.opt.timestep)):
        sim.step()
        heights.append(sim.data.qpos[2])
    assert not sim.fallen
    assert np.max(np.abs(np.array(heights) - z0)) < 0.05
    assert np.linalg.norm(sim.data.qpos[:2]) < 0.05  # it did not wander off


def test_a_hard_push_topples_g1_and_is_detected():
    sim = Simulation(load_robot("g1"))
    sim.push(np.array([0.0, 400.0, 0.0]), 0.5)
    for _ in range(2000):
        sim.step()
    assert sim.fallen
    sim.reset()
    assert not sim.fallen and abs(sim.data.qpos[2] - load_robot("g1").q_standing[2]) < 1e-9
