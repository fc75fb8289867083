"""Small vector helpers on the control stack's hot paths."""

from __future__ import annotations

import math

import numpy as np


def vector_norm(x: np.ndarray) -> float:
    """Euclidean norm of a 1-D float array: ``np.linalg.norm``'s own expression (√ of ``x.dot(x)``, the same
    number) without its Python overhead (called several times every planner tick)."""
    return math.sqrt(float(x.dot(x)))
