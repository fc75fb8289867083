"""Quadruped retargeting (STMR): UVM, SMR (spatial), TMR (temporal, ``tmr/``).

The engine API the studio and the temporal stage use::

    from engine.retarget.quadruped.pipeline import retarget, RetargetOptions
    motion = retarget(source, "go1", "smr", RetargetOptions(baseless=False), progress=cb, cancel=event)

The returned motion carries its figures in ``motion.metrics`` (foot slide, contact IoU, penetration, keypoint
error, DTW %, travel, frames/s: ``engine.retarget.report.summary``, what ``studio retarget --json`` prints);
``retarget_detailed`` also returns the UVM target keypoints and the timing. Sources: ``engine.retarget.importers.
import_source(path)`` or ``KeypointMotion.load``; exports: ``engine.export.export_motion(motion, fmt, path)``.
"""
