"""Exports of a RobotMotion: one module per format, each a function ``export_<format>(motion, path, ...)``.

* ``amp_json``    — motion_imitation / AMP_for_hardware JSON (``--amp-full``: the 61-value AMP frame)
* ``unitree_csv`` — Unitree-style CSV, no header: xyz, quat x,y,z,w, joints (fps stated in the README)
* ``npz``         — the RobotMotion npz itself
"""

from __future__ import annotations

from pathlib import Path

from engine.retarget.motion import RobotMotion

FORMATS = ("amp-json", "unitree-csv", "npz")


def export_motion(motion: RobotMotion, fmt: str, path: str | Path, amp_full: bool = False,
                  amp_leg_order: str = "pybullet") -> None:
    if fmt == "amp-json":
        from engine.export.amp_json import export_amp_json

        export_amp_json(motion, path, full=amp_full, leg_order=amp_leg_order)
    elif fmt == "unitree-csv":
        from engine.export.unitree_csv import export_unitree_csv

        export_unitree_csv(motion, path)
    elif fmt == "npz":
        from engine.export.npz import export_npz

        export_npz(motion, path)
    else:
        raise ValueError(f"--format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
