"""Quadruped retargeting (STMR): UVM, SMR (spatial), TMR (temporal, another module).

The engine API the studio and the temporal stage use::

    from engine.retarget.quadruped import retarget, RetargetOptions
    motion = retarget(source, "go1", "smr", RetargetOptions(baseless=False), progress=cb, cancel=event)

``retarget_detailed`` also returns the UVM target keypoints and the timing (``engine.retarget.report.summary``
turns that into the figures ``studio retarget --json`` prints).
"""

from engine.retarget.quadruped.pipeline import (  # noqa: F401
    METHODS, QUADRUPEDS, NotAQuadruped, RetargetCancelled, RetargetOptions, RetargetOutput, retarget,
    retarget_detailed,
)
