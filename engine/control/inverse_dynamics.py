"""Compatibility name of :mod:`engine.control.wbc` (the whole-body controller package); new code imports from there."""

from engine.constants import CONTROL_PERIOD_S, GRAVITY_MPS2, SIDES  # noqa: F401
from engine.control.wbc import *  # noqa: F401,F403
from engine.control.wbc import __all__  # noqa: F401
from engine.control.wbc.qp import CentroidalQp, DaqpQpSolver, DenseQpSolver, OsqpQpSolver  # noqa: F401
from engine.control.wbc.reference import N_BASIS, N_CORNERS  # noqa: F401
from engine.control.wbc.setpoints import fallback_hold, integrate_setpoints  # noqa: F401
