"""Equality up to floating-point rounding, for the speed-up reference tests.

A float rewrite of a numpy expression (``a @ b`` unrolled into products and sums) is bit-equal to it on
one CPU and an ulp or two off on another: numpy's dot and matmul kernels pick their instructions (fused
multiply-add or not, the order of a reduction) by the CPU they run on. The reference tests therefore
hold the new code to the old one within a few ulp of the operands' size, never more.
"""

from __future__ import annotations

import numpy as np

ROUNDING_ULP = 8  # a few roundings of an unrolled dot product, with room for one cancellation


def assert_equal_to_rounding(actual, desired, scale: float | None = None, ulp: int = ROUNDING_ULP,  # noqa: ANN001
                             err_msg: str = "") -> None:
    """``actual`` equals ``desired`` to ``ulp`` units of ``max(|desired|, scale)`` (NaN where NaN, inf where inf).

    ``scale``: the size of the terms that were summed, when the result can cancel below them."""
    a, d = np.asarray(actual, dtype=float), np.asarray(desired, dtype=float)
    assert a.shape == d.shape, f"shapes differ: {a.shape} vs {d.shape}. {err_msg}"
    size = np.abs(np.where(np.isfinite(d), d, 0.0))
    if scale is not None:
        size = np.maximum(size, scale)
    finite = np.isfinite(d)
    np.testing.assert_array_equal(np.isfinite(a), finite, err_msg=f"non-finite entries differ. {err_msg}")
    np.testing.assert_array_equal(a[~finite], d[~finite], err_msg=err_msg)
    tol = ulp * np.finfo(float).eps * size[finite]
    bad = np.abs(a[finite] - d[finite]) > tol
    assert not bad.any(), (f"{int(bad.sum())} of {bad.size} entries differ beyond {ulp} ulp: "
                           f"{a[finite][bad][:4].tolist()} vs {d[finite][bad][:4].tolist()} "
                           f"(tolerance {tol[bad][:4].tolist()}). {err_msg}")
