"""GaitPlanner.evaluate computes the same reference, to ``MAX_ULP`` (bit for bit on this machine), as the code it
replaced (kept here): the blended channels' values without their rates (BlendedGait.channel_values), both feet's
swing test on one phase, and then the channels, the soles' parameters (GaitPlanner._foot_params, kept here as
foot_params_before) and the frames in one compiled call (planner_kernels.evaluate_reference_into)."""

from __future__ import annotations

from dataclasses import fields

import math

import numpy as np

from engine.control.walking_controller import WalkingController
from engine.gait.blending import HEEL, SWING_PHASES, TOE, BlendedGait
from engine.gait.command_schedule import preset
from engine.gait.heel_toe import stance_pitch
from engine.gait.planner import (
    _NO_POS,
    _NO_ROTS,
    CONTACT_TOL_M,
    ROLL_SMOOTHING,
    GaitPlanner,
    GaitReference,
    PlannerFeedback,
)
from engine.gait.planner_kernels import (
    FOOT_FLAT,
    FOOT_ROLLED,
    FOOT_SWING,
    MIN_HEEL_TOE_TRANSITION_S,
    TRANSITION_SMOOTHING_S,
    reference_frames_into,
)
from engine.gait.style import load_style, styles_dir
from engine.gait.swing import nominal_swing
from engine.geometry import smooth_max, smooth_min
from engine.robot.model import load_robot
from engine.sim import Simulation


def evaluate_before(self: GaitPlanner, phi: float) -> GaitReference:
    """GaitPlanner.evaluate before its glue was trimmed (commit bd1817b), as it was."""
    blend = self.blend
    cycle_vals, left_vals, right_vals, *_ = blend.channels(phi)
    t = blend.time_at(phi)
    swinging = (self.in_swing("left", phi), self.in_swing("right", phi))
    left, left_progress = foot_params_before(self, "left", phi, t, blend, left_vals, swinging[0])
    right, right_progress = foot_params_before(self, "right", phi, t, blend, right_vals, swinging[1])
    pelvis_yaw, pelvis_pitch, pelvis_roll = cycle_vals[1:4].tolist()
    params = np.array([float(self.path.yaw), pelvis_yaw, pelvis_pitch, pelvis_roll, self.sole_length_m,
                       self.sole_width_m, ROLL_SMOOTHING, ROLL_SMOOTHING ** 2, *left, *right])
    prev = self._last_pose
    dt = self.t_s - prev["t"] if prev is not None else 0.0
    # (reference_frames before it wrote into the caller's arrays: its own arrays, the same numbers)
    rots, foot_pos, corners = np.empty((3, 3, 3)), np.empty((2, 3)), np.empty((2, 4, 3))
    ang, lin = np.empty((3, 3)), np.empty((2, 3))
    reference_frames_into(
        params, self.sole_corners_local, prev["rots"] if prev is not None else _NO_ROTS,
        prev["foot_pos"] if prev is not None else _NO_POS, dt if prev is not None and dt > 0 else 0.0, rots, foot_pos,
        corners, ang, lin)
    pelvis_rot, foot_rot = rots[0], rots[1:]
    pelvis_z = blend.attribute("pelvis_height_m") + cycle_vals[0]
    upper = cycle_vals[4:].copy()
    # (the soles' rotations are rots[1:], their positions foot_pos: rows left, right)
    self._last_pose = {"t": self.t_s, "pelvis_z": pelvis_z, "rots": rots, "foot_pos": foot_pos, "upper": upper}
    if prev is None or dt <= 0:
        z_rate = 0.0
        upper_qd = np.zeros_like(upper)
    else:
        z_rate = (pelvis_z - prev["pelvis_z"]) / dt
        upper_qd = (upper - prev["upper"]) / dt
    return GaitReference(
        t_s=self.t_s, phase=phi, command=self.command.copy(),
        sample_weights=self.weights.copy(), path_pose=self.path.pose(),
        pelvis_z=pelvis_z, pelvis_z_rate=z_rate, pelvis_rot=pelvis_rot, pelvis_ang_vel=ang[0],
        foot_pos=foot_pos.copy(), foot_rot=foot_rot, foot_lin_vel=lin, foot_ang_vel=ang[1:],
        contact=np.array([not swinging[0], not swinging[1]]),
        corner_contact=corners[:, :, 2] < CONTACT_TOL_M, sole_corners=corners,
        upper_q=upper, upper_qd=upper_qd,
        footholds={"left": self.target["left"] if swinging[0] else self.latched["left"],  # (SIDES' order)
                   "right": self.target["right"] if swinging[1] else self.latched["right"]},
        cycle_s=blend.events_s[3],
        swing_progress=np.array([left_progress, right_progress]),
    )


def foot_params_before(self: GaitPlanner, side: str, phi: float, t: float, blend: BlendedGait, vals: np.ndarray,
                       swinging: bool) -> tuple[tuple[float, ...], float]:
    """GaitPlanner._foot_params before evaluate was one compiled call (commit 3390552), as it was: the sole's part
    of :func:`engine.gait.planner_kernels.reference_frames_into`' parameters (FOOT_PARAMS: mode, x, y, yaw, rig yaw,
    heel and toe pitch, roll, offset) and its swing progress.

    Swinging: the nominal swing (Eqs. 5–6) at its progress ⊕ the style's rig and offset. Standing: the
    latched foothold with the heel/toe transitions after touchdown / before liftoff."""
    lo, td = SWING_PHASES[side]
    k = math.floor(phi - lo)
    if swinging:
        t_lo, t_td = blend.event_time(k + lo), blend.event_time(k + td)
        s = min(max((t - t_lo) / (t_td - t_lo), 0.0), 1.0)
        x, y, yaw, _ = nominal_swing(self.swing_start[side], self.target[side], s)
        v = vals.tolist()  # the rig's angles as floats (the same numbers, without numpy scalars)
        return (FOOT_SWING, x, y, yaw, v[3], v[HEEL], v[TOE], v[6], v[0], v[1], v[2]), s
    hold = self.latched[side]
    t_td = blend.event_time(k + td)  # last touchdown (k indexes the swing that ended)
    t_next_lo = blend.event_time(k + 1 + lo)
    foothold_s = t_next_lo - t_td
    t_ltd, t_rlo, t_rtd, cycle = blend.events_s
    ds = (t_rlo - t_ltd, cycle - t_rtd)
    ds_after_td, ds_before_lo = ds if side == "left" else ds[::-1]
    # A pitched foot at liftoff/touchdown needs time to roll from/to flat: never less than
    # MIN_HEEL_TOE_TRANSITION_S (else the foot would snap), never more than the double support.
    # Smooth min/max: durations vary with the blend weights, and a hard switch of the
    # binding limit would put a kink in the foot's pitch.
    eps = TRANSITION_SMOOTHING_S
    d_td = smooth_min(smooth_min(smooth_max(blend.attribute("touchdown_transition_s"), MIN_HEEL_TOE_TRANSITION_S, eps),
                                 0.5 * foothold_s, eps), ds_after_td, eps)
    d_lo = smooth_min(smooth_min(smooth_max(blend.attribute("liftoff_transition_s"), MIN_HEEL_TOE_TRANSITION_S, eps),
                                 0.5 * foothold_s, eps), ds_before_lo, eps)
    liftoff_pitch, touchdown_pitch = blend.boundary_pitch[side]
    if not self.landed[side]:
        d_td = 0.0
    heel, toe = stance_pitch(t - t_td, t_next_lo - t, touchdown_pitch, liftoff_pitch, d_td, d_lo)
    mode = FOOT_FLAT if heel == 0.0 and toe == 0.0 else FOOT_ROLLED
    return (mode, hold.x, hold.y, hold.yaw, 0.0, heel, toe, 0.0, 0.0, 0.0, 0.0), 1.0


#: Floats may differ by this many units in the last place (relative), or by ``ATOL`` near zero: the blended channels
#: are a BLAS dot product, numpy's (before) and numba's through scipy's (now). They agree bit for bit here, but two
#: OpenBLAS builds may pick different kernels on another CPU. A wrong change (a swapped index, a dropped term) is off
#: by far more.
MAX_ULP = 4
ATOL = 1e-12


def _assert_same(a: object, b: object, what: str) -> None:
    """The same type and numbers (arrays: shape, dtype, then bytes for integers and bools, ``MAX_ULP`` / ``ATOL`` for
    floats; dicts: keys in order, then each value; floats: ``MAX_ULP`` / ``ATOL``; the rest, e.g. Footholds: ==)."""
    assert type(a) is type(b), (what, type(a), type(b))
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray)
        assert a.dtype == b.dtype and a.shape == b.shape, what
        if np.issubdtype(a.dtype, np.floating):
            np.testing.assert_allclose(a, b, rtol=MAX_ULP * np.finfo(float).eps, atol=ATOL, err_msg=what)
        else:
            assert a.tobytes() == b.tobytes(), what
    elif isinstance(a, (float, np.floating)):
        np.testing.assert_allclose(float(a), float(b), rtol=MAX_ULP * np.finfo(float).eps, atol=ATOL, err_msg=what)
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), what
        for key in a:
            _assert_same(a[key], b[key], f"{what}[{key}]")
    else:
        assert a == b, (what, a, b)


def test_evaluate_matches_the_python_it_replaced() -> None:
    """Every planner tick of 4 s of G1's sweep (standing, walking, turning, strafing): the reference and the state
    evaluate leaves for the next tick (_last_pose) equal the replaced code's, field by field."""
    robot = load_robot("g1")
    style = load_style(styles_dir("g1") / "neutral.json")
    schedule = preset("sweep", style.velocities)
    controller = WalkingController(robot, style)
    planner = controller.planner
    evaluate_now = planner.evaluate
    compared, swinging = 0, [0, 0]

    def evaluate_both(phi: float) -> GaitReference:
        nonlocal compared
        prev = planner._last_pose
        now = evaluate_now(phi)
        after_now = planner._last_pose
        planner._last_pose = prev
        before = evaluate_before(planner, phi)
        after_before = planner._last_pose
        for f in fields(GaitReference):
            _assert_same(getattr(now, f.name), getattr(before, f.name), f"{f.name} at t = {planner.t_s}")
        assert after_now is not None and after_before is not None
        _assert_same(after_now, after_before, f"_last_pose at t = {planner.t_s}")
        for i in range(2):
            swinging[i] += not bool(now.contact[i])
        compared += 1
        planner._last_pose = after_now  # the run goes on from the new code's state
        return now

    planner.evaluate = evaluate_both  # type: ignore[method-assign]
    sim = Simulation(robot, controller)
    dt = float(sim.model.opt.timestep)
    for k in range(2000):
        controller.set_command(schedule(k * dt))
        sim.step()
        assert not sim.fallen
    assert compared >= 490 and min(swinging) > 50  # every planner tick; both feet swung and stood


def _compare_inside_step(planner: GaitPlanner, counts: dict[str, int]) -> None:
    """Make ``planner.evaluate`` (called by ``step``) run the new and the replaced code from the same state and
    compare the references and the _last_pose they leave, field by field (the new code's state goes on); counts the
    comparisons and those with rates (a tick with time since the last evaluate)."""
    evaluate_now = planner.evaluate

    def evaluate_both(phi: float) -> GaitReference:
        prev = planner._last_pose
        now = evaluate_now(phi)
        after_now = planner._last_pose
        planner._last_pose = prev
        before = evaluate_before(planner, phi)
        what = f"at t = {planner.t_s}"
        for f in fields(GaitReference):
            _assert_same(getattr(now, f.name), getattr(before, f.name), f"{f.name} {what}")
        _assert_same(after_now, planner._last_pose, f"_last_pose {what}")
        planner._last_pose = after_now
        counts["compared"] += 1
        counts["with rates"] += bool(np.abs(now.foot_lin_vel).max() > 0.0 and np.abs(now.upper_qd).max() > 0.0)
        return now

    planner.evaluate = evaluate_both  # type: ignore[method-assign]


def test_evaluate_matches_the_python_it_replaced_with_heel_toe_rolls() -> None:
    """The planner alone (no robot) on the rigged style (toe-off and heel-strike pitches, a yawed and rolled swing
    foot, a swaying pelvis) under ramping commands, random time scaling and step adjustments, and some ticks
    without time (no rates): every branch of the soles' parameters (swinging, standing flat and rolled, before the
    first landing) and the rates give the old numbers (to ``MAX_ULP``), compared inside ``step``'s own evaluate."""
    from engine.gait.offline_plan import planner_for
    from engine.gait.style import StyleContext
    from tests.gait.test_planner_speed_references import _rigged_style

    robot = load_robot("g1")
    rng = np.random.default_rng(12)
    modes = {FOOT_SWING: 0, FOOT_ROLLED: 0, FOOT_FLAT: 0}
    planner = planner_for(robot, _rigged_style(), StyleContext.for_robot("g1"))
    planner.path_follows_feet = 0.5
    step = GaitPlanner.step
    counts = {"compared": 0, "with rates": 0}
    _compare_inside_step(planner, counts)
    command, goal = np.zeros(3), np.array([0.4, 0.1, 0.3])
    for k in range(600):
        if k % 120 == 0:
            goal = rng.uniform([-0.3, -0.2, -0.6], [0.5, 0.2, 0.6])
        command = command + np.clip(goal - command, -0.01, 0.01)
        fb = PlannerFeedback(float(rng.uniform(0.7, 1.4)), rng.normal(0.0, 0.02, 2) if k % 3 else None)
        ref = step(planner, 0.008 if k % 50 else 0.0, command, fb, with_preview=False)
        t = planner.blend.time_at(ref.phase)
        for i, side in enumerate(("left", "right")):
            vals = planner.blend.channel_values(ref.phase)[1 + i]
            params, _ = foot_params_before(planner, side, ref.phase, t, planner.blend, vals, not bool(ref.contact[i]))
            modes[params[0]] += 1
    assert min(modes.values()) > 50, modes  # every mode of the soles' parameters came up
    assert counts["compared"] == 600 and counts["with rates"] > 500, counts
