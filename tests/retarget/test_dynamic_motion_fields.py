"""The dynamic fields of a RobotMotion (TMR's result) survive a save/load and bad ones are one-line errors."""

from __future__ import annotations

import numpy as np
import pytest

from engine.retarget.motion import MotionFormatError, RobotMotion


def _motion(**extra) -> RobotMotion:  # noqa: ANN003
    T, n = 5, 12
    qpos = np.zeros((T, 7 + n))
    qpos[:, 3] = 1.0
    return RobotMotion(fps=100.0, qpos=qpos, joint_names=[f"j{i}" for i in range(n)], contact=np.ones((T, 4), bool),
                       robot="go1", method="stmr", qvel=np.zeros((T, 6 + n)), ctrl=np.ones((T, n)), extra=extra)


def test_dynamic_fields_round_trip(tmp_path) -> None:  # noqa: ANN001
    m = _motion(pd_targets=np.full((5, 12), 0.1), pd_kp=np.full(12, 30.0), pd_kd=np.ones(12), alpha=np.array([1.5]),
                segment_knots_s=np.array([0.0, 0.06]), contact_sim=np.zeros((5, 4), bool))
    m.save(tmp_path / "d.npz")
    back = RobotMotion.load(tmp_path / "d.npz")
    assert set(back.extra) == set(m.extra)
    for k, v in m.extra.items():
        np.testing.assert_array_equal(back.extra[k], v)
    assert back.extra["contact_sim"].dtype == bool


@pytest.mark.parametrize("extra, expected", [
    ({"pd_targets": np.zeros((4, 12))}, "pd_targets: expected shape (5, 12), got (4, 12)"),
    ({"pd_kp": np.full(12, np.nan)}, "pd_kp: expected finite numbers"),
    ({"alpha": np.array([1.0, 2.0]), "segment_knots_s": np.array([0.0, 1.0])}, "segment_knots_s: expected S + 1 = 3"),
    ({"alpha": np.array([-1.0])}, "alpha: expected positive time scales"),
    ({"contact_sim": np.full((5, 4), 2)}, "contact_sim: expected booleans"),
    ({"weights": np.zeros(3)}, "weights: expected one of pd_targets"),
])
def test_bad_dynamic_fields_are_one_line_errors(extra, expected) -> None:  # noqa: ANN001
    with pytest.raises(MotionFormatError) as err:
        _motion(**extra)
    assert expected in str(err.value) and "\n" not in str(err.value)
