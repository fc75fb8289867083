"""Speed-ups of the gait planner compute the same numbers as the code they replaced (kept here)."""

from __future__ import annotations

import math

import numpy as np

from engine.gait.footsteps import stance_offset, stance_offset_xy_yaw
from engine.gait.phase_map import PHASE_WAYPOINTS, PhaseMap, _pchip_slope


def phase_map_tables_reference(ev: tuple[float, float, float, float]) -> tuple[list, list]:
    """PhaseMap.__init__'s slopes and segments before the speed-up (weights computed per call)."""
    phi = list(PHASE_WAYPOINTS)
    times = [0.0, ev[0], ev[1], ev[2], ev[3]]
    hs = [phi[i + 1] - phi[i] for i in range(4)]
    ds = [(times[i + 1] - times[i]) / hs[i] for i in range(4)]
    slopes = [0.0] * 5
    for i in range(1, 4):
        slopes[i] = _pchip_slope(ds[i - 1], ds[i], hs[i - 1], hs[i])
    slopes[0] = slopes[4] = _pchip_slope(ds[3], ds[0], hs[3], hs[0])
    seg = []
    for i in range(4):
        h, d, m0, m1 = hs[i], ds[i], slopes[i], slopes[i + 1]
        c2 = (3.0 * d - 2.0 * m0 - m1) / h
        c3 = (m0 + m1 - 2.0 * d) / (h * h)
        seg.append((phi[i], times[i], m0, c2, c3, h, times[i + 1]))
    return slopes, seg


def test_phase_map_tables_match_the_reference() -> None:
    rng = np.random.default_rng(3)
    for _ in range(2000):
        ev = tuple(np.cumsum(rng.uniform(0.01, 0.6, 4)).tolist())
        slopes, seg = phase_map_tables_reference(ev)
        pm = PhaseMap(*ev)
        assert pm._slopes == slopes  # exact float equality, element by element
        assert pm._seg == seg


def test_stance_offset_floats_match_the_array() -> None:
    rng = np.random.default_rng(4)
    for _ in range(500):
        width, splay, bias = rng.normal(0.0, 0.3, 3).tolist()
        for side in ("left", "right"):
            assert stance_offset_xy_yaw(side, width, splay, bias) == tuple(stance_offset(side, width, splay, bias).tolist())


# ------------------------------------------------------------------------------ the reference's frames (one kernel)
def angular_velocity_reference(r0: np.ndarray, r1: np.ndarray, dt: float) -> np.ndarray:
    """planner._angular_velocity before the speed-up."""
    d = (r1 @ r0.T).tolist()
    return np.array([d[2][1] - d[1][2], d[0][2] - d[2][0], d[1][0] - d[0][1]]) / (2.0 * dt)


def foot_at_reference(planner, side: str, phi: float, t: float, blend, vals: np.ndarray):  # noqa: ANN001, ANN201
    """GaitPlanner._foot_at before the speed-up: (position, rotation, swing progress) of the sole."""
    from engine.gait.blending import HEEL, SWING_PHASES, TOE
    from engine.gait.heel_toe import foot_rig, stance_pitch
    from engine.gait.planner_kernels import MIN_HEEL_TOE_TRANSITION_S, TRANSITION_SMOOTHING_S
    from engine.gait.swing import nominal_swing
    from engine.geometry import rot_z, smooth_max, smooth_min

    self = planner
    lo, td = SWING_PHASES[side]
    k = math.floor(phi - lo)
    if self.in_swing(side, phi):
        t_lo, t_td = blend.event_time(k + lo), blend.event_time(k + td)
        s = min(max((t - t_lo) / (t_td - t_lo), 0.0), 1.0)
        x, y, yaw, _ = nominal_swing(self.swing_start[side], self.target[side], s)
        v = vals.tolist()
        rig_r, rig_t = foot_rig(self.sole_length_m, v[3], v[HEEL], v[TOE], v[6], self.sole_width_m)
        offset = vals[0:3] + rig_t
        base = rot_z(yaw)
        return np.array([x, y, 0.0]) + base @ offset, base @ rig_r, s
    hold = self.latched[side]
    t_td = blend.event_time(k + td)
    t_next_lo = blend.event_time(k + 1 + lo)
    foothold_s = t_next_lo - t_td
    t_ltd, t_rlo, t_rtd, cycle = blend.events_s
    ds = (t_rlo - t_ltd, cycle - t_rtd)
    ds_after_td, ds_before_lo = ds if side == "left" else ds[::-1]
    eps = TRANSITION_SMOOTHING_S
    d_td = smooth_min(smooth_min(smooth_max(blend.attribute("touchdown_transition_s"), MIN_HEEL_TOE_TRANSITION_S, eps),
                                 0.5 * foothold_s, eps), ds_after_td, eps)
    d_lo = smooth_min(smooth_min(smooth_max(blend.attribute("liftoff_transition_s"), MIN_HEEL_TOE_TRANSITION_S, eps),
                                 0.5 * foothold_s, eps), ds_before_lo, eps)
    liftoff_pitch, touchdown_pitch = blend.boundary_pitch[side]
    if not self.landed[side]:
        d_td = 0.0
    heel, toe = stance_pitch(t - t_td, t_next_lo - t, touchdown_pitch, liftoff_pitch, d_td, d_lo)
    base = rot_z(hold.yaw)
    pos = hold.position()
    if heel == 0.0 and toe == 0.0:
        return pos, base, 1.0
    rig_r, rig_t = foot_rig(self.sole_length_m, 0.0, heel, toe, 0.0)
    return pos + base @ rig_t, base @ rig_r, 1.0


def frames_reference(planner, phi: float) -> dict:  # noqa: ANN001
    """GaitPlanner._pose_at and the frames of GaitPlanner.evaluate before the speed-up (numpy's 3 × 3 products)."""
    from engine.geometry import rot_z, rot_zyx

    blend = planner.blend
    cycle_vals, left_vals, right_vals, *_ = blend.channels(phi)
    t = blend.time_at(phi)
    feet = [foot_at_reference(planner, side, phi, t, blend, vals)
            for side, vals in (("left", left_vals), ("right", right_vals))]
    foot_pos = np.array([f[0] for f in feet])
    foot_rot = np.array([f[1] for f in feet])
    return {"pelvis_rot": rot_z(planner.path.yaw) @ rot_zyx(cycle_vals[1], cycle_vals[2], cycle_vals[3]),
            "foot_pos": foot_pos, "foot_rot": foot_rot, "progress": np.array([f[2] for f in feet]),
            "corners": (foot_rot @ planner.sole_corners_local.T).transpose(0, 2, 1) + foot_pos[:, None, :]}


def _numpy_fuses_3x3_products() -> bool:
    """numpy's 3 × 3 matmul rounds once per term (OpenBLAS's dgemm with FMA, as on this machine's AVX2)."""
    a = np.array([[1.0 + 2.0 ** -30, 1.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    b = np.array([[1.0 - 2.0 ** -30, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    return bool((a @ b)[0, 0] != 0.0)  # fused: −2⁻⁶⁰; rounded product first: 1 − 1 = 0


def _assert_same(got: np.ndarray, want: np.ndarray) -> None:
    """Bit-equal where numpy fuses its products as the kernel does; to rounding elsewhere."""
    if _numpy_fuses_3x3_products():
        np.testing.assert_array_equal(got, want)
    else:
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def _rigged_style():  # noqa: ANN202
    """G1's neutral style with every swing rolling off its toe onto its heel (0.3 rad), yawing and rolling the foot
    (the rig's every term) and the pelvis yawing, pitching and rolling."""
    from engine.gait.curves import HermiteCurve, Knot, TangentMode
    from engine.gait.style import load_style, styles_dir

    style = load_style(styles_dir("g1") / "neutral.json")
    flat = TangentMode.FLAT
    for name, sample in style.samples.items():
        for side in ("left", "right"):
            d = sample.intervals.swing_duration_s(side)
            for channel, (a, b, c) in (("toe_pitch", (0.3, 0.0, 0.0)), ("heel_pitch", (0.0, 0.0, -0.3)),
                                       ("yaw", (0.0, 0.2, 0.0)), ("roll", (0.0, -0.15, 0.0))):
                sample = sample.with_curve(f"{side}_foot.{channel}", HermiteCurve(
                    [Knot(0.0, a, mode=flat), Knot(0.5 * d, b, mode=flat), Knot(d, c, mode=flat)], d))
        cycle = sample.intervals.cycle_s
        for channel, amplitude in (("yaw", 0.05), ("pitch", 0.04), ("roll", -0.03)):
            sample = sample.with_curve(f"pelvis.{channel}", HermiteCurve(
                [Knot(0.0, 0.0, mode=flat), Knot(0.5 * cycle, amplitude, mode=flat), Knot(cycle, 0.0, mode=flat)],
                cycle))
        style = style.with_sample(name, sample)
    return style


def test_reference_frames_equal_the_numpy_frames() -> None:
    """The compiled frames of GaitPlanner.evaluate (pelvis and sole rotations, sole positions and corners, their
    backward-difference rates) along G1 walks under ramping commands, time scaling and step adjustments: heel/toe
    rolls, a yawed and rolled swing foot and a swaying pelvis, and the neutral style."""
    from engine.gait.offline_plan import planner_for
    from engine.gait.planner import PlannerFeedback
    from engine.gait.style import StyleContext, load_style, styles_dir
    from engine.robot.model import load_robot

    robot = load_robot("g1")
    rng = np.random.default_rng(43)
    rolled = swung = 0
    for style in (_rigged_style(), load_style(styles_dir("g1") / "neutral.json")):
        planner = planner_for(robot, style, StyleContext.for_robot("g1"))
        planner.path_follows_feet = 0.5
        command, goal, prev = np.zeros(3), np.array([0.4, 0.1, 0.3]), None
        for k in range(500):
            if k % 120 == 0:
                goal = rng.uniform([-0.3, -0.2, -0.6], [0.5, 0.2, 0.6])
            command = command + np.clip(goal - command, -0.01, 0.01)
            fb = PlannerFeedback(float(rng.uniform(0.7, 1.4)), rng.normal(0.0, 0.02, 2) if k % 3 else None)
            dt = 0.008 if k % 50 else 0.0  # a tick without time: no rates
            ref = planner.step(dt, command, fb, with_preview=False)
            want = frames_reference(planner, ref.phase)
            _assert_same(ref.pelvis_rot, want["pelvis_rot"])
            _assert_same(ref.foot_pos, want["foot_pos"])
            _assert_same(ref.foot_rot, want["foot_rot"])
            _assert_same(ref.sole_corners, want["corners"])
            np.testing.assert_array_equal(ref.corner_contact, want["corners"][:, :, 2] < 1e-3)
            assert ref.swing_progress.tolist() == want["progress"].tolist()
            if prev is None or dt == 0.0:
                assert not ref.pelvis_ang_vel.any() and not ref.foot_ang_vel.any() and not ref.foot_lin_vel.any()
            else:
                h = ref.t_s - prev.t_s  # the planner's time step (its clock's sum, not dt)
                _assert_same(ref.pelvis_ang_vel, angular_velocity_reference(prev.pelvis_rot, ref.pelvis_rot, h))
                for i in range(2):
                    _assert_same(ref.foot_ang_vel[i], angular_velocity_reference(prev.foot_rot[i], ref.foot_rot[i], h))
                np.testing.assert_array_equal(ref.foot_lin_vel, (ref.foot_pos - prev.foot_pos) / h)
            rolled += int(np.any(np.abs(ref.foot_rot[:, 2, 0]) > 0.05) and ref.contact.all())
            swung += int(not ref.contact.all())
            prev = ref
    assert rolled > 50 and swung > 300  # soles rolled in double support, swings rigged


def channels_reference(blend, phi: float) -> tuple[np.ndarray, ...]:  # noqa: ANN001
    """BlendedGait.channels before the speed-up: the members' times and rate scales from their phase maps in Python."""
    f = phi - math.floor(phi)
    dphi_dt = 1.0 / blend.dtime_dphase(phi)
    times = np.empty(len(blend.members))
    scale = np.empty(len(blend.members))
    for i, (_, b) in enumerate(blend.members):
        times[i] = float(b.phase_map.time_at(f))
        scale[i] = float(b.phase_map.dtime_dphase(f)) * dphi_dt
    values, rates = blend.merged.evaluate(times, scale)
    v = blend.weights @ values
    r = blend.weights @ rates
    c = blend.merged.n_cycle
    return v[:c], v[c:c + 7], v[c + 7:], r[:c], r[c:c + 7], r[c + 7:]


def test_channels_with_the_phase_maps_compiled_equal_the_reference() -> None:
    """BlendedGait.channels (members' phase maps evaluated in the kernel) at random phases, also negative, beyond one
    cycle and on the waypoints, for random member sets and weights of the G1 neutral and rigged styles' samples."""
    from engine.gait.blending import BlendedGait, ChannelLayout, StyleBanks
    from engine.gait.phase_map import PHASE_WAYPOINTS
    from engine.gait.style import StyleContext, load_style, styles_dir

    ctx = StyleContext.for_robot("g1")
    layout = ChannelLayout(ctx.upper_joints, np.array([ctx.standing_angles[j] for j in ctx.upper_joints]))
    rng = np.random.default_rng(47)
    for style in (load_style(styles_dir("g1") / "neutral.json"), _rigged_style()):
        banks = list(StyleBanks(style, layout).banks.values())
        for _ in range(200):
            members = [banks[i] for i in rng.choice(len(banks), size=int(rng.integers(1, 7)), replace=False)]
            blend = BlendedGait([(float(w), b) for w, b in zip(rng.uniform(0.05, 1.0, len(members)), members)])
            phis = [*rng.uniform(-3.0, 5.0, 5).tolist(), *(k + w for k in (0, 2) for w in PHASE_WAYPOINTS), -1e-17]
            for phi in phis:
                for got, want in zip(blend.channels(phi), channels_reference(blend, phi)):
                    np.testing.assert_array_equal(got, want)


# ------------------------------------------------------------------------------ the upcoming foothold (one kernel)
def upcoming_foothold_reference(planner, side: str, adjust_xy: np.ndarray):  # noqa: ANN001, ANN201
    """GaitPlanner._upcoming_foothold before the compiled call (path pose ahead, stance offset, step adjustment, safe
    region on Python floats)."""
    from engine.gait.footsteps import Foothold, foothold_from_path, project_to_safe_region

    blend = planner.blend
    phi_td, phi_lo = planner._contact_midpoint_phase(side, planner.phi)
    t_now = blend.time_at(planner.phi)
    t_mid = 0.5 * (blend.event_time(phi_td) + blend.event_time(phi_lo))
    pose = planner._path_pose_ahead(max(t_mid - t_now, 0.0))
    target = foothold_from_path(pose, planner._stance_xy_yaw(side))
    adjust_x, adjust_y = adjust_xy.tolist()
    if adjust_x != 0.0 or adjust_y != 0.0:  # adjust_xy.any()
        target = Foothold(target.x + adjust_x, target.y + adjust_y, target.yaw)
    other = "right" if side == "left" else "left"
    return project_to_safe_region(planner.latched[other], target, side, planner.region)


def test_upcoming_foothold_equals_the_python_it_replaced() -> None:
    """On closed-loop sweeps of both robots (command ramps, goals, step adjustments), at every planner tick, for both
    feet: no, random, tiny and large step adjustments (the safe region's projection taken and not) and the command
    holding (no goal), bit for bit."""
    from tests.neutral_sweeps import neutral_sweep_ticks

    rng = np.random.default_rng(12)
    compared = projected = 0
    for k, controller, _ in neutral_sweep_ticks(1500):
        if k % 4:
            continue
        planner = controller.planner
        name = controller.robot.name
        goal, limits = planner.command_goal, planner.command_rate_limits
        for holds in (False, True):
            if holds:
                planner.command_goal = planner.command_rate_limits = None
            for side in ("left", "right"):
                free = upcoming_foothold_reference(planner, side, np.zeros(2))
                for adjust in (np.zeros(2), rng.normal(0.0, 0.05, 2), np.array([1e-300, -0.0]),
                               rng.normal(0.0, 0.4, 2)):
                    got = planner._upcoming_foothold(side, adjust)
                    want = upcoming_foothold_reference(planner, side, adjust)
                    assert (got.x, got.y, got.yaw) == (want.x, want.y, want.yaw), (name, k, side, adjust, holds)
                    assert type(got.x) is float
                    compared += 1
                    # the safe region moved it (not just the adjustment added to the free foothold)
                    projected += abs(want.x - free.x - adjust[0]) + abs(want.y - free.y - adjust[1]) > 1e-6
            planner.command_goal, planner.command_rate_limits = goal, limits
        planner._path_table = planner._path_rows = None  # (the table of this tick: rebuilt from the goal)
    assert compared > 9000 and projected > 100, (compared, projected)
