"""Constraint regions of the CoP waypoints: polygons as half-planes, vectorised for all supports of a call
(intersections of consecutive supports by containment), padded to a fixed layout."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.control.mpc.kernels import geometry_padded, support_geometry
from engine.control.mpc.types import MIN_POLYGON_AREA_M2
from engine.geometry.polygon import convex_hull, polygon_area, polygon_centroid, polygon_halfplanes

FloatArray = NDArray[np.float64]


#: Tolerance of the containment test between consecutive supports [m].
_CONTAIN_TOL_M = 1e-9


@dataclass(frozen=True)
class _Region:
    """Geometry of one support polygon (reference path; used by the fallback plan)."""

    valid: bool
    normals: FloatArray  # (H, 2)
    offsets: FloatArray  # (H,)
    centroid: FloatArray  # (2,)
    hull: FloatArray  # (M, 2)


def _make_region(polygon: np.ndarray) -> _Region:
    """Reference (slow) path: convex hull, half-planes, centroid."""
    try:
        v = np.asarray(polygon, dtype=float)
    except (TypeError, ValueError):
        v = np.zeros((0, 2))
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3 or not np.isfinite(v).all():
        return _Region(False, np.zeros((0, 2)), np.zeros(0), np.zeros(2), np.zeros((0, 2)))
    hull = convex_hull(v)
    if len(hull) < 3 or polygon_area(hull) < MIN_POLYGON_AREA_M2:
        return _Region(False, np.zeros((0, 2)), np.zeros(0), np.zeros(2), hull)
    normals, offsets = polygon_halfplanes(hull)
    return _Region(True, normals, offsets, polygon_centroid(hull), hull)


@dataclass
class _SupportGeometry:
    """Half-planes and centroids of a call's support polygons, padded to ``V`` slots.

    Points are complex numbers ``x + iy``.  ``hull`` (S, V) vertices (padded with the
    first one), ``normals`` (S, V) unit outward normals (zero for padding and for an
    edge that continues the previous one), ``offsets`` (S, V) (+inf for those),
    ``centroids`` (S,).
    """

    hull: NDArray[np.complex128]
    normals: NDArray[np.complex128]
    offsets: FloatArray
    centroids: NDArray[np.complex128]


def _support_geometry(polygons: Sequence[object]) -> _SupportGeometry | None:
    """Geometry of all polygons at once; None if one is empty or degenerate.

    Convex polygons (either orientation, collinear vertices allowed) are processed
    vectorised; others (non-convex, repeated vertices, non-finite) are replaced by their
    convex hull first (reference path: :func:`_make_region`).
    """
    arrays: list[FloatArray] = []
    for poly in polygons:
        if type(poly) is np.ndarray and poly.dtype == np.float64 and poly.ndim == 2 and poly.shape[1] == 2:
            v = poly
        else:
            try:
                v = np.asarray(poly, dtype=float)
            except (TypeError, ValueError):
                return None
            if v.ndim != 2 or v.shape[1] != 2:
                return None
        if len(v) < 3:
            return None
        arrays.append(v)
    geom = _geometry_padded(arrays)
    bad = geom[-1]
    if bad.any():  # non-convex, repeated vertices or non-finite: use the hull (reference path)
        for k in np.flatnonzero(bad):
            region = _make_region(arrays[k])
            if not region.valid:
                return None
            arrays[k] = region.hull
        geom = _geometry_padded(arrays)
        if geom[-1].any():
            return None
    if not (geom[4] >= MIN_POLYGON_AREA_M2).all():
        return None
    return _SupportGeometry(*geom[:4])


#: Index arrays of the padded layout, per tuple of vertex counts (few distinct ones occur).
_PAD_LAYOUTS: dict[tuple[int, ...], tuple] = {}


def _pad_layout(lens: tuple[int, ...]) -> tuple:
    layout = _PAD_LAYOUTS.get(lens)
    if layout is None:
        n = np.array(lens)
        n_v = int(n.max())
        starts = np.cumsum(n) - n
        slot = np.arange(n_v)
        real = slot < n[:, None]
        nxt = np.where(slot + 1 < n[:, None], slot + 1, 0)  # next real vertex (padding: vertex 0)
        prv = np.where(slot > 0, slot - 1, n[:, None] - 1)  # previous edge (for real slots)
        row = np.arange(len(n))[:, None] * n_v
        idx = starts[:, None] + np.where(real, slot, 0)  # vertices, padded with vertex 0
        layout = (idx, starts[:, None] + nxt, row + prv, real)
        if len(_PAD_LAYOUTS) > 256:
            _PAD_LAYOUTS.clear()
        _PAD_LAYOUTS[lens] = layout
    return layout


def _geometry_padded(arrays: list[FloatArray]) -> tuple:
    """:func:`_geometry_padded_numpy` compiled (:func:`engine.control.mpc.kernels.geometry_padded`, the same
    numbers); the numpy code for non-finite vertices and polygons of more than 16 vertices."""
    lens = tuple(len(a) for a in arrays)
    n_v = max(lens)
    points = np.concatenate(arrays)
    if n_v > 16 or not np.isfinite(points).all():
        return _geometry_padded_numpy(arrays)
    idx, idx_next, _, _ = _pad_layout(lens)
    zf = points.view(np.complex128)[:, 0]
    hull, normals, offsets, centroids, area, bad = geometry_padded(
        points, np.array(lens, dtype=np.int64), n_v, np.abs(zf[idx_next] - zf[idx]))
    return (hull.view(np.complex128)[..., 0], normals.view(np.complex128)[..., 0], offsets,
            centroids.view(np.complex128)[:, 0], area, bad)


def _geometry_padded_numpy(arrays: list[FloatArray]) -> tuple:
    """Vectorised geometry of polygons (n_k, 2), with complex numbers ``x + iy``.

    Returns ``(hull (S, V), normals (S, V) complex, offsets (S, V), centroids (S,)
    complex, area (S,), not-convex mask (S,))``; vertices are padded with the first
    one, so padded edges have zero length (no half-plane, no area).
    """
    idx, idx_next, flat_prev, real = _pad_layout(tuple(len(a) for a in arrays))
    zf = np.concatenate(arrays).view(np.complex128)[:, 0]
    if not np.isfinite(zf).all():
        bad = np.array([not np.isfinite(a).all() for a in arrays])
        return None, None, None, None, None, bad
    z = zf[idx]
    zn = zf[idx_next]
    z0 = z[:, :1]
    w, wn = z - z0, zn - z0
    cross = (w.conj() * wn).imag  # shoelace terms about vertex 0 (padding: zero)
    area2 = cross.sum(axis=1)
    orient = np.where(area2 < 0.0, -1.0, 1.0)[:, None]
    edges = zn - z
    length = np.abs(edges)
    normals = edges * (-1j * orient) / np.maximum(length, 1e-300)  # outward: -i e (CCW), +i e (CW)
    # Convex: the outward normal turns the way of the orientation at every vertex (no
    # repeated vertex); an edge continuing the previous one (collinear vertex) repeats
    # its half-plane, which is dropped.
    rel = normals.ravel()[flat_prev].conj() * normals  # rotation from the previous edge's normal
    bad = ((length <= 1e-9) & real).any(axis=1) | (rel.imag * orient < -1e-9).any(axis=1)
    use = (length > 1e-9) & (rel.real < 1.0 - 1e-12)
    normals = np.where(use, normals, 0.0)
    offsets = np.where(use, (normals.conj() * z).real, np.inf)
    centroids = z0[:, 0] + ((w + wn) * cross).sum(axis=1) / (3.0 * np.where(area2 == 0.0, 1.0, area2))
    return z, normals, offsets, centroids, 0.5 * np.abs(area2), bad


def _support_geometry_xy(
    polygons: Sequence[object],
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, int] | None:
    """:func:`_support_geometry` as float arrays ``(hull (S, V, 2), normals (S, V, 2), offsets (S, V),
    centroids (S, 2))`` (the same numbers) and the most half-planes of one polygon; convex polygons of 3 to
    16 finite vertices go straight to the compiled kernel (what the controller passes), others through
    :func:`_support_geometry`."""
    points: FloatArray | None = None
    try:
        lens = [len(p) for p in polygons]  # type: ignore[arg-type]
        n_v = max(lens, default=0)
        if 3 <= min(lens, default=0) and n_v <= 16:
            points = np.concatenate(polygons)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        lens, n_v, points = [], 0, None
    if points is not None and points.dtype == np.float64 and points.ndim == 2 and points.shape[1] == 2:
        idx, idx_next, _, _ = _pad_layout(tuple(lens))
        zf = points.view(np.complex128)[:, 0]
        with np.errstate(invalid="ignore", over="ignore"):  # non-finite vertices: the kernel says so
            edge_length = np.abs(zf[idx_next] - zf[idx])
        status, hull, normals, offsets, centroids, max_h = support_geometry(
            points, np.array(lens, dtype=np.int64), n_v, edge_length, MIN_POLYGON_AREA_M2)
        if status == 0:
            return hull, normals, offsets, centroids, int(max_h)
        if status == 2:
            return None
    geom = _support_geometry(polygons)
    if geom is None:
        return None
    n_s, n_v = geom.offsets.shape
    max_h = int((geom.offsets < np.inf).sum(axis=1).max())
    return (geom.hull.view(np.float64).reshape(n_s, n_v, 2), geom.normals.view(np.float64).reshape(n_s, n_v, 2),
            geom.offsets, geom.centroids.view(np.float64).reshape(n_s, 2), max_h)


def _support_geometry_complex(hull: FloatArray, normals: FloatArray, offsets: FloatArray,
                              centroids: FloatArray) -> _SupportGeometry:
    """:class:`_SupportGeometry` (complex points) of :func:`_support_geometry_xy`'s float arrays."""
    return _SupportGeometry(hull.view(np.complex128)[..., 0], normals.view(np.complex128)[..., 0], offsets,
                            centroids.view(np.complex128)[:, 0])
