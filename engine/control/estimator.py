"""Compatibility name of :mod:`engine.control.estimation` (the state-estimation package)."""

from engine.control.estimation import *  # noqa: F401,F403
from engine.control.estimation import __all__  # noqa: F401
from engine.control.estimation.ekf import _inv_sym  # noqa: F401
from engine.control.estimation.quaternion import _quat_step  # noqa: F401
