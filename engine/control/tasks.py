"""Compatibility name of :mod:`engine.control.wbc.tasks`."""

from engine.control.wbc.tasks import *  # noqa: F401,F403
from engine.control.wbc.tasks import __all__  # noqa: F401
