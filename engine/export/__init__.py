"""Exports of a RobotMotion: one module per format, each a function ``export_<format>(motion, path, ...)``.

* ``amp_json``        — motion_imitation / AMP_for_hardware JSON (``--amp-full``: the 61-value AMP frame)
* ``unitree_csv``     — Unitree-style CSV, no header: xyz, quat x,y,z,w, joints (Unitree's order for G1)
* ``beyondmimic_npz`` — BeyondMimic / whole_body_tracking npz (fps, joint_pos, …, body_quat_w w,x,y,z)
* ``npz``             — the RobotMotion npz itself

``fps`` resamples first (``resample.py``: lerp, root slerp).
"""

from __future__ import annotations

from pathlib import Path

from engine.retarget.motion import RobotMotion

FORMATS = ("amp-json", "unitree-csv", "beyondmimic-npz", "npz")
SUFFIXES = {"amp-json": (".json", ".txt"), "unitree-csv": (".csv",), "beyondmimic-npz": (".npz",), "npz": (".npz",)}


def export_motion(motion: RobotMotion, fmt: str, path: str | Path, amp_full: bool = False,
                  amp_leg_order: str = "pybullet", fps: float | None = None) -> RobotMotion:
    """Write ``motion`` (resampled to ``fps`` if given) as ``fmt``; returns the motion written."""
    if fmt not in FORMATS:
        raise ValueError(f"--format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
    if fps is not None:
        from engine.export.resample import resample

        motion = resample(motion, fps)
    if fmt == "amp-json":
        from engine.export.amp_json import export_amp_json

        export_amp_json(motion, path, full=amp_full, leg_order=amp_leg_order)
    elif fmt == "unitree-csv":
        from engine.export.unitree_csv import export_unitree_csv

        export_unitree_csv(motion, path)
    elif fmt == "beyondmimic-npz":
        from engine.export.beyondmimic_npz import export_beyondmimic_npz

        export_beyondmimic_npz(motion, path)
    else:
        from engine.export.npz import export_npz

        export_npz(motion, path)
    return motion
