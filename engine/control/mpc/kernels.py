"""The CoM MPC's compiled (numba) kernels: the support polygons' padded geometry in one call.

:func:`geometry_padded` computes what :func:`engine.control.mpc.regions._geometry_padded` computes with
complex numpy arrays (hull, outward normals, half-plane offsets, centroids, areas, the not-convex
mask), on real and imaginary parts and with numpy's complex products, quotients and row sums
spelled out in the same order: the same numbers (``tests/control/test_stack_speed_references.py``).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core.extending import intrinsic


@intrinsic
def _fma(typingctx, a, b, c):  # noqa: ANN001, ANN202, ARG001
    """a·b + c rounded once (LLVM's fma): numpy's SIMD complex product uses fused multiply-adds."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # noqa: ANN001, ANN202, ARG001
        double = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [double], ir.FunctionType(double, [double, double, double]))
        return builder.call(fn, args)

    return sig, codegen


@njit(cache=True, nogil=True, inline="always")
def _cmul(ar, ai, br, bi):  # noqa: ANN001, ANN202
    """numpy's complex product (a_r b_r − a_i b_i, a_r b_i + a_i b_r), each part one fused multiply-add."""
    return _fma(ar, br, -(ai * bi)), _fma(ar, bi, ai * br)


@njit(cache=True, nogil=True)
def _row_sum(values, n):  # noqa: ANN001, ANN201
    """Σ values[:n] in numpy's order (its pairwise sum: one accumulator below 8 terms, else eight)."""
    if n < 8:
        total = 0.0
        for j in range(n):
            total += values[j]
        return total
    acc = values[:8].copy()
    i = 8
    while i + 8 <= n:
        for j in range(8):
            acc[j] += values[i + j]
        i += 8
    total = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]))
    for j in range(i, n):
        total += values[j]
    return total


@njit(cache=True, nogil=True)
def _complex_row_sum(re, im, n):  # noqa: ANN001, ANN201
    """Σ (re + i im)[:n] in numpy's order (its pairwise sum over the interleaved parts: one accumulator
    per part below 4 terms, else four)."""
    if 2 * n < 8:
        a, b = 0.0, 0.0
        for j in range(n):
            a += re[j]
            b += im[j]
        return a, b
    ar = re[:4].copy()
    ai = im[:4].copy()
    k = 4
    while 2 * (k + 4) <= 2 * n:
        for j in range(4):
            ar[j] += re[k + j]
            ai[j] += im[k + j]
        k += 4
    a, b = (ar[0] + ar[1]) + (ar[2] + ar[3]), (ai[0] + ai[1]) + (ai[2] + ai[3])
    for j in range(k, n):
        a += re[j]
        b += im[j]
    return a, b


@njit(cache=True, nogil=True)
def geometry_padded(points, lens, n_v, edge_length):  # noqa: ANN001, ANN201
    """Padded geometry of the polygons stacked in ``points`` (P, 2), ``lens[k]`` vertices each, ``n_v`` slots.

    Returns ``(hull (S, V, 2), normals (S, V, 2), offsets (S, V), centroids (S, 2), area (S,),
    bad (S,))``; unused slots: vertex 0, zero normal, +inf offset. ``edge_length`` (S, V) is numpy's
    ``abs`` of the padded edges (its SIMD hypot differs from libm's in the last bit)."""
    n_s = lens.shape[0]
    hull = np.empty((n_s, n_v, 2))
    normals = np.zeros((n_s, n_v, 2))
    offsets = np.empty((n_s, n_v))
    centroids = np.empty((n_s, 2))
    area = np.empty(n_s)
    bad = np.zeros(n_s, dtype=np.bool_)
    cross = np.empty(n_v)
    sx = np.empty(n_v)
    sy = np.empty(n_v)
    nx = np.empty(n_v)
    ny = np.empty(n_v)
    length = np.empty(n_v)
    start = 0
    for k in range(n_s):
        n = lens[k]
        x0, y0 = points[start, 0], points[start, 1]
        for j in range(n_v):
            i = j if j < n else 0
            hull[k, j, 0], hull[k, j, 1] = points[start + i, 0], points[start + i, 1]
        for j in range(n_v):
            jn = j + 1 if j + 1 < n else 0
            zx, zy = hull[k, j, 0], hull[k, j, 1]
            znx, zny = points[start + jn, 0], points[start + jn, 1]
            wx, wy = zx - x0, zy - y0
            wnx, wny = znx - x0, zny - y0
            cross[j] = _cmul(wx, -wy, wnx, wny)[1]  # imag(conj(w) wn)
            sx[j], sy[j] = wx + wnx, wy + wny
            ex, ey = znx - zx, zny - zy
            length[j] = edge_length[k, j]
            nx[j], ny[j] = ex, ey
        area2 = _row_sum(cross, n_v)
        orient = -1.0 if area2 < 0.0 else 1.0
        cr, ci = _cmul(-0.0, -1.0, orient, 0.0)  # (-1j) * (orient + 0j)
        for j in range(n_v):
            ex, ey = nx[j], ny[j]
            px, py = _cmul(ex, ey, cr, ci)  # e * (-1j orient)
            d = max(length[j], 1e-300)
            scl = 1.0 / (d + 0.0 * 0.0)  # numpy's complex ÷ (d + 0j)
            nx[j], ny[j] = (px + py * 0.0) * scl, (py - px * 0.0) * scl
        for j in range(n_v):
            jp = j - 1 if j > 0 else n - 1
            # rel = conj(n_prev) n
            rel_re, rel_im = _cmul(nx[jp], -ny[jp], nx[j], ny[j])
            if (length[j] <= 1e-9 and j < n) or rel_im * orient < -1e-9:
                bad[k] = True
            use = length[j] > 1e-9 and rel_re < 1.0 - 1e-12
            if use:
                normals[k, j, 0], normals[k, j, 1] = nx[j], ny[j]
                offsets[k, j] = _cmul(nx[j], -ny[j], hull[k, j, 0], hull[k, j, 1])[0]
            else:
                offsets[k, j] = np.inf
        # centroid: z0 + Σ (w + wn) cross / (3 area2)
        for j in range(n_v):
            sx[j], sy[j] = _cmul(sx[j], sy[j], cross[j], 0.0)
        cx, cy = _complex_row_sum(sx, sy, n_v)
        den = 3.0 * (1.0 if area2 == 0.0 else area2)
        rat = 0.0 / den  # numpy's complex ÷ (den + 0j) (Smith's method, |real| ≥ |imag|)
        scl = 1.0 / (den + 0.0 * rat)
        centroids[k, 0] = x0 + (cx + cy * rat) * scl
        centroids[k, 1] = y0 + (cy - cx * rat) * scl
        area[k] = 0.5 * abs(area2)
        start += n
    return hull, normals, offsets, centroids, area, bad
