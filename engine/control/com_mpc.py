"""Compatibility name of :mod:`engine.control.mpc` (the CoM MPC package); new code imports from there."""

from engine.control.mpc import *  # noqa: F401,F403
from engine.control.mpc import __all__  # noqa: F401
from engine.control.mpc.controller import FloatArray  # noqa: F401
from engine.control.mpc.lip import _Segments  # noqa: F401
from engine.control.mpc.regions import _make_region, _Region, _support_geometry  # noqa: F401
