"""Compatibility name of :mod:`engine.control.wbc.placo_peer`."""

from engine.control.wbc.placo_peer import PlacoWbc  # noqa: F401
