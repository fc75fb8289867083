"""Physical and timing constants shared by the whole engine (defined once)."""

from __future__ import annotations

GRAVITY_MPS2 = 9.81  # standard gravity used by every model of the controller (LIP, ID, estimator)
CONTROL_PERIOD_S = 0.002  # 500 Hz: one physics step per control tick
SIDES = ("left", "right")  # biped feet, in this order everywhere inside the engine
FOOT_FRAMES = ("left_foot", "right_foot")  # the soles' frames of a biped's model, in SIDES' order
