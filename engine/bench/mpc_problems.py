"""Recorded-like CoM MPC problems: a straight walk's supports and a closed-loop-like sequence of
``ComMpc.solve`` calls (test fixtures and the ``mpc`` bench's workload; no simulator needed)."""

from __future__ import annotations

import math

import numpy as np

from engine.constants import GRAVITY_MPS2
from engine.control.mpc import ComMpc, ComMpcSolution, SupportInterval, propagate_lip
from engine.control.mpc.regions import _make_region, _Region
from engine.control.mpc.types import FloatArray
from engine.geometry.polygon import convex_hull

def _foot_rectangle(center_xy_m: FloatArray, yaw_rad: float, length_m: float, width_m: float) -> FloatArray:
    half = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]]) * [0.5 * length_m, 0.5 * width_m]
    rot = np.array([[math.cos(yaw_rad), -math.sin(yaw_rad)], [math.sin(yaw_rad), math.cos(yaw_rad)]])
    return (half[[2, 3, 0, 1]] @ rot.T) + center_xy_m  # counter-clockwise


def example_walking_supports(
    n_steps: int = 8,
    step_length_m: float = 0.25,
    step_width_m: float = 0.2,
    single_support_s: float = 0.4,
    double_support_s: float = 0.1,
    initial_double_support_s: float = 0.5,
    final_double_support_s: float = 3.0,
    foot_length_m: float = 0.2,
    foot_width_m: float = 0.08,
    t0_s: float = 0.0,
    yaw_rad: float = 0.0,
) -> list[SupportInterval]:
    """Straight walk (first step with the right foot) as alternating double/single supports.

    Feet are rectangles; double support is the convex hull of both feet.  The walk
    starts and ends in double support (the final one models stopping).
    """
    rot = np.array([[math.cos(yaw_rad), -math.sin(yaw_rad)], [math.sin(yaw_rad), math.cos(yaw_rad)]])

    def foot(x_m: float, side: float) -> FloatArray:
        return _foot_rectangle(rot @ np.array([x_m, 0.5 * side * step_width_m]), yaw_rad, foot_length_m, foot_width_m)

    feet = {1.0: foot(0.0, 1.0), -1.0: foot(0.0, -1.0)}  # left (+y), right (-y)
    t = t0_s
    out = [SupportInterval(t, t + initial_double_support_s, convex_hull(np.vstack(list(feet.values()))))]
    t += initial_double_support_s
    for i in range(n_steps):
        swing = -1.0 if i % 2 == 0 else 1.0
        out.append(SupportInterval(t, t + single_support_s, feet[-swing]))
        t += single_support_s
        feet[swing] = foot((i + 1) * step_length_m, swing)
        ds = final_double_support_s if i == n_steps - 1 else double_support_s
        out.append(SupportInterval(t, t + ds, convex_hull(np.vstack(list(feet.values())))))
        t += ds
    return out




def _clip_into(point: FloatArray, region: _Region) -> FloatArray:
    """``point`` if inside ``region``, else the point of the segment centroid -> point on its boundary."""
    c = region.centroid
    den = region.normals @ (point - c)
    num = region.offsets - region.normals @ c
    with np.errstate(divide="ignore", invalid="ignore"):
        scale = np.min(np.where(den > 0.0, num / den, np.inf), initial=1.0)
    return c + min(max(scale, 0.0), 1.0) * (point - c)


def closed_loop_like_problems(
    n_calls: int = 500,
    seed: int = 0,
    *,
    mpc: ComMpc | None = None,
    dt_s: float = 0.008,
    com_height_m: float = 0.6,
    state_noise: tuple[float, float] = (0.002, 0.01),
    pull: float = 0.2,
) -> list[tuple[tuple, dict]]:
    """A realistic receding-horizon sequence of ``ComMpc.solve`` problems, without a simulator.

    Mimics what the closed-loop walking controller feeds the MPC (G1-like numbers):

    * single / double supports of 0.36 / 0.09 s at a gait time rate ``kappa`` sweeping
      [0.75, 1.35] (durations / kappa) with per-call jitter; the remaining duration of
      the current phase is rescaled every call, as gait time scaling does;
    * a rate-limited speed command (0.3 m/s forward, then 0.2 m/s backward) with some
      turning; footholds re-targeted every call, with adjustments that random-walk by a
      few mm per call (up to +-3 cm) plus a capture-point step feedback;
    * initial states that continue the previous plan, pulled by ``pull`` per call towards
      a "robot" (an exact LIP tracking the plan with DCM feedback and a centimetre CoP
      error, its CoP clipped into the support), plus per-call noise of ``state_noise`` =
      (position [m], velocity [m/s]) standard deviations.  Centimetres make this
      narrow-footed gait uncapturable within a few steps (still a good solver stress
      test); the walking controller itself continues its plan exactly (``pull=0``,
      ``state_noise=(0, 0)``);
    * the initial CoP clipped into the first support, as the controller does.

    The loop is closed with ``mpc`` (a fresh :class:`ComMpc` by default).  Returns
    ``[(args, kwargs), ...]`` exactly as :meth:`ComMpc.solve` received them.
    """
    rng = np.random.default_rng(seed)
    mpc = mpc if mpc is not None else ComMpc()
    omega = math.sqrt(GRAVITY_MPS2 / com_height_m)
    foot_l, foot_w, width = 0.16, 0.06, 0.20
    ss_s, ds_s = 0.36, 0.09

    def foot(pose: FloatArray) -> FloatArray:
        return _foot_rectangle(pose[:2], pose[2], foot_l, foot_w)

    def rot(yaw: float) -> FloatArray:
        return np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])

    feet = {1: np.array([0.0, 0.5 * width, 0.0]), -1: np.array([0.0, -0.5 * width, 0.0])}
    t = 0.0
    speed = 0.0
    phase = float(rng.uniform(0.0, 2.0 * math.pi))
    kappa = float(np.clip(1.05 + 0.32 * math.sin(phase), 0.75, 1.35))
    phase_ds, phase_end, swing = True, 0.45, -1  # current phase; next (or current) swing foot
    adjust = walk_noise = dcm_error = np.zeros(2)
    robot = np.array([0.0, 0.0, 0.0, 0.0])  # x, y, vx, vy
    plan: ComMpcSolution | None = None
    problems: list[tuple[tuple, dict]] = []
    for i in range(n_calls):
        # Speed command: forward, then backward, rate limited (as the controller filters it).
        target = 0.3 if t < 0.45 * n_calls * dt_s else -0.2
        speed += float(np.clip(target - speed, -0.25 * dt_s, 0.25 * dt_s))
        yaw_rate = 0.25 * math.sin(0.4 * t)
        # Gait time scale (a rate: durations are nominal / kappa): sweeps [0.75, 1.35] smoothly,
        # with per-call jitter.
        kappa_new = float(np.clip(1.05 + 0.32 * math.sin(1.3 * t + phase) + rng.normal(0.0, 0.004), 0.75, 1.35))
        phase_end = t + max(phase_end - t, 0.0) * kappa / kappa_new
        kappa = kappa_new
        # Foothold adjustment: a random walk plus capture-point step feedback (as gait feedback does).
        walk_noise = np.clip(walk_noise + rng.normal(0.0, 0.002, 2), -0.03, 0.03)
        adjust = walk_noise + 0.5 * dcm_error
        while t >= phase_end:  # contact switches
            if phase_ds:
                phase_ds, phase_end = False, phase_end + ss_s / kappa
            else:  # the swing foot lands where it is targeted now
                stance = feet[-swing]
                yaw = stance[2] + yaw_rate * (ss_s + ds_s)
                xy = stance[:2] + rot(yaw) @ [speed * (ss_s + ds_s), swing * width] + adjust
                feet[swing] = np.array([xy[0], xy[1], yaw])
                swing = -swing
                phase_ds, phase_end = True, phase_end + ds_s / kappa
        # Supports from now to beyond the window, footholds re-targeted from the current state.
        planned = dict(feet)
        polys = [convex_hull(np.vstack([foot(planned[1]), foot(planned[-1])])) if phase_ds else foot(planned[-swing])]
        bounds = [(t, phase_end)]
        is_ds, sw, t_end = phase_ds, swing, phase_end
        while t_end < t + mpc.preview_s + 0.2:
            if is_ds:
                is_ds, dur = False, ss_s / kappa
                polys.append(foot(planned[-sw]))
            else:
                stance = planned[-sw]
                yaw = stance[2] + yaw_rate * (ss_s + ds_s)
                step = [speed * (ss_s + ds_s), sw * width]
                xy = stance[:2] + rot(yaw) @ step + (adjust if sw == swing else 0.0)
                planned[sw] = np.array([xy[0], xy[1], yaw])
                sw = -sw
                is_ds, dur = True, ds_s / kappa
                polys.append(convex_hull(np.vstack([foot(planned[1]), foot(planned[-1])])))
            bounds.append((t_end, t_end + dur))
            t_end += dur
        supports = [SupportInterval(a, b, p) for (a, b), p in zip(bounds, polys)]
        # Initial state: the previous plan, pulled towards the robot (as the walking controller does).
        if plan is None:
            com, vel = robot[:2].copy(), robot[2:].copy()
            cop = com.copy()
        else:
            com, vel, _ = plan.com_at(t)
            com = com + pull * (robot[:2] - com) + rng.normal(0.0, state_noise[0], 2)
            vel = vel + pull * (robot[2:] - vel) + rng.normal(0.0, state_noise[1], 2)
            cop = plan.cop_at(t)
        first_region = _make_region(supports[0].polygon)
        cop = _clip_into(cop, first_region)
        args = (t, com, vel, cop, com_height_m, supports)
        problems.append((args, {}))
        sol = mpc.solve(*args)
        if sol.ok:
            plan = sol
        # The robot tracks the plan with DCM feedback (its CoP, with a centimetre error, clipped
        # into the support), over one control period (exact LIP).
        if plan is not None:
            ref_pos, ref_vel, _ = plan.com_at(t)
            dcm_error = (robot[:2] + robot[2:] / omega) - (ref_pos + ref_vel / omega)
            cop_robot = plan.cop_at(t) + (1.0 + 3.0 / omega) * dcm_error
        else:
            cop_robot = cop.copy()
        cop_robot = _clip_into(cop_robot + rng.normal(0.0, 0.01, 2), first_region)
        pos, vel_r = propagate_lip([t, t + dt_s], np.vstack([cop_robot, cop_robot]), robot[:2], robot[2:], omega)
        robot = np.concatenate([pos[-1], vel_r[-1]])
        t = round(t + dt_s, 9)
    return problems
