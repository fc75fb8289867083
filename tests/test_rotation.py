"""engine/geometry/rotation.py: roll and pitch read back what rot_zyx composed (the project's one convention)."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from engine.geometry.rotation import matrix_from_quat, quat_from_matrix, roll_pitch_of, rot_zyx, yaw_of


@given(st.floats(-math.pi + 1e-6, math.pi - 1e-6), st.floats(-1.5, 1.5), st.floats(-math.pi + 1e-6, math.pi - 1e-6))
def test_roll_pitch_yaw_read_back_rot_zyx(yaw: float, pitch: float, roll: float) -> None:
    m = matrix_from_quat(quat_from_matrix(rot_zyx(yaw, pitch, roll)))  # through a quaternion, as from MuJoCo's qpos
    r, p = roll_pitch_of(m)
    assert abs(r - roll) < 1e-9 and abs(p - pitch) < 1e-9 and abs(yaw_of(m) - yaw) < 1e-9
