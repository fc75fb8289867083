"""The gait planner's compiled (numba) kernels: the command ramp and the path table's poses, the blended
channels, and the contact preview (its intervals, predicted footholds and support polygons: one sole's corners,
or the convex hull of two soles, each whole or cut to the strip along its heel or toe edge: a foot rolling on
that edge).

Each computes what the Python code it replaced computed, with the same expressions in the same order (the same
numbers: ``tests/control/test_stack_speed_references.py`` keeps the replaced code as references). The preview
was the bulk of a planner tick: its footholds move with the path every tick, so nothing of it can be kept from
one tick to the next, and one compiled call replaces ~10 intervals of small Python and numpy steps.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.extending import intrinsic

from engine.geometry.polygon import _hull_compiled

#: Edge codes of :func:`support_hull`: the whole sole, the heel strip, the toe strip.
EDGE_CODES = {None: 0, "heel": 1, "toe": 2}


def support_hull(holds: tuple, length_m: float, width_m: float, edges: tuple, strip_depth_m: float) -> np.ndarray:
    """Counter-clockwise hull (M, 2) of the soles (``length_m`` × ``width_m``) on ``holds`` (Footholds),
    the one of ``edges[i]`` ("heel", "toe" or None) cut to its ``strip_depth_m`` strip."""
    n = len(holds)
    poses = np.empty((n, 3))
    codes = np.empty(n, dtype=np.int64)
    for i, (h, e) in enumerate(zip(holds, edges)):
        poses[i, 0], poses[i, 1], poses[i, 2] = h.x, h.y, h.yaw
        codes[i] = EDGE_CODES[e]
    return _support_hull_compiled(poses, float(length_m), float(width_m), codes, float(strip_depth_m))


@njit(cache=True, nogil=True)
def _sole_points(pts, k, x0, y0, yaw, length_m, width_m, front_trim_m, code, strip_share):  # noqa: ANN001, ANN201, PLR0913
    """Rows k..k+3 of ``pts``: the corners of the sole on (x0, y0, yaw) as :meth:`Foothold.corners` computes them
    (back-left, back-right, front-right, front-left; ``front_trim_m`` cut at the toe), or its heel (code 1) or toe
    (code 2) strip, ``strip_share`` of the length deep (the planner's edge strips)."""
    c, s = math.cos(yaw), math.sin(yaw)
    trim = min(max(front_trim_m, 0.0), 0.9 * length_m)
    hl, hw = 0.5 * (length_m - trim), 0.5 * width_m
    x, y = x0 - c * 0.5 * trim, y0 - s * 0.5 * trim
    blx, bly = x - c * hl - s * hw, y - s * hl + c * hw
    brx, bry = x - c * hl + s * hw, y - s * hl - c * hw
    frx, fry = x + c * hl + s * hw, y + s * hl - c * hw
    flx, fly = x + c * hl - s * hw, y + s * hl + c * hw
    f = strip_share
    if code == 1:  # heel strip: bl, br, br + f (fr − br), bl + f (fl − bl)
        pts[k, 0], pts[k, 1] = blx, bly
        pts[k + 1, 0], pts[k + 1, 1] = brx, bry
        pts[k + 2, 0], pts[k + 2, 1] = brx + f * (frx - brx), bry + f * (fry - bry)
        pts[k + 3, 0], pts[k + 3, 1] = blx + f * (flx - blx), bly + f * (fly - bly)
    elif code == 2:  # toe strip: fl + f (bl − fl), fr + f (br − fr), fr, fl
        pts[k, 0], pts[k, 1] = flx + f * (blx - flx), fly + f * (bly - fly)
        pts[k + 1, 0], pts[k + 1, 1] = frx + f * (brx - frx), fry + f * (bry - fry)
        pts[k + 2, 0], pts[k + 2, 1] = frx, fry
        pts[k + 3, 0], pts[k + 3, 1] = flx, fly
    else:
        pts[k, 0], pts[k, 1] = blx, bly
        pts[k + 1, 0], pts[k + 1, 1] = brx, bry
        pts[k + 2, 0], pts[k + 2, 1] = frx, fry
        pts[k + 3, 0], pts[k + 3, 1] = flx, fly


@njit(cache=True, nogil=True)
def _support_hull_compiled(poses, length_m, width_m, codes, strip_depth_m):  # noqa: ANN001, ANN201
    n = poses.shape[0]
    pts = np.empty((4 * n, 2))
    f = min(strip_depth_m / max(length_m, 1e-9), 1.0)
    for i in range(n):  # Foothold.corners(length_m, width_m) (front trim 0), whole or cut to a strip
        _sole_points(pts, 4 * i, poses[i, 0], poses[i, 1], poses[i, 2], length_m, width_m, 0.0, codes[i], f)
    return _hull_compiled(pts)


@njit(cache=True, nogil=True)
def preview_polygons(poses, down, codes, length_m, width_m, front_trim_m, strip_depth_m):  # noqa: ANN001, ANN201, PLR0913
    """The support polygons of a contact preview in one call: interval i stands on the feet j with ``down[i, j]``
    at ``poses[i, j]`` (x, y, yaw). One foot: its sole's corners (:meth:`Foothold.corners` with ``front_trim_m``);
    both: :func:`support_hull` of the two soles (edge ``codes[i, j]``: 0 whole, 1 heel strip, 2 toe strip).
    Returns the polygons padded to (n, 8, 2) and their vertex counts (n,)."""
    n = poses.shape[0]
    out = np.zeros((n, 8, 2))
    counts = np.empty(n, dtype=np.int64)
    f = min(strip_depth_m / max(length_m, 1e-9), 1.0)
    pts = np.empty((8, 2))
    for i in range(n):
        if down[i, 0] and down[i, 1]:
            for j in range(2):
                _sole_points(pts, 4 * j, poses[i, j, 0], poses[i, j, 1], poses[i, j, 2], length_m, width_m, 0.0,
                             codes[i, j], f)
            hull = _hull_compiled(pts)
            m = hull.shape[0]
            out[i, :m] = hull
            counts[i] = m
        else:
            j = 0 if down[i, 0] else 1
            _sole_points(out[i], 0, poses[i, j, 0], poses[i, j, 1], poses[i, j, 2], length_m, width_m, front_trim_m,
                         0, f)
            counts[i] = 4
    return out, counts


@njit(cache=True, nogil=True)
def command_ramp_pieces(command, goal, rate_limits, step_s, n):  # noqa: ANN001, ANN201
    """The path table's velocity part (``planner._command_ramp``): the mean velocity of each of the ``n`` pieces
    (n, 3) of the rate-limited ramp toward ``goal`` (per axis v ← v + clip(goal − v, ±|limit|·step), each piece
    at v + dv/2, the goal held once reached), and each piece's turn angle and exact arc (dx, dy) in its
    start frame (``path_frame.arc_displacement``'s expressions, elementwise as the numpy code computed them)."""
    vels = np.empty((n, 3))
    for j in range(3):
        g, lim, v = goal[j], abs(rate_limits[j]) * step_s, command[j]
        for i in range(n):
            dv = min(max(g - v, -lim), lim)
            vels[i, j] = v + 0.5 * dv  # the piece's mean velocity
            if dv == 0.0:
                for k in range(i + 1, n):
                    vels[k, j] = v
                break
            v = v + dv
    th = np.empty(n)
    dx = np.empty(n)
    dy = np.empty(n)
    h = step_s
    for i in range(n):
        w = vels[i, 2]
        t = w * h
        th[i] = t
        if abs(t) < 1e-9:
            sinc, cosc = h * (1.0 - t * t / 6.0), h * (0.5 * t)
        else:
            sinc, cosc = math.sin(t) / w, (1.0 - math.cos(t)) / w
        dx[i] = vels[i, 0] * sinc - vels[i, 1] * cosc
        dy[i] = vels[i, 0] * cosc + vels[i, 1] * sinc
    return vels, th, dx, dy


@njit(cache=True, nogil=True)
def path_table_poses(x, y, yaw, th, dx, dy):  # noqa: ANN001, ANN201
    """The planner's path table poses (n, 3) from the start pose and the pieces' turn angles and arcs
    (``GaitPlanner._build_path_table``'s numpy cumsums, in their order: the same numbers)."""
    n = th.shape[0]
    poses = np.empty((n, 3))
    poses[0, 0], poses[0, 1], poses[0, 2] = x, y, yaw
    acc_th, acc_x, acc_y = 0.0, 0.0, 0.0
    for i in range(1, n):
        acc_th = th[0] if i == 1 else acc_th + th[i - 1]
        poses[i, 2] = acc_th
    for i in range(1, n):
        poses[i, 2] += yaw
    for i in range(1, n):
        c, s = math.cos(poses[i - 1, 2]), math.sin(poses[i - 1, 2])
        ddx = c * dx[i - 1] - s * dy[i - 1]
        ddy = s * dx[i - 1] + c * dy[i - 1]
        acc_x = ddx if i == 1 else acc_x + ddx
        acc_y = ddy if i == 1 else acc_y + ddy
        poses[i, 0], poses[i, 1] = acc_x + x, acc_y + y
    return poses


@njit(cache=True, nogil=True)
def path_table(x, y, yaw, command, goal, rate_limits, step_s, n):  # noqa: ANN001, ANN201, PLR0913
    """The planner's path table in one call: the poses (n, 3) from (x, y, yaw) along the rate-limited ramp from
    ``command`` toward ``goal`` (:func:`command_ramp_pieces`, :func:`path_table_poses`) and the pieces' mean
    velocities (n, 3)."""
    vels, th, dx, dy = command_ramp_pieces(command, goal, rate_limits, step_s, n)
    return path_table_poses(x, y, yaw, th, dx, dy), vels


@njit(cache=True, nogil=True)
def merged_bank_rows(member_times, member_rate_scale, member_of_row, offset, periodic, period, hi, search, t0, coef):  # noqa: ANN001, ANN201, PLR0913
    """``MergedBank.evaluate``'s values and d/dt of every row (its numpy code, the same numbers: numpy's
    float remainder for periodic rows, its clip otherwise, then the Horner cubic of the row's segment)."""
    n_rows = offset.shape[0]
    values = np.empty(n_rows)
    rates = np.empty(n_rows)
    for r in range(n_rows):
        t = member_times[member_of_row[r]] - offset[r]
        if periodic[r]:
            t = t % period[r]  # Python's float remainder: numpy's (fmod, then the divisor's sign)
        else:
            t = min(max(t, 0.0), hi[r])
        idx = -1
        for j in range(search.shape[1]):
            if search[r, j] <= t:
                idx += 1
        tau = t - t0[r, idx]
        c0, c1, c2, c3 = coef[r, idx, 0], coef[r, idx, 1], coef[r, idx, 2], coef[r, idx, 3]
        values[r] = c0 + tau * (c1 + tau * (c2 + tau * c3))
        rates[r] = (c1 + tau * (2.0 * c2 + 3.0 * c3 * tau)) * member_rate_scale[member_of_row[r]]
    return values, rates


@njit(cache=True, nogil=True)
def _phase_segment(waypoints, p):  # noqa: ANN001, ANN202
    """bisect_right(waypoints, p) − 1: the phase map's segment of phase p."""
    j = -1
    for w in waypoints:
        if w <= p:
            j += 1
    return j


@njit(cache=True, nogil=True)
def merged_bank_at_phase(f, dphi_dt, waypoints, segments, cycles, member_of_row, offset, periodic, period, hi,  # noqa: ANN001, ANN201, PLR0913
                         search, t0, coef):
    """BlendedGait.channels' member times and rate scales and :func:`merged_bank_rows` in one call: each member's
    time Ωᵢ(f) (PhaseMap.time_at on a float) and dΩᵢ/dφ(f) · ``dphi_dt`` (PhaseMap.dtime_dphase), from its phase
    map's ``segments`` (members, 4, 5: the segment's phase, then the cubic's coefficients c0..c3, PhaseMap._seg) and
    ``cycles``; their expressions (the same numbers)."""
    m = segments.shape[0]
    times = np.empty(m)
    scale = np.empty(m)
    for i in range(m):
        p, k = f, 0.0
        if not 0.0 <= p < 1.0:
            k = math.floor(p)
            p -= k
            if p >= 1.0:
                p, k = 0.0, k + 1.0
        j = _phase_segment(waypoints, p)
        s = p - segments[i, j, 0]
        t = segments[i, j, 1] + s * (segments[i, j, 2] + s * (segments[i, j, 3] + s * segments[i, j, 4]))
        times[i] = t + k * cycles[i] if k != 0.0 else t
        q = f % 1.0
        if q >= 1.0:
            q = 0.0
        j = _phase_segment(waypoints, q)
        s = q - segments[i, j, 0]
        scale[i] = (segments[i, j, 2] + s * (2.0 * segments[i, j, 3] + 3.0 * s * segments[i, j, 4])) * dphi_dt
    return merged_bank_rows(times, scale, member_of_row, offset, periodic, period, hi, search, t0, coef)


# ---------------------------------------------------------------------------------------------------- the preview
# GaitPlanner.preview's loop compiled. Python's float semantics are kept where they could differ from LLVM's: min
# and max keep their first argument on ties, squares go through libm's pow (Python's x ** 2 is pow(x, 2.0), which
# differs from x * x in the last bit for ~0.1 % of x; a literal exponent would let LLVM fold it into x * x).

#: GaitPlanner.preview's contact events in a cycle: LLO, LTD, RLO, RTD (phases; SWING_PHASES' liftoff / touchdown).
PREVIEW_EVENT_PHASES = np.array([0.0, 0.1, 0.5, 0.6])
MAX_PREVIEW_INTERVALS = 16  # four cycles of four events


@njit(cache=True, nogil=True)
def _first_max(a, b):  # noqa: ANN001, ANN202
    """Python's max(a, b): a unless b > a."""
    return b if b > a else a


@njit(cache=True, nogil=True)
def _first_min(a, b):  # noqa: ANN001, ANN202
    """Python's min(a, b): a unless b < a."""
    return b if b < a else a


@njit(cache=True, nogil=True)
def _event_time(phi_event, events):  # noqa: ANN001, ANN202
    """BlendedGait.event_time on its events (t_LTD, t_RLO, t_RTD, cycle)."""
    k = math.floor(phi_event + 1e-9)
    f = phi_event - k
    if f < 0.05:
        t = 0.0
    elif f < 0.3:
        t = events[0]
    elif f < 0.55:
        t = events[1]
    else:
        t = events[2]
    return k * events[3] + t


@njit(cache=True, nogil=True)
def _at_event(phi, event_phi):  # noqa: ANN001, ANN202
    d = phi - event_phi
    return abs(d - round(d)) < 1e-9


@njit(cache=True, nogil=True)
def _predicted_foothold(side, phi_td, t_now, events, support, stance, table_times, table_poses, table_vels,  # noqa: ANN001, ANN202, PLR0913
                        table_step_s, region, two, out):
    """GaitPlanner._predicted_foothold into ``out`` (x, y, yaw): the path pose at the middle of the contact that
    starts at ``phi_td`` (path_ahead: the table's piece, then its arc), ⊕ the stance offset (foothold_from_path),
    projected to the safe region beside ``support`` (footsteps.project_to_safe_region)."""
    _adjusted_foothold(side, phi_td, t_now, events, support, stance, table_times, table_poses, table_vels,
                       table_step_s, region, two, 0.0, 0.0, out)


@njit(cache=True, nogil=True)
def upcoming_foothold(side, phi, t_now, events, support_x, support_y, support_yaw, stances, table_times,  # noqa: ANN001, ANN201, PLR0913
                      table_poses, table_vels, table_step_s, region, two, adjust_x, adjust_y):
    """GaitPlanner._upcoming_foothold as (x, y, yaw): the foothold of the contact after the current or next swing of
    ``side`` (0 left, 1 right; its stance offset ``stances[side]``) at phase ``phi`` (gait time ``t_now``), moved by
    the step adjustment (``adjust_x``, ``adjust_y``; added only when one is non-zero, as there) before the
    safe-region projection beside the other foot (``support_*``). Floats in and out: an array argument or result
    costs the call more than the arithmetic."""
    lo = PREVIEW_EVENT_PHASES[0] if side == 0 else PREVIEW_EVENT_PHASES[2]
    td = PREVIEW_EVENT_PHASES[1] if side == 0 else PREVIEW_EVENT_PHASES[3]
    support = np.empty(3)
    support[0], support[1], support[2] = support_x, support_y, support_yaw
    out = np.empty(3)
    _adjusted_foothold(side, math.floor(phi - lo) + td, t_now, events, support, stances[side], table_times,
                       table_poses, table_vels, table_step_s, region, two, adjust_x, adjust_y, out)
    return out[0], out[1], out[2]


@njit(cache=True, nogil=True)
def _adjusted_foothold(side, phi_td, t_now, events, support, stance, table_times, table_poses, table_vels,  # noqa: ANN001, ANN202, PLR0913
                       table_step_s, region, two, adjust_x, adjust_y, out):
    """:func:`_predicted_foothold` with the step adjustment added to the target before its projection (when
    ``adjust_x`` or ``adjust_y`` is non-zero: x + 0.0 would turn a −0.0 into 0.0)."""
    lo = PREVIEW_EVENT_PHASES[0] if side == 0 else PREVIEW_EVENT_PHASES[2]
    phi_next_lo = math.floor(phi_td - lo) + 1 + lo
    t_mid = 0.5 * (_event_time(phi_td, events) + _event_time(phi_next_lo, events))
    dt = _first_max(t_mid - t_now, 0.0)
    k = min(int(dt / table_step_s), table_times.shape[0] - 1)
    x0, y0, yaw0 = table_poses[k, 0], table_poses[k, 1], table_poses[k, 2]
    vx, vy, w = table_vels[k, 0], table_vels[k, 1], table_vels[k, 2]
    ds = dt - table_times[k]
    th = w * ds  # path_frame.arc_displacement
    if abs(th) < 1e-9:
        sinc, cosc = ds * (1.0 - th * th / 6.0), ds * (0.5 * th)
    else:
        sinc, cosc = math.sin(th) / w, (1.0 - math.cos(th)) / w
    dx = vx * sinc - vy * cosc
    dy = vx * cosc + vy * sinc
    c, s = math.cos(yaw0), math.sin(yaw0)  # path_frame.predict_xy_yaw
    px, py, pyaw = x0 + c * dx - s * dy, y0 + s * dx + c * dy, yaw0 + th
    c, s = math.cos(pyaw), math.sin(pyaw)  # foothold_from_path
    tx, ty, tyaw = px + c * stance[0] - s * stance[1], py + s * stance[0] + c * stance[1], pyaw + stance[2]
    if adjust_x != 0.0 or adjust_y != 0.0:
        tx, ty = tx + adjust_x, ty + adjust_y
    # project_to_safe_region
    sx, sy, syaw = support[0], support[1], support[2]
    c, s = math.cos(syaw), math.sin(syaw)
    dx, dy = tx - sx, ty - sy
    local_yaw = ((tyaw - syaw) + math.pi) % (2 * math.pi) - math.pi  # wrap_angle
    sign = 1.0 if side == 0 else -1.0
    x, y_own = c * dx + s * dy, sign * (-s * dx + c * dy)
    side_m, front_m, cross_m, max_yaw = region[0], region[1], region[2], region[3]
    bx, by = x, _first_max(y_own, side_m)  # beside
    best_d2 = (bx - x) ** two + (by - y_own) ** two
    cx, cy = _first_max(x, front_m), _first_max(y_own, cross_m)  # in front (still not crossing)
    d2 = (cx - x) ** two + (cy - y_own) ** two
    if d2 < best_d2:
        bx, by, best_d2 = cx, cy, d2
    cx, cy = _first_min(x, -front_m), _first_max(y_own, cross_m)  # behind
    d2 = (cx - x) ** two + (cy - y_own) ** two
    if d2 < best_d2:
        bx, by, best_d2 = cx, cy, d2
    yaw = _first_min(_first_max(local_yaw, -max_yaw), max_yaw)
    if bx == x and by == y_own and yaw == local_yaw:
        out[0], out[1], out[2] = tx, ty, tyaw
    else:  # support.from_local((best x, sign · best y, yaw))
        ly = sign * by
        out[0], out[1], out[2] = sx + c * bx - s * ly, sy + s * bx + c * ly, syaw + yaw


@njit(cache=True, nogil=True)
def _rolling_edge(side, phi_start, phi_end, phi, edge_now, landed, touchdown_edge, liftoff_edge):  # noqa: ANN001, ANN202, PLR0913
    """GaitPlanner._rolling_edge as an edge code: ``edge_now`` is the code of the foot's pitch now (−1: no last
    pose), ``touchdown_edge`` / ``liftoff_edge`` those of the blend's boundary pitches."""
    lo = PREVIEW_EVENT_PHASES[0] if side == 0 else PREVIEW_EVENT_PHASES[2]
    td = PREVIEW_EVENT_PHASES[1] if side == 0 else PREVIEW_EVENT_PHASES[3]
    if phi_start == phi and edge_now[side] >= 0:
        if edge_now[side] != 0:
            return edge_now[side]
    elif landed[side] and _at_event(phi_start, td):
        if touchdown_edge[side] != 0:
            return touchdown_edge[side]
    if _at_event(phi_end, lo):
        return liftoff_edge[side]
    return 0


@njit(cache=True, nogil=True)
def preview_intervals(phi, t_now, kappa, hold_s, horizon_s, events, holds, swinging, edge_now, landed,  # noqa: ANN001, ANN201, PLR0913, PLR0915
                      touchdown_edge, liftoff_edge, stances, table_times, table_poses, table_vels, table_step_s,
                      region, length_m, width_m, front_trim_m, strip_depth_m, two):
    """GaitPlanner.preview's support intervals: from phase ``phi`` (gait time ``t_now``) over the contact events
    of the next four cycles (``events``: t_LTD, t_RLO, t_RTD, cycle) until one ends ``horizon_s`` ahead.

    The feet start on ``holds`` (2, 3) (a swinging foot's on its target, ``swinging``); a foot that touches down
    later lands on its predicted foothold (``stances`` (2, 3), the path table, the safe ``region`` (side, front,
    cross, max yaw)). Returns, for the n intervals, their start and end [s from now] (n, 2); per interval the
    feet down (left, right: 0/1), the foothold index per foot (0, 1: ``holds``, 2…: the predicted ones) and the
    polygon's vertex count (n, 5); the footholds (m, 3); the polygons (n, 8, 2) (:func:`preview_polygons`). Few
    arrays: each one returned costs the call about a microsecond."""
    t_start = np.empty(MAX_PREVIEW_INTERVALS)
    t_end = np.empty(MAX_PREVIEW_INTERVALS)
    down = np.zeros((MAX_PREVIEW_INTERVALS, 2), dtype=np.bool_)
    hold_index = np.zeros((MAX_PREVIEW_INTERVALS, 2), dtype=np.int64)
    codes = np.zeros((MAX_PREVIEW_INTERVALS, 2), dtype=np.int64)
    poses = np.zeros((MAX_PREVIEW_INTERVALS, 2, 3))
    footholds = np.empty((2 + MAX_PREVIEW_INTERVALS, 3))
    footholds[:2] = holds
    n_holds = 2
    current = np.array([0, 1])
    still_swinging = swinging.copy()
    k = math.floor(phi)
    prev_phi, t0 = phi, 0.0
    n = 0
    done = False
    for cycle_index in range(k, k + 4):
        for event in range(4):
            b = cycle_index + PREVIEW_EVENT_PHASES[event]
            if not b > phi:
                continue
            t1 = (cycle_index * events[3] + (0.0 if event == 0 else events[event - 1]) - t_now) / kappa + hold_s
            mid = 0.5 * (prev_phi + b)
            f = mid - math.floor(mid)
            left_down = not (PREVIEW_EVENT_PHASES[0] <= f < PREVIEW_EVENT_PHASES[1])  # GaitPlanner.in_swing
            right_down = not (PREVIEW_EVENT_PHASES[2] <= f < PREVIEW_EVENT_PHASES[3])
            t_start[n], t_end[n] = t0, t1
            down[n, 0], down[n, 1] = left_down, right_down
            for side in range(2):
                hold_index[n, side] = current[side]
                poses[n, side] = footholds[current[side]]
                if left_down and right_down:
                    codes[n, side] = _rolling_edge(side, prev_phi, b, phi, edge_now, landed, touchdown_edge,
                                                   liftoff_edge)
            n += 1
            if t1 >= horizon_s:
                done = True
                break
            if event == 1 or event == 3:  # the left (LTD) / right (RTD) foot touches down at b
                side = 0 if event == 1 else 1
                if still_swinging[side]:
                    still_swinging[side] = False
                else:
                    _predicted_foothold(side, b, t_now, events, footholds[current[1 - side]], stances[side],
                                        table_times, table_poses, table_vels, table_step_s, region, two,
                                        footholds[n_holds])
                    current[side] = n_holds
                    n_holds += 1
            prev_phi, t0 = b, t1
        if done:
            break
    polygons, counts = preview_polygons(poses[:n], down[:n], codes[:n], length_m, width_m, front_trim_m,
                                        strip_depth_m)
    times = np.empty((n, 2))
    rows = np.empty((n, 5), dtype=np.int64)
    for i in range(n):
        times[i, 0], times[i, 1] = t_start[i], t_end[i]
        rows[i, 0], rows[i, 1] = down[i, 0], down[i, 1]
        rows[i, 2], rows[i, 3], rows[i, 4] = hold_index[i, 0], hold_index[i, 1], counts[i]
    return times, rows, footholds[:n_holds], polygons


@njit(cache=True, nogil=True)
def pack_supports(t_s, times, rows, polygons):  # noqa: ANN001, ANN201
    """The CoM MPC's packed supports of :func:`preview_intervals`' intervals (what
    :meth:`engine.control.mpc.ComMpc.solve` otherwise builds from the contact phases): per interval its start and
    end in absolute time ``t_s +`` (the contact phases' float sums) and its vertex count (n, 3), and the polygons'
    vertices one after the other (Σ counts, 2), as ``np.concatenate`` of the phases' polygons."""
    n = times.shape[0]
    table = np.empty((n, 3))
    total = 0
    for i in range(n):
        table[i, 0], table[i, 1], table[i, 2] = t_s + times[i, 0], t_s + times[i, 1], float(rows[i, 4])
        total += rows[i, 4]
    points = np.empty((total, 2))
    r = 0
    for i in range(n):
        for j in range(rows[i, 4]):
            points[r, 0], points[r, 1] = polygons[i, j, 0], polygons[i, j, 1]
            r += 1
    return table, points


# ------------------------------------------------------------------------------------------ the reference's frames
#: Layout of :func:`reference_frames_into`'s ``params``: the path yaw, the pelvis yaw/pitch/roll curves, the sole's
#: length and width, heel_toe.ROLL_SMOOTHING and its square (Python's ** 2), then per foot (left, right)
#: FOOT_PARAMS values from FOOT_PARAMS_AT.
FOOT_PARAMS_AT = 8
FOOT_PARAMS = 11  # mode, x, y, yaw, rig yaw, heel pitch, toe pitch, roll, offset x, y, z
#: Foot modes: swinging (the nominal swing ⊕ the style's rig and offset), standing rolled (the heel/toe rig about
#: the latched foothold), standing flat.
FOOT_SWING, FOOT_ROLLED, FOOT_FLAT = 0.0, 1.0, 2.0


@intrinsic
def fused_multiply_add(typingctx, a, b, c):  # noqa: ANN001, ANN201, ARG001
    """a · b + c rounded once (LLVM's fma: the FMA instruction where the CPU has it, else libm's exact fma)."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):  # noqa: ANN001, ANN202, ARG001
        return builder.fma(*args)

    return sig, codegen


@njit(cache=True, nogil=True)
def _rot_z_into(out, a):  # noqa: ANN001, ANN202
    """engine.geometry.rot_z(a) into ``out`` (3, 3)."""
    c, s = math.cos(a), math.sin(a)
    out[0, 0], out[0, 1], out[0, 2] = c, -s, 0.0
    out[1, 0], out[1, 1], out[1, 2] = s, c, 0.0
    out[2, 0], out[2, 1], out[2, 2] = 0.0, 0.0, 1.0


@njit(cache=True, nogil=True)
def _rot_zyx_into(out, yaw, pitch, roll):  # noqa: ANN001, ANN202
    """engine.geometry.rot_zyx(yaw, pitch, roll) into ``out`` (3, 3), its expressions."""
    cz, sz = math.cos(yaw), math.sin(yaw)
    cy, sy = math.cos(pitch), math.sin(pitch)
    cx, sx = math.cos(roll), math.sin(roll)
    out[0, 0], out[0, 1], out[0, 2] = cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx
    out[1, 0], out[1, 1], out[1, 2] = sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx
    out[2, 0], out[2, 1], out[2, 2] = -sy, cy * sx, cy * cx


@njit(cache=True, nogil=True)
def _mat3_into(out, a, b):  # noqa: ANN001, ANN202
    """out = a @ b (3 × 3) as numpy's matmul computes it through OpenBLAS's dgemm with FMA: per entry
    fma(a₂ b₂, fma(a₁ b₁, a₀ b₀))."""
    for i in range(3):
        for j in range(3):
            out[i, j] = _dot3_gemm(a[i, 0], a[i, 1], a[i, 2], b[0, j], b[1, j], b[2, j])


@njit(cache=True, nogil=True)
def _dot3_gemm(a0, a1, a2, b0, b1, b2):  # noqa: ANN001, ANN202, PLR0913
    """A 3-term dot product in dgemm's order: fma(a₂, b₂, fma(a₁, b₁, a₀ b₀))."""
    return fused_multiply_add(a2, b2, fused_multiply_add(a1, b1, a0 * b0))


@njit(cache=True, nogil=True)
def _dot3_gemv(a0, a1, a2, x0, x1, x2):  # noqa: ANN001, ANN202, PLR0913
    """A 3-term dot product in the order of numpy's 3 × 3 matrix · vector (OpenBLAS's dgemv_t tail, compiled with
    contraction): fma(a₂, x₂, fma(a₀, x₀, a₁ x₁))."""
    return fused_multiply_add(a2, x2, fused_multiply_add(a0, x0, a1 * x1))


@njit(cache=True, nogil=True)
def _angular_velocity_into(out, r0, r1, dt):  # noqa: ANN001, ANN202
    """planner._angular_velocity: the world angular velocity taking r0 to r1 in dt (small-angle), from r1 r0ᵀ."""
    d = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            d[i, j] = _dot3_gemm(r1[i, 0], r1[i, 1], r1[i, 2], r0[j, 0], r0[j, 1], r0[j, 2])
    h = 2.0 * dt
    out[0], out[1], out[2] = (d[2, 1] - d[1, 2]) / h, (d[0, 2] - d[2, 0]) / h, (d[1, 0] - d[0, 1]) / h


@njit(cache=True, nogil=True)
def _foot_rig_into(rot, trans, length_m, yaw, heel_pitch, toe_pitch, roll, width_m, roll_smoothing,  # noqa: ANN001, ANN202, PLR0913
                   roll_smoothing_sq):
    """heel_toe.foot_rig into ``rot`` (3, 3) and ``trans`` (3,): its expressions."""
    if yaw == 0.0 and heel_pitch == 0.0 and toe_pitch == 0.0 and roll == 0.0:
        for i in range(3):
            for j in range(3):
                rot[i, j] = 1.0 if i == j else 0.0
            trans[i] = 0.0
        return
    half = 0.5 * length_m
    ch, sh = math.cos(heel_pitch), math.sin(heel_pitch)
    toe_x, toe_z = -half + length_m * ch, -length_m * sh
    hx = -half - (-half * ch) - toe_x
    hz = 0.0 - (half * sh) - toe_z
    ct, st = math.cos(toe_pitch), math.sin(toe_pitch)
    tx = toe_x + ct * hx + st * hz
    tz = toe_z - st * hx + ct * hz
    if roll != 0.0 and width_m > 0.0:
        sr = math.sin(roll)
        tz += 0.5 * width_m * (math.sqrt(sr * sr + roll_smoothing_sq) - roll_smoothing)
    cz, sz = math.cos(yaw), math.sin(yaw)
    _rot_zyx_into(rot, yaw, heel_pitch + toe_pitch, roll)
    trans[0], trans[1], trans[2] = cz * tx, sz * tx, tz


@njit(cache=True, nogil=True)
def reference_frames_into(params, corners_local, prev_rots, prev_foot_pos, dt, rots, foot_pos, corners, ang,  # noqa: ANN001, ANN201, PLR0913
                          lin):
    """The rotations and positions of GaitPlanner.evaluate in one call: the pelvis rotation Rz(path yaw) ·
    Rzyx(pelvis curves); each sole's pose (``params``' FOOT_PARAMS: a swinging foot at the nominal swing's
    (x, y, yaw) with the style's rig (foot_rig) and offset, a standing foot on its latched foothold, rolled by the
    heel/toe rig or flat), its corners, and, with ``dt`` > 0, the backward-difference rates from the previous
    tick's rotations ``prev_rots`` (pelvis, left, right) and sole positions.

    Writes the rotations ``rots`` (3, 3, 3) (pelvis, left sole, right sole), the sole positions ``foot_pos`` (2, 3),
    their ``corners`` (2, 4, 3), the angular velocities ``ang`` (3, 3) (pelvis, left, right) and the sole velocities
    ``lin`` (2, 3) (zeros without rates). The 3 × 3 products
    are multiplied out in the order numpy's matmul computes them through OpenBLAS with FMA (dgemm, dgemv): the same
    numbers where numpy does, equal to rounding elsewhere (tests/gait/test_planner_speed_references.py keeps the
    replaced code)."""
    length_m, width_m, roll_smoothing, roll_sq = params[4], params[5], params[6], params[7]
    base = np.empty((3, 3))
    rig = np.empty((3, 3))
    pelvis = rots[0]
    foot_rot = rots[1:]
    _rot_z_into(base, params[0])
    _rot_zyx_into(rig, params[1], params[2], params[3])
    _mat3_into(pelvis, base, rig)
    trans = np.empty(3)
    for j in range(2):
        p = params[FOOT_PARAMS_AT + FOOT_PARAMS * j: FOOT_PARAMS_AT + FOOT_PARAMS * (j + 1)]
        mode, x, y, yaw = p[0], p[1], p[2], p[3]
        _rot_z_into(base, yaw)
        if mode == FOOT_FLAT:
            foot_pos[j, 0], foot_pos[j, 1], foot_pos[j, 2] = x, y, 0.0
            foot_rot[j] = base
            continue
        if mode == FOOT_SWING:
            _foot_rig_into(rig, trans, length_m, p[4], p[5], p[6], p[7], width_m, roll_smoothing, roll_sq)
            trans[0], trans[1], trans[2] = p[8] + trans[0], p[9] + trans[1], p[10] + trans[2]
        else:
            _foot_rig_into(rig, trans, length_m, 0.0, p[5], p[6], 0.0, 0.0, roll_smoothing, roll_sq)
        for i in range(3):
            foot_pos[j, i] = (x if i == 0 else (y if i == 1 else 0.0)) + _dot3_gemv(
                base[i, 0], base[i, 1], base[i, 2], trans[0], trans[1], trans[2])
        _mat3_into(foot_rot[j], base, rig)
    for j in range(2):
        for c in range(4):
            for i in range(3):
                corners[j, c, i] = _dot3_gemm(foot_rot[j, i, 0], foot_rot[j, i, 1], foot_rot[j, i, 2], corners_local[c, 0],
                                              corners_local[c, 1], corners_local[c, 2]) + foot_pos[j, i]
    ang[:] = 0.0
    lin[:] = 0.0
    if dt > 0.0:
        _angular_velocity_into(ang[0], prev_rots[0], pelvis, dt)
        for j in range(2):
            _angular_velocity_into(ang[1 + j], prev_rots[1 + j], foot_rot[j], dt)
            for i in range(3):
                lin[j, i] = (foot_pos[j, i] - prev_foot_pos[j, i]) / dt


# ---------------------------------------------------------------------------------------- the planner tick's reference
# GaitPlanner.evaluate in one call: the blended channels' values (BlendedGait.channel_values), each sole's part of
# reference_frames_into's parameters (what GaitPlanner._foot_params computed: the nominal swing, or the latched
# foothold with the heel/toe transitions) and reference_frames_into, written into the caller's arrays. Python's float
# semantics as in the preview above: min/max keep their first argument on ties, squares go through libm's pow
# (``two``).

#: Heel/toe transition smoothing and floor of the soles' stance parameters [s] (_foot_params_into), and the swing
#: bank's heel_pitch / toe_pitch indices (blending.HEEL, TOE).
TRANSITION_SMOOTHING_S = 0.01
MIN_HEEL_TOE_TRANSITION_S = 0.08
SWING_HEEL, SWING_TOE = 4, 5


@njit(cache=True, nogil=True)
def _smoothstep(s):  # noqa: ANN001, ANN202
    """engine.geometry.smoothstep: 3s² − 2s³ on [0, 1], its expressions."""
    s = 0.0 if s < 0 else (1.0 if s > 1 else s)
    return s * s * (3.0 - 2.0 * s)


@njit(cache=True, nogil=True)
def _smooth_min(a, b, eps, two):  # noqa: ANN001, ANN202
    """engine.geometry.smooth_min (its (a − b) ** 2 through pow)."""
    return 0.5 * (a + b - math.sqrt((a - b) ** two + eps * eps))


@njit(cache=True, nogil=True)
def _smooth_max(a, b, eps, two):  # noqa: ANN001, ANN202
    """engine.geometry.smooth_max (its (a − b) ** 2 through pow)."""
    return 0.5 * (a + b + math.sqrt((a - b) ** two + eps * eps))


@njit(cache=True, nogil=True)
def _foot_params_into(p, side, phi, t, events, vals, swinging, start, target, landed, pitch, touchdown_transition_s,  # noqa: ANN001, ANN202, PLR0913
                      liftoff_transition_s, two):
    """GaitPlanner._foot_params: the sole's FOOT_PARAMS into ``p`` and its swing progress (returned). Swinging:
    the nominal swing (swing.nominal_swing) from ``start`` to ``target`` (x, y, yaw) at its progress ⊕ the style's
    rig and offset (``vals``: the side's blended swing channels). Standing: on ``start`` (the latched foothold) with
    the heel/toe transitions (heel_toe.stance_pitch) after touchdown / before liftoff; ``pitch`` (2, 2): the blend's
    (liftoff, touchdown) (heel, toe) pitches of the side."""
    lo = PREVIEW_EVENT_PHASES[0] if side == 0 else PREVIEW_EVENT_PHASES[2]
    td = PREVIEW_EVENT_PHASES[1] if side == 0 else PREVIEW_EVENT_PHASES[3]
    k = math.floor(phi - lo)
    if swinging:
        t_lo, t_td = _event_time(k + lo, events), _event_time(k + td, events)
        s = _first_min(_first_max((t - t_lo) / (t_td - t_lo), 0.0), 1.0)
        a = _smoothstep(s)
        p[0] = FOOT_SWING
        p[1] = (1.0 - a) * start[0] + a * target[0]
        p[2] = (1.0 - a) * start[1] + a * target[1]
        p[3] = start[2] + a * ((target[2] - start[2] + math.pi) % (2 * math.pi) - math.pi)  # wrap_angle
        p[4], p[5], p[6], p[7] = vals[3], vals[SWING_HEEL], vals[SWING_TOE], vals[6]
        p[8], p[9], p[10] = vals[0], vals[1], vals[2]
        return s
    t_td = _event_time(k + td, events)  # last touchdown (k indexes the swing that ended)
    t_next_lo = _event_time(k + 1 + lo, events)
    foothold_s = t_next_lo - t_td
    if side == 0:
        ds_after_td, ds_before_lo = events[1] - events[0], events[3] - events[2]
    else:
        ds_after_td, ds_before_lo = events[3] - events[2], events[1] - events[0]
    eps = TRANSITION_SMOOTHING_S
    d_td = _smooth_min(_smooth_min(_smooth_max(touchdown_transition_s, MIN_HEEL_TOE_TRANSITION_S, eps, two),
                                   0.5 * foothold_s, eps, two), ds_after_td, eps, two)
    d_lo = _smooth_min(_smooth_min(_smooth_max(liftoff_transition_s, MIN_HEEL_TOE_TRANSITION_S, eps, two),
                                   0.5 * foothold_s, eps, two), ds_before_lo, eps, two)
    if not landed:
        d_td = 0.0
    heel, toe = 0.0, 0.0  # heel_toe.stance_pitch
    since_td, until_lo = t - t_td, t_next_lo - t
    if d_td > 0 and since_td < d_td:
        w = 1.0 - _smoothstep(since_td / d_td)
        heel += w * pitch[1, 0]
        toe += w * pitch[1, 1]
    if d_lo > 0 and until_lo < d_lo:
        w = 1.0 - _smoothstep(until_lo / d_lo)
        heel += w * pitch[0, 0]
        toe += w * pitch[0, 1]
    p[0] = FOOT_FLAT if heel == 0.0 and toe == 0.0 else FOOT_ROLLED
    p[1], p[2], p[3] = start[0], start[1], start[2]
    p[4], p[5], p[6] = 0.0, heel, toe
    p[7] = p[8] = p[9] = p[10] = 0.0
    return 1.0


@njit(cache=True, nogil=True)
def evaluate_reference_into(phi, t, events, weights, waypoints, segments, cycles, member_of_row, offset, periodic,  # noqa: ANN001, ANN201, PLR0913
                            period, hi, search, t0, coef, n_cycle, path_yaw, frame, feet, swinging, landed, pitch,
                            attributes, corners_local, has_prev, dt, prev_rots, prev_foot_pos, prev_pelvis_z,
                            prev_upper, two, rots, foot_pos, corners, corner_contact, ang, lin, upper, upper_qd,
                            progress, scalars):
    """GaitPlanner.evaluate's numbers at phase ``phi`` (gait time ``t``) in one call, into the caller's arrays.

    The blend: its ``events`` (t_LTD, t_RLO, t_RTD, cycle), ``weights`` and merged bank (``waypoints`` … ``coef``:
    :func:`merged_bank_at_phase`'s, ``n_cycle`` cycle channels per member), ``pitch`` (2, 2, 2): per side the
    (liftoff, touchdown) (heel, toe) pitches, ``attributes``: pelvis height, touchdown and liftoff transitions.
    ``frame``: the sole's length and width, heel_toe.ROLL_SMOOTHING and its square, planner.CONTACT_TOL_M.
    ``feet`` (2, 2, 3): per side (swing start, target) while ``swinging``, else (latched, latched); ``landed`` (2,).
    The last tick's frames (``has_prev``, ``dt`` since it, ``prev_*``) give the backward-difference rates.

    Writes :func:`reference_frames_into`'s ``rots`` … ``lin``, ``corner_contact`` (2, 4) (a corner below
    ``frame[4]``), the upper-body joints ``upper`` and rates ``upper_qd`` (K,), the feet's
    swing ``progress`` (2,) and ``scalars`` (2,): the pelvis height and its rate (0 without rates). The channels' blend
    is a BLAS dgemv, as numpy's ``weights @ values`` is: the same numbers as the Python it replaces (bit for bit
    here; tests/gait/test_planner_evaluate_reference.py keeps that code and allows 4 ulp for another BLAS build)."""
    values, _ = merged_bank_at_phase(phi - math.floor(phi), 1.0, waypoints, segments, cycles, member_of_row, offset,
                                     periodic, period, hi, search, t0, coef)
    v = np.dot(weights, values.reshape((weights.shape[0], values.shape[0] // weights.shape[0])))
    params = np.empty(FOOT_PARAMS_AT + 2 * FOOT_PARAMS)
    params[0], params[1], params[2], params[3] = path_yaw, v[1], v[2], v[3]
    params[4], params[5], params[6], params[7] = frame[0], frame[1], frame[2], frame[3]
    for j in range(2):
        at = FOOT_PARAMS_AT + FOOT_PARAMS * j
        vals = v[n_cycle + 7 * j: n_cycle + 7 * (j + 1)]
        progress[j] = _foot_params_into(params[at: at + FOOT_PARAMS], j, phi, t, events, vals, swinging[j],
                                        feet[j, 0], feet[j, 1], landed[j], pitch[j], attributes[1], attributes[2],
                                        two)
    rates = has_prev and not dt <= 0
    reference_frames_into(params, corners_local, prev_rots, prev_foot_pos, dt if has_prev and dt > 0 else 0.0, rots,
                          foot_pos, corners, ang, lin)
    for j in range(2):
        for c in range(4):
            corner_contact[j, c] = corners[j, c, 2] < frame[4]
    pelvis_z = attributes[0] + v[0]
    scalars[0] = pelvis_z
    scalars[1] = (pelvis_z - prev_pelvis_z) / dt if rates else 0.0
    for i in range(upper.shape[0]):
        upper[i] = v[4 + i]
        upper_qd[i] = (upper[i] - prev_upper[i]) / dt if rates else 0.0
