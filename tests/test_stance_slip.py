"""Stance slip counts the drift of a sole that is really in stance (planned flat and loaded)."""

from __future__ import annotations

import mujoco
import numpy as np

from engine.constants import GRAVITY_MPS2
from engine.gait.style import SIDES
from engine.robot.model import load_robot
from engine.stance_slip import SLIP_SETTLE_S, STANCE_LOAD_FRACTION, StanceSlipMeter
from engine.walk_runner import ContactMeter

DT_S = 0.002
WEIGHT_N = 35.0 * GRAVITY_MPS2


def _feed(meter: StanceSlipMeter, flat: list[bool], xy_m: np.ndarray, load_n: list[float], ticks: int,
          velocity_mps: np.ndarray | None = None) -> np.ndarray:
    """Feed ``ticks`` ticks of the same plan and loads, the left sole moving at ``velocity_mps``; returns its final xy."""
    xy = np.array(xy_m, dtype=float)
    for _ in range(ticks):
        meter.update(np.array(flat), xy, np.array(load_n))
        if velocity_mps is not None:
            xy[0] += velocity_mps * DT_S
    return xy


def test_air_travel_after_a_late_touchdown_is_not_slip() -> None:
    # The plan holds the left foot flat on the ground for 0.24 s while the foot is still in the air,
    # travelling 48 mm forward (a stumble); then it lands and stands still. Anchored on the plan alone
    # (the old metric) this read over 40 mm of slip.
    meter = StanceSlipMeter(DT_S, WEIGHT_N)
    xy = np.array([[0.0, 0.1], [0.0, -0.1]])
    xy = _feed(meter, [True, True], xy, [0.0, WEIGHT_N], 120, velocity_mps=np.array([0.4, 0.0]))
    assert xy[0, 0] > 0.045
    _feed(meter, [True, True], xy, [0.5 * WEIGHT_N, 0.5 * WEIGHT_N], 200)
    assert meter.max_slip_m < 1e-9
    # The same feed with no load condition (the old meter) sees the air travel.
    old = StanceSlipMeter(DT_S, WEIGHT_N, load_fraction=-np.inf)
    xy = _feed(old, [True, True], np.array([[0.0, 0.1], [0.0, -0.1]]), [0.0, WEIGHT_N], 120,
               velocity_mps=np.array([0.4, 0.0]))
    assert old.max_slip_m > 0.04


def test_a_loaded_sole_that_slides_is_caught() -> None:
    meter = StanceSlipMeter(DT_S, WEIGHT_N)
    xy = np.array([[0.0, 0.1], [0.0, -0.1]])
    xy = _feed(meter, [True, True], xy, [0.6 * WEIGHT_N, 0.4 * WEIGHT_N], 20)  # settles, anchors
    # Slides 5 mm sideways over 0.25 s while carrying 60 % of the weight.
    _feed(meter, [True, True], xy, [0.6 * WEIGHT_N, 0.4 * WEIGHT_N], 125, velocity_mps=np.array([0.0, 0.02]))
    assert 0.0045 < meter.max_slip_m < 0.0055


def test_a_lightly_touching_foot_is_not_in_stance_and_unloading_drops_the_anchor() -> None:
    meter = StanceSlipMeter(DT_S, WEIGHT_N)
    light = 0.5 * STANCE_LOAD_FRACTION * WEIGHT_N
    xy = np.array([[0.0, 0.1], [0.0, -0.1]])
    # Brushing the floor (below the load fraction) while moving 2 cm: not stance.
    xy = _feed(meter, [True, True], xy, [light, WEIGHT_N], 100, velocity_mps=np.array([0.1, 0.0]))
    assert meter.max_slip_m < 1e-9
    # Loaded, still: anchors after the settle time; then unloaded and moved; loaded again: a new anchor.
    _feed(meter, [True, True], xy, [WEIGHT_N, WEIGHT_N], int(2 * SLIP_SETTLE_S / DT_S))
    xy = _feed(meter, [True, True], xy, [0.0, WEIGHT_N], 50, velocity_mps=np.array([0.3, 0.0]))
    _feed(meter, [True, True], xy, [WEIGHT_N, WEIGHT_N], 50)
    assert meter.max_slip_m < 1e-9
    # A foot the plan does not hold flat (heel or toe roll) is not measured, loaded or not.
    _feed(meter, [False, True], xy, [WEIGHT_N, WEIGHT_N], 50, velocity_mps=np.array([0.1, 0.0]))
    assert meter.max_slip_m < 1e-9


def test_contact_meter_measures_each_foot_load_from_mujoco() -> None:
    robot = load_robot("g1")
    model = robot.mj_model
    data = mujoco.MjData(model)
    soles = [model.body(robot.config.soles[s].link).id for s in SIDES]
    meter = ContactMeter(model, soles)
    data.qpos[:] = robot.mj_standing_qpos()
    mujoco.mj_forward(model, data)
    _, total = meter.cop(data)
    weight = robot.mass_kg * GRAVITY_MPS2
    assert total > 0.2 * weight
    assert np.all(meter.foot_load_n > STANCE_LOAD_FRACTION * weight)  # standing: both feet carry load
    assert abs(meter.foot_load_n.sum() - total) < 1e-6 * total  # every floor contact is a sole's
    # Lifted 5 cm off the floor, neither foot carries anything.
    data.qpos[2] += 0.05
    mujoco.mj_forward(model, data)
    meter.cop(data)
    assert np.all(meter.foot_load_n == 0.0)
