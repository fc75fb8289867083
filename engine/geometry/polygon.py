"""Planar convex polygons (support polygons, sole rectangles): hulls, area, centroid, half-planes,
clipping, point-in-polygon and projection into a polygon. The one polygon module of the engine."""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (monotone chain) of (N, 2) points; collinear points dropped.
    Compiled (:func:`_hull_compiled`); :func:`convex_hull_2d_numpy` is the reference it equals."""
    pts = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    if len(pts) <= 2:
        return convex_hull_2d_numpy(pts)
    return _hull_compiled(pts)


#: The monotone chain sorts by x, then by y; points whose x lie within this (m) of the first of their run sort as
#: one x, by y. Sorted by raw x, points on one vertical line whose x differ by rounding alone (soles side by side:
#: −0.09999999999999999 and −0.10000000000000002) come in an order along the line that is not theirs, and the
#: collinear test then drops an end of the line: two feet side by side gave a hexagon inside their rectangle
#: (tests/test_polygon_compiled.py). Runs, not a grid: a grid splits such x wherever a grid line falls between them.
SAME_X_M = 1e-12


def _chain_order(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """``points`` in the monotone chain's order: by x (runs within :data:`SAME_X_M` as one x), then y."""
    keyed = []
    run, run_x = -1, math.nan
    for p in sorted(points):
        if not p[0] - run_x <= SAME_X_M:  # (a NaN starts a run of its own)
            run, run_x = run + 1, p[0]
        keyed.append((run, p))
    return [p for _, p in sorted(keyed, key=lambda k: (k[0], k[1][1]))]


def convex_hull_2d_numpy(points: np.ndarray) -> np.ndarray:
    """The reference (plain Python) of :func:`convex_hull_2d`."""
    pts = _chain_order(list(map(tuple, np.asarray(points, dtype=float).tolist())))
    if len(pts) <= 2:
        return np.array(pts, dtype=float)
    lower: list = []
    for p in pts:
        while len(lower) >= 2 and ((lower[-1][0] - lower[-2][0]) * (p[1] - lower[-2][1])
                                   - (lower[-1][1] - lower[-2][1]) * (p[0] - lower[-2][0])) <= 1e-15:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and ((upper[-1][0] - upper[-2][0]) * (p[1] - upper[-2][1])
                                   - (upper[-1][1] - upper[-2][1]) * (p[0] - upper[-2][0])) <= 1e-15:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1], dtype=float)


@njit(cache=True, nogil=True)
def _hull_compiled(points):  # noqa: ANN001, ANN201
    """:func:`convex_hull_2d_numpy` for N ≥ 3 points: the same order (:func:`_chain_order`), turn test and
    tolerance."""
    n = points.shape[0]
    pts = points.copy()
    for i in range(1, n):  # insertion sort by (x, y): the order of Python's sorted() on tuples
        x, y = pts[i, 0], pts[i, 1]
        j = i - 1
        while j >= 0 and (pts[j, 0] > x or (pts[j, 0] == x and pts[j, 1] > y)):
            pts[j + 1, 0], pts[j + 1, 1] = pts[j, 0], pts[j, 1]
            j -= 1
        pts[j + 1, 0], pts[j + 1, 1] = x, y
    runs = np.empty(n)  # each point's run of x within SAME_X_M of its first
    run, run_x = -1.0, np.nan
    for i in range(n):
        if not pts[i, 0] - run_x <= SAME_X_M:
            run, run_x = run + 1.0, pts[i, 0]
        runs[i] = run
    for i in range(1, n):  # stable insertion sort by (run, y)
        x, y, r = pts[i, 0], pts[i, 1], runs[i]
        j = i - 1
        while j >= 0 and (runs[j] > r or (runs[j] == r and pts[j, 1] > y)):
            pts[j + 1, 0], pts[j + 1, 1], runs[j + 1] = pts[j, 0], pts[j, 1], runs[j]
            j -= 1
        pts[j + 1, 0], pts[j + 1, 1], runs[j + 1] = x, y, r
    lower = np.empty((n, 2))
    k = 0
    for i in range(n):
        px, py = pts[i, 0], pts[i, 1]
        while k >= 2 and ((lower[k - 1, 0] - lower[k - 2, 0]) * (py - lower[k - 2, 1])
                          - (lower[k - 1, 1] - lower[k - 2, 1]) * (px - lower[k - 2, 0])) <= 1e-15:
            k -= 1
        lower[k, 0], lower[k, 1] = px, py
        k += 1
    upper = np.empty((n, 2))
    m = 0
    for i in range(n - 1, -1, -1):
        px, py = pts[i, 0], pts[i, 1]
        while m >= 2 and ((upper[m - 1, 0] - upper[m - 2, 0]) * (py - upper[m - 2, 1])
                          - (upper[m - 1, 1] - upper[m - 2, 1]) * (px - upper[m - 2, 0])) <= 1e-15:
            m -= 1
        upper[m, 0], upper[m, 1] = px, py
        m += 1
    out = np.empty((k - 1 + m - 1, 2))
    out[:k - 1] = lower[:k - 1]
    out[k - 1:] = upper[:m - 1]
    return out


def polygon_area(polygon: ArrayLike) -> float:
    """Signed area [m^2] of a polygon (positive when counter-clockwise)."""
    v = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(v) < 3:
        return 0.0
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def polygon_centroid(polygon: ArrayLike) -> FloatArray:
    """Area centroid [m] of a simple polygon; vertex mean for degenerate (zero-area) input, NaN if empty."""
    v = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(v) == 0:
        return np.full(2, np.nan)
    if len(v) < 3:
        return v.mean(axis=0)
    origin = v.mean(axis=0)
    w = v - origin
    x, y = w[:, 0], w[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    area2 = float(cross.sum())
    if abs(area2) < 1e-14:
        return origin
    cx = float(np.dot(x + xn, cross)) / (3.0 * area2)
    cy = float(np.dot(y + yn, cross)) / (3.0 * area2)
    return origin + np.array([cx, cy])


def convex_hull(points: ArrayLike) -> FloatArray:
    """Counter-clockwise convex hull (Andrew's monotone chain) without collinear points."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    pts = np.unique(pts, axis=0)  # lexicographically sorted
    if len(pts) < 3:
        return pts

    def cross(o: FloatArray, a: FloatArray, b: FloatArray) -> float:
        return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))

    lower: list[FloatArray] = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-15:
            lower.pop()
        lower.append(p)
    upper: list[FloatArray] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-15:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def polygon_halfplanes(polygon: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Half-planes ``A x <= b`` (unit outward normals ``A`` (H, 2), offsets ``b`` (H,) [m]).

    ``polygon`` must be convex; it may be given in either orientation.  Edges shorter
    than 1e-9 m are skipped.
    """
    v = np.asarray(polygon, dtype=float).reshape(-1, 2)
    if len(v) < 3:
        return np.zeros((0, 2)), np.zeros(0)
    if polygon_area(v) < 0.0:
        v = v[::-1]
    edges = np.roll(v, -1, axis=0) - v
    length = np.hypot(edges[:, 0], edges[:, 1])
    keep = length > 1e-9
    normals = np.stack([edges[keep, 1], -edges[keep, 0]], axis=1) / length[keep, None]
    offsets = np.einsum("ij,ij->i", normals, v[keep])
    return normals, offsets


def outside_distance_m(point_xy: ArrayLike, polygon: ArrayLike) -> float:
    """How far ``point_xy`` lies outside the convex ``polygon`` (the largest half-plane violation; ≤ 0 inside; a
    polygon of fewer than three vertices: the distance to their mean). The half-planes come from
    :func:`halfplanes_cached`: support polygons recur tick after tick."""
    normals, offsets, _ = halfplanes_cached(polygon)
    if len(offsets) == 0:
        return float(np.linalg.norm(np.asarray(point_xy) - np.asarray(polygon).reshape(-1, 2).mean(axis=0)))
    return float(np.max(normals @ np.asarray(point_xy, dtype=float) - offsets))


#: Half-planes of recently seen polygons, by value (support polygons recur tick after tick).
_HALFPLANE_CACHE: dict[tuple, tuple[FloatArray, FloatArray, FloatArray]] = {}
_HALFPLANE_CACHE_SIZE = 64


def halfplanes_cached(polygon: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`polygon_halfplanes` ``(normals, offsets)`` and ``offsets + 1e-9``, kept by the polygon's
    values (the same numbers as computing them; the arrays are shared: read-only)."""
    v = np.asarray(polygon, dtype=float)
    key = (v.shape, v.tobytes())
    hit = _HALFPLANE_CACHE.get(key)
    if hit is None:
        if len(_HALFPLANE_CACHE) >= _HALFPLANE_CACHE_SIZE:
            _HALFPLANE_CACHE.clear()
        normals, offsets = polygon_halfplanes(v)
        hit = (normals, offsets, offsets + 1e-9)
        for a in hit:
            a.flags.writeable = False
        _HALFPLANE_CACHE[key] = hit
    return hit


def clip_convex_polygons(subject: ArrayLike, clip: ArrayLike, tol_m: float = 1e-9) -> FloatArray:
    """Intersection of two convex polygons (Sutherland-Hodgman); (0, 2) if empty.

    Touching polygons yield a degenerate (zero-area) intersection, which is returned.
    """
    out = np.asarray(subject, dtype=float).reshape(-1, 2)
    if polygon_area(out) < 0.0:
        out = out[::-1]
    normals, offsets = polygon_halfplanes(clip)
    if len(normals) == 0:
        return np.zeros((0, 2))
    for normal, offset in zip(normals, offsets):
        if len(out) == 0:
            break
        d = out @ normal - offset
        inside = d <= tol_m
        if inside.all():
            continue
        nxt_pts = np.roll(out, -1, axis=0)
        nxt_d = np.roll(d, -1)
        nxt_in = np.roll(inside, -1)
        new_pts: list[FloatArray] = []
        for i in range(len(out)):
            if inside[i]:
                new_pts.append(out[i])
            if inside[i] != nxt_in[i]:
                lam = d[i] / (d[i] - nxt_d[i])
                new_pts.append(out[i] + lam * (nxt_pts[i] - out[i]))
        out = np.array(new_pts).reshape(-1, 2)
    return out


#: Tolerance of the containment test between consecutive supports [m].


def point_in_polygon(p: np.ndarray, poly: np.ndarray, margin: float) -> bool:
    """``p`` inside the counter-clockwise convex ``poly`` or within ``margin`` of it (a segment or a
    point for degenerate supports)."""
    if len(poly) < 3:
        if len(poly) == 2:  # a line contact: distance to the segment
            a, b = poly
            d = b - a
            s = np.clip(np.dot(p - a, d) / max(np.dot(d, d), 1e-12), 0, 1)
            return float(np.linalg.norm(p - (a + s * d))) <= margin
        return len(poly) == 1 and float(np.linalg.norm(p - poly[0])) <= margin
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        edge = b - a
        cross = edge[0] * (p[1] - a[1]) - edge[1] * (p[0] - a[0])
        if cross < -margin * float(np.linalg.norm(edge)):
            return False
    return True


def clip_into_polygon(p: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """``p`` if inside the convex polygon, else its centroid-ward projection onto it: the point
    c + s (p − c) with s the largest multiple of 2⁻³⁰ inside (what a 30-step bisection on the
    segment finds), computed from the half-planes directly."""
    normals, offsets, bound = halfplanes_cached(polygon)
    # np.all's answer on the list of flags (without ndarray.all's Python layer and reduction; NaN compares False)
    if len(offsets) == 0 or all((normals @ p <= bound).tolist()):
        return p
    c = polygon_centroid(polygon)
    d = p - c
    den, num = normals @ d, bound - normals @ c
    with np.errstate(divide="ignore", invalid="ignore"):
        s_max = float(np.min(np.where(den > 0.0, num / den, np.inf), initial=1.0))
    unit = 2.0 ** -30
    k = min(max(math.floor(s_max / unit), 0), 2 ** 30 - 1)

    def inside(j: int) -> bool:
        return all((normals @ (c + (j * unit) * d) <= bound).tolist())

    while k > 0 and not inside(k):  # rounding at the boundary: step to the dyadic the bisection ends on
        k -= 1
    while k + 1 < 2 ** 30 and inside(k + 1):
        k += 1
    return c + (k * unit) * d
