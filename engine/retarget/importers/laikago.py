"""Keypoints of motion_imitation's Laikago frames (Peng et al. 2020: ``laikago/laikago_toes.urdf``).

That model is not example-robot-data's ``laikago.urdf``: its chassis frame is y up, z forward, x left
(the frames' root quaternion includes INIT_ROT = (0.5, 0.5, 0.5, 0.5) x,y,z,w), its thighs point 34° backward
at zero and its hip axes are mirrored between the sides. So the FK here is the chain of that URDF's joint
placements (constants below: hip, upper-leg, knee and toe offsets; rotation axes), applied with numpy. The root
position of a pybullet frame is the chassis's centre of mass (inertial origin (0, 0.03, 0.0438) in the chassis
frame), which is removed first. Checked numerically: on the standing frames of sidesteps/hopturn the toe spheres
(r = 3 cm) rest on the ground within a few millimetres, and the left legs are on the left.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

INIT_ROT_XYZW = np.array([0.5, 0.5, 0.5, 0.5])
COM_OFFSET = np.array([0.0, 0.03, 0.043794])
TOE_RADIUS_M = 0.03
# per leg in the engine order FL, FR, RL, RR: hip origin, hip axis sign (about z), upper-leg offset, knee offset
_LEGS = {
    "FL": ((0.0817145, 0.0, 0.242889), +1.0, (0.055855, 0.0, 0.0), (-0.02069, -0.20833, -0.1422)),
    "FR": ((-0.0817145, 0.0, 0.242889), -1.0, (-0.053565, 0.0, 0.0), (0.02069, -0.20833, -0.1422)),
    "RL": ((0.0817145, 0.0, -0.194401), +1.0, (0.055855, 0.0, 0.0), (-0.02069, -0.20833, -0.1422)),
    "RR": ((-0.0817145, 0.0, -0.194401), -1.0, (-0.053565, 0.0, 0.0), (0.02069, -0.20833, -0.1422)),
}
_TOE = np.array([0.0, -0.25, -0.022])


def _rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    return Rotation.from_rotvec(angle[:, None] * axis[None, :]).as_matrix()


def laikago_keypoints(frames: np.ndarray, order: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World keypoints (T, 16, 3), body-frame base position (T, 3) and heading quaternion (T, 4, w,x,y,z)."""
    t_n = len(frames)
    r_file = Rotation.from_quat(frames[:, 3:7])  # x,y,z,w
    rot = r_file.as_matrix()
    origin = frames[:, 0:3] - rot @ COM_OFFSET
    legs = frames[:, 7:19].reshape(t_n, 4, 3)
    kp = np.empty((t_n, 16, 3))
    for e, leg in enumerate(("FL", "FR", "RL", "RR")):
        hip, sign, upper, knee = (np.asarray(v, dtype=float) if not isinstance(v, float) else v for v in _LEGS[leg])
        angles = legs[:, order.index(leg)]
        r_hip = _rot(np.array([0.0, 0.0, sign]), angles[:, 0])
        r_up = r_hip @ _rot(np.array([1.0, 0.0, 0.0]), angles[:, 1])
        r_low = r_up @ _rot(np.array([1.0, 0.0, 0.0]), angles[:, 2])
        p_hip = np.broadcast_to(hip, (t_n, 3))
        p_thigh = p_hip + r_hip @ upper
        p_knee = p_thigh + r_up @ knee
        p_toe = p_knee + r_low @ _TOE
        for k, p in enumerate((p_hip, p_thigh, p_knee, p_toe)):
            kp[:, 4 * e + k] = origin + np.einsum("tij,tj->ti", rot, p)
    heading = (r_file * Rotation.from_quat(INIT_ROT_XYZW).inv()).as_quat()  # x,y,z,w
    return kp, origin, heading[:, [3, 0, 1, 2]]
