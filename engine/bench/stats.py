"""Shared statistics of the bench sections."""

from __future__ import annotations

import numpy as np


def percentiles_us(samples_s: list[float] | np.ndarray) -> dict[str, float]:
    arr = np.asarray(samples_s, dtype=float) * 1e6
    if arr.size == 0:
        return {"median_us": float("nan"), "p99_us": float("nan")}
    return {"median_us": round(float(np.median(arr)), 1), "p99_us": round(float(np.percentile(arr, 99)), 1)}
