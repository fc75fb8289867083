"""The whole-body tick's snapshot reader (engine/control/wbc/snapshot.py) gives DynamicsSnapshot.compute's numbers
bit for bit: the feet's placements, Jacobians and classical accelerations computed from pinocchio's joint-level
results against pinocchio's own frame functions, on random states of both robots."""

from __future__ import annotations

import numpy as np
import pytest

from engine.constants import SIDES
from engine.control.wbc.snapshot import SnapshotReader
from engine.control.wbc.tasks import DynamicsSnapshot
from engine.robot.model import load_robot

FIELDS = ("mass_matrix", "nonlinear_effects", "centroidal_map", "centroidal_drift", "momentum", "com_m",
          "base_rotation", "frame_position_m", "frame_rotation", "frame_jacobian", "frame_velocity", "frame_drift")


def _random_states(robot, n: int, seed: int):  # noqa: ANN001, ANN202
    rng = np.random.default_rng(seed)
    model = robot.pin_model
    for k in range(n):
        q = robot.q_standing.copy()
        q[:3] += rng.normal(size=3) * 0.3
        quat = rng.normal(size=4)
        q[3:7] = quat / np.linalg.norm(quat)
        q[7:] += rng.normal(size=model.nq - 7) * 0.4
        v = rng.normal(size=model.nv) * (0.0 if k == 0 else 1.0 + k % 3)
        yield q, v


@pytest.mark.parametrize("name", ["g1", "talos"])
def test_reader_equals_dynamics_snapshot_bit_for_bit(name: str) -> None:
    robot = load_robot(name)
    model = robot.pin_model
    fids = [model.getFrameId(f"{s}_foot") for s in SIDES]
    reader = SnapshotReader(model, model.createData(), fids)
    assert reader.exact
    reference_data = model.createData()
    for q, v in _random_states(robot, 200, seed=3):
        got = reader.compute(q, v)
        want = DynamicsSnapshot.compute(model, reference_data, q, v, fids)
        assert got.mass_kg == want.mass_kg
        for field in FIELDS:
            a, b = getattr(got, field), getattr(want, field)
            assert a.shape == b.shape, field
            # bit for bit, signed zeros included
            assert np.array_equal(np.ascontiguousarray(a).view(np.int64), np.ascontiguousarray(b).view(np.int64)), field


def test_reader_refuses_other_than_two_frames() -> None:
    model = load_robot("g1").pin_model
    with pytest.raises(ValueError, match="two frames"):
        SnapshotReader(model, model.createData(), [model.getFrameId("left_foot")])
