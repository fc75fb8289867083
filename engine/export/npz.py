"""The RobotMotion npz (format ``robot-motion/1``, see engine/retarget/motion.py), written atomically."""

from __future__ import annotations

from pathlib import Path

from engine.retarget.motion import RobotMotion


def export_npz(motion: RobotMotion, path: str | Path) -> None:
    motion.save(path)
