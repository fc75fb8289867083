"""Unitree-style motion CSV: one row per frame, no header: x, y, z, qx, qy, qz, qw, joints (robot's own order).

The frame rate is not stored in the file: it is the motion's fps (the README states it; retargeted STMR clips
keep their source's rate). Quaternions are converted from the engine's w,x,y,z at this edge.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from engine.atomic_io import atomic_write_text
from engine.retarget.motion import RobotMotion


def unitree_rows(motion: RobotMotion) -> np.ndarray:
    q = motion.qpos
    return np.concatenate([q[:, 0:3], q[:, 4:7], q[:, 3:4], q[:, 7:]], axis=1)


def export_unitree_csv(motion: RobotMotion, path: str | Path) -> None:
    buf = io.StringIO()
    np.savetxt(buf, unitree_rows(motion), delimiter=",", fmt="%.8f")
    atomic_write_text(path, buf.getvalue())


def read_unitree_csv(path: str | Path) -> np.ndarray:
    """qpos (T, 7+n) in MuJoCo order from a Unitree CSV."""
    rows = np.loadtxt(path, delimiter=",", ndmin=2)
    return np.concatenate([rows[:, 0:3], rows[:, 6:7], rows[:, 3:6], rows[:, 7:]], axis=1)
