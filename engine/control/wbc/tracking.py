"""The controller slot for a reference-tracking whole-body controller."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from engine.control.controller import JointCommand, RobotState
from engine.control.wbc.reference import WbcReference

FloatArray = NDArray[np.float64]


# ----------------------------------------------------------------------------- controller slot


ReferenceSource = Callable[[RobotState], WbcReference]


class TrackingController:
    """Puts a reference-tracking whole-body controller (``compute(state, ref)``) in the
    simulation's controller slot: ``reference(state)`` supplies the reference each tick."""

    def __init__(self, wbc, reference: ReferenceSource):  # noqa: ANN001 - TaskSpaceInverseDynamics or PlacoWbc
        self.wbc = wbc
        self.reference = reference
        self.name = getattr(wbc, "name", "wbc")

    def reset(self, state: RobotState) -> None:
        self.wbc.reset(state)

    def compute(self, state: RobotState) -> JointCommand:
        return self.wbc.compute(state, self.reference(state))
